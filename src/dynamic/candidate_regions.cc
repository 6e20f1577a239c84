// Candidate mask -> object regions: connected components, split by class.
#include "dynaorb/dynamic/candidate_regions.h"

#include <algorithm>
#include <array>
#include <bitset>
#include <climits>
#include <cstdint>
#include <cstring>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "id_runs.h"

namespace dynaorb::dynamic {

namespace {

// connectedComponentsWithStats(mask, comp, stats, centroids, 8, CV_32S)
// without the centroids: the same labels (the same labelling algorithm),
// and each component's CC_STAT_LEFT, TOP, WIDTH, HEIGHT and AREA from one
// pass over the runs of each row. OpenCV gathers its statistics pixel by
// pixel inside the labelling, centroid sums included: 1.9 ms at 640x480
// with half the image in candidates, against 0.4 ms here (one thread).
// Returns the number of labels, the background (0) included.
int components_with_boxes(const cv::Mat& mask, cv::Mat& comp, cv::Mat& stats) {
  const int n = cv::connectedComponents(mask, comp, 8, CV_32S);
  stats.create(n, cv::CC_STAT_MAX, CV_32S);
  std::vector<int> x0(n, INT_MAX), y0(n, INT_MAX), x1(n, -1), y1(n, -1), area(n, 0);
  for (int y = 0; y < comp.rows; ++y) {
    const int* c = comp.ptr<int>(y);
    for (int x = 0; x < comp.cols;) {
      const int l = c[x];
      const int start = x;
      x = detail::id_run_end(c, x, comp.cols);
      area[l] += x - start;
      x0[l] = std::min(x0[l], start);
      x1[l] = std::max(x1[l], x - 1);
      y0[l] = std::min(y0[l], y);
      y1[l] = y;
    }
  }
  for (int r = 0; r < n; ++r) {
    int* st = stats.ptr<int>(r);
    const bool seen = area[r] > 0;  // only the background can be empty (a mask of all ones)
    st[cv::CC_STAT_LEFT] = seen ? x0[r] : 0;
    st[cv::CC_STAT_TOP] = seen ? y0[r] : 0;
    st[cv::CC_STAT_WIDTH] = seen ? x1[r] - x0[r] + 1 : 0;
    st[cv::CC_STAT_HEIGHT] = seen ? y1[r] - y0[r] + 1 : 0;
    st[cv::CC_STAT_AREA] = area[r];
  }
  return n;
}

// Appends the 8-connected components of `mask` (a part of the image whose
// top-left corner is `origin`) as regions of class `cls`.
void add_components(const cv::Mat& mask, const cv::Point& origin, unsigned char cls, CandidateRegions& out) {
  cv::Mat comp, stats;
  const int n = components_with_boxes(mask, comp, stats);
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

cv::Mat nearest_class_by_transforms(const cv::Mat& lab, const std::vector<unsigned char>& present) {
  cv::Mat best_dist(lab.size(), CV_32FC1, cv::Scalar(std::numeric_limits<float>::max()));
  cv::Mat best_class(lab.size(), CV_8UC1, cv::Scalar(0));
  for (unsigned char c : present) {
    cv::Mat dist;
    cv::distanceTransform(lab != c, dist, cv::DIST_L2, cv::DIST_MASK_5);
    const cv::Mat closer = dist < best_dist;
    dist.copyTo(best_dist, closer);
    best_class.setTo(c, closer);
  }
  return best_class;
}

cv::Mat nearest_class(const cv::Mat& lab, const std::vector<unsigned char>& present, const cv::Mat& where) {
  CV_Assert(lab.type() == CV_8UC1 && where.type() == CV_8UC1 && where.size() == lab.size());
  // OpenCV's 5x5 chamfer (distanceTransform with DIST_L2 / DIST_MASK_5):
  // weights 1, 1.4 and 2.1969 in 16.16 fixed point, a forward and a backward
  // raster pass. Here each pixel carries (distance, class) as one integer,
  // distance << 8 | class: the minimum of such keys over the same passes is
  // the nearest class with ties to the lower id, because adding a weight
  // keeps the order and the minimum distributes over the classes' sources.
  constexpr int kShift = 16;
  const int64_t hv = static_cast<int64_t>(cvRound(1.0f * (1 << kShift))) << 8;
  const int64_t diag = static_cast<int64_t>(cvRound(1.4f * (1 << kShift))) << 8;
  const int64_t knight = static_cast<int64_t>(cvRound(2.1969f * (1 << kShift))) << 8;
  const int64_t far = static_cast<int64_t>(INT_MAX >> 2) << 8;  // no source yet
  std::array<bool, 256> source{};
  for (unsigned char c : present) source[c] = true;

  const int rows = lab.rows, cols = lab.cols, border = 2, step = cols + 2 * border;
  std::vector<int64_t> key(static_cast<size_t>(rows + 2 * border) * step, far);
  auto at = [&](int y, int x) -> int64_t& { return key[static_cast<size_t>(y + border) * step + x + border]; };
  for (int y = 0; y < rows; ++y) {
    const unsigned char* l = lab.ptr<unsigned char>(y);
    int64_t* k = &at(y, 0);
    for (int x = 0; x < cols; ++x) {
      if (source[l[x]]) {
        k[x] = l[x];
        continue;
      }
      int64_t m = k[x - 2 * step - 1] + knight;
      m = std::min(m, k[x - 2 * step + 1] + knight);
      m = std::min(m, k[x - step - 2] + knight);
      m = std::min(m, k[x - step - 1] + diag);
      m = std::min(m, k[x - step] + hv);
      m = std::min(m, k[x - step + 1] + diag);
      m = std::min(m, k[x - step + 2] + knight);
      m = std::min(m, k[x - 1] + hv);
      k[x] = m;
    }
  }
  // The per-class transforms compare floats: a distance of 2^24 (256 px) or
  // more is rounded there, and ties could then differ. Such a pixel of
  // `where` hands the box to the per-class transforms.
  const int64_t exact_below = static_cast<int64_t>(1) << (24 + 8);
  cv::Mat best(lab.size(), CV_8UC1);
  for (int y = rows - 1; y >= 0; --y) {
    const unsigned char* l = lab.ptr<unsigned char>(y);
    const unsigned char* w = where.ptr<unsigned char>(y);
    unsigned char* b = best.ptr<unsigned char>(y);
    int64_t* k = &at(y, 0);
    for (int x = cols - 1; x >= 0; --x) {
      if (!source[l[x]]) {
        int64_t m = k[x];
        m = std::min(m, k[x + 2 * step + 1] + knight);
        m = std::min(m, k[x + 2 * step - 1] + knight);
        m = std::min(m, k[x + step + 2] + knight);
        m = std::min(m, k[x + step + 1] + diag);
        m = std::min(m, k[x + step] + hv);
        m = std::min(m, k[x + step - 1] + diag);
        m = std::min(m, k[x + step - 2] + knight);
        m = std::min(m, k[x + 1] + hv);
        k[x] = m;
        if (w[x] && m >= exact_below) return nearest_class_by_transforms(lab, present);
      }
      b[x] = static_cast<unsigned char>(k[x] & 0xff);
    }
  }
  return best;
}

CandidateBlobs candidate_blobs(const cv::Mat& candidates) {
  CandidateBlobs b;
  if (candidates.empty() || candidates.type() != CV_8UC1) return b;
  b.count = components_with_boxes(candidates, b.comp, b.stats) - 1;  // non-zero is foreground
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
    // to the lower id, over the blob's box.
    const cv::Mat best_class = nearest_class(labels(box), present, blob);
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
