// Candidate mask -> object regions: connected components, split by class.
#include "dynaorb/dynamic/candidate_regions.h"

#include <limits>
#include <opencv2/imgproc.hpp>

namespace dynaorb::dynamic {

namespace {

// Appends the 8-connected components of `mask` as regions of class `cls`.
void add_components(const cv::Mat& mask, unsigned char cls, CandidateRegions& out) {
  cv::Mat comp, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, comp, stats, centroids, 8, CV_32S);
  if (n <= 1) return;
  const int offset = out.count;
  for (int r = 1; r < n; ++r) {
    out.label.push_back(cls);
    out.pixels.push_back(stats.at<int>(r, cv::CC_STAT_AREA));
  }
  for (int y = 0; y < comp.rows; ++y) {
    const int* c = comp.ptr<int>(y);
    int* id = out.ids.ptr<int>(y);
    for (int x = 0; x < comp.cols; ++x)
      if (c[x] > 0) id[x] = c[x] + offset;
  }
  out.count += n - 1;
}

}  // namespace

CandidateRegions candidate_regions(const cv::Mat& candidates, const cv::Mat& labels, bool split_by_label) {
  CandidateRegions out;
  if (candidates.empty() || candidates.type() != CV_8UC1) return out;
  out.ids = cv::Mat(candidates.size(), CV_32SC1, cv::Scalar(0));
  const cv::Mat cand = candidates != 0;
  if (cv::countNonZero(cand) == 0) return out;

  const bool have_labels = split_by_label && !labels.empty() && labels.type() == CV_8UC1 &&
                           labels.size() == candidates.size();
  std::vector<unsigned char> classes;
  if (have_labels) {
    int hist[256] = {0};
    for (int y = 0; y < labels.rows; ++y) {
      const unsigned char* l = labels.ptr<unsigned char>(y);
      const unsigned char* c = cand.ptr<unsigned char>(y);
      for (int x = 0; x < labels.cols; ++x)
        if (c[x] && l[x]) ++hist[l[x]];
    }
    for (int v = 1; v < 256; ++v)
      if (hist[v] > 0) classes.push_back(static_cast<unsigned char>(v));
  }
  if (classes.size() <= 1) {
    add_components(cand, classes.empty() ? 0 : classes.front(), out);
    return out;
  }

  // Nearest class for every pixel: one distance transform per class present
  // (a handful of classes at most).
  cv::Mat best_dist(cand.size(), CV_32FC1, cv::Scalar(std::numeric_limits<float>::max()));
  cv::Mat best_class(cand.size(), CV_8UC1, cv::Scalar(0));
  for (unsigned char c : classes) {
    cv::Mat dist;
    cv::distanceTransform(labels != c, dist, cv::DIST_L2, cv::DIST_MASK_5);
    const cv::Mat closer = dist < best_dist;
    dist.copyTo(best_dist, closer);
    best_class.setTo(c, closer);
  }
  for (unsigned char c : classes) add_components(cand & (best_class == c), c, out);
  return out;
}

}  // namespace dynaorb::dynamic
