// Candidate mask -> object regions: connected components, split by class.
#include "dynaorb/dynamic/candidate_regions.h"

#include <bitset>
#include <cstring>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace dynaorb::dynamic {

namespace {

// Appends the 8-connected components of `mask` (a part of the image whose
// top-left corner is `origin`) as regions of class `cls`.
void add_components(const cv::Mat& mask, const cv::Point& origin, unsigned char cls, CandidateRegions& out) {
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
    int* id = out.ids.ptr<int>(y + origin.y) + origin.x;
    for (int x = 0; x < comp.cols; ++x)
      if (c[x] > 0) id[x] = c[x] + offset;
  }
  out.count += n - 1;
}

}  // namespace

CandidateBlobs candidate_blobs(const cv::Mat& candidates) {
  CandidateBlobs b;
  if (candidates.empty() || candidates.type() != CV_8UC1) return b;
  cv::Mat centroids;
  b.count = cv::connectedComponentsWithStats(candidates, b.comp, b.stats, centroids, 8, CV_32S) - 1;  // non-zero is foreground
  return b;
}

CandidateRegions candidate_regions(const cv::Mat& candidates, const cv::Mat& labels, bool split_by_label) {
  return candidate_regions(candidate_blobs(candidates), labels, split_by_label);
}

CandidateRegions candidate_regions(const CandidateBlobs& blobs, const cv::Mat& labels, bool split_by_label) {
  CandidateRegions out;
  if (blobs.comp.empty()) return out;
  const cv::Mat& comp = blobs.comp;
  const cv::Mat& stats = blobs.stats;
  const int n = blobs.count + 1;
  const bool have_labels = split_by_label && !labels.empty() && labels.type() == CV_8UC1 &&
                           labels.size() == comp.size();
  if (!have_labels) {
    // The blobs are the regions.
    out.ids = comp;
    out.count = blobs.count;
    out.label.assign(static_cast<size_t>(blobs.count), 0);
    for (int r = 1; r <= blobs.count; ++r) out.pixels.push_back(stats.at<int>(r, cv::CC_STAT_AREA));
    return out;
  }
  // The classes inside each blob: only a blob that holds two classes or more
  // needs splitting, and only over its own bounding box.
  std::vector<std::bitset<256>> classes(n);
  for (int y = 0; y < labels.rows; ++y) {
    const unsigned char* l = labels.ptr<unsigned char>(y);
    const int* c = comp.ptr<int>(y);
    for (int x = 0; x < labels.cols; ++x)
      if (c[x] > 0 && l[x]) classes[c[x]].set(l[x]);
  }
  out.ids = cv::Mat(comp.size(), CV_32SC1, cv::Scalar(0));
  for (int r = 1; r < n; ++r) {
    const cv::Rect box(stats.at<int>(r, cv::CC_STAT_LEFT), stats.at<int>(r, cv::CC_STAT_TOP),
                       stats.at<int>(r, cv::CC_STAT_WIDTH), stats.at<int>(r, cv::CC_STAT_HEIGHT));
    const cv::Mat blob = comp(box) == r;
    std::vector<unsigned char> present;
    for (int v = 1; v < 256; ++v)
      if (classes[r].test(v)) present.push_back(static_cast<unsigned char>(v));
    if (present.size() <= 1) {
      // One object (a blob of one class, or of none: candidates from
      // elsewhere than the labels).
      const int id = ++out.count;
      out.label.push_back(present.empty() ? 0 : present.front());
      out.pixels.push_back(stats.at<int>(r, cv::CC_STAT_AREA));
      for (int y = 0; y < box.height; ++y) {
        const unsigned char* b = blob.ptr<unsigned char>(y);
        int* ids = out.ids.ptr<int>(y + box.y) + box.x;
        for (int x = 0; x < box.width; ++x)
          if (b[x]) ids[x] = id;
      }
      continue;
    }
    // Classes that touch: every pixel of the blob goes to the class of its
    // nearest labelled pixel (the margin carries no label of its own), ties
    // to the lower id; one distance transform per class over the blob's box
    // (over the whole image they cost ~2 ms each at 640x480).
    const cv::Mat lab = labels(box);
    cv::Mat best_dist(box.size(), CV_32FC1, cv::Scalar(std::numeric_limits<float>::max()));
    cv::Mat best_class(box.size(), CV_8UC1, cv::Scalar(0));
    for (unsigned char c : present) {
      cv::Mat dist;
      cv::distanceTransform(lab != c, dist, cv::DIST_L2, cv::DIST_MASK_5);
      const cv::Mat closer = dist < best_dist;
      dist.copyTo(best_dist, closer);
      best_class.setTo(c, closer);
    }
    for (unsigned char c : present) add_components(blob & (best_class == c), box.tl(), c, out);
  }
  return out;
}

namespace {

bool same_pixels(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty()) return a.empty() && b.empty();
  if (a.size() != b.size() || a.type() != b.type()) return false;
  if (a.data == b.data && a.step == b.step) return true;
  const size_t row = a.cols * a.elemSize();
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), row) != 0) return false;
  return true;
}

}  // namespace

const CandidateRegions& RegionsMemo::get(const cv::Mat& candidates, const cv::Mat& labels, bool split_by_label) {
  for (Entry& e : entries_) {
    if (!same_pixels(e.candidates, candidates)) continue;
    for (const Result& r : e.results)
      if (r.split == split_by_label && same_pixels(r.labels, labels)) return r.regions;
    e.results.push_back({labels.clone(), split_by_label, candidate_regions(e.blobs, labels, split_by_label)});
    return e.results.back().regions;
  }
  Entry e;
  e.candidates = candidates.clone();
  e.blobs = candidate_blobs(candidates);
  e.results.push_back({labels.clone(), split_by_label, candidate_regions(e.blobs, labels, split_by_label)});
  entries_.push_back(std::move(e));
  return entries_.back().results.back().regions;
}

}  // namespace dynaorb::dynamic
