// The semantic prior (STDyn-SLAM Sec. III-B, DM-SLAM Sec. 3.2.1, DDL-SLAM
// Sec. III-A): movable-class pixels of the label image, widened by a margin.
#include "dynaorb/dynamic/semantic_stage.h"

#include <algorithm>
#include <cstdint>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include "dynaorb/io/errors.h"
#include "file_node_options.h"

namespace dynaorb::dynamic {

const std::vector<int>& voc_movable_classes() {
  static const std::vector<int> ids = {1, 2, 3, 4, 6, 7, 8, 10, 12, 13, 14, 15, 17, 19};
  return ids;
}

const std::vector<int>& coco_movable_classes() {
  static const std::vector<int> ids = {1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 34};
  return ids;
}

const std::vector<int>& cityscapes_movable_classes() {
  static const std::vector<int> ids = {11, 12, 13, 14, 15, 16, 17, 18};
  return ids;
}

std::string to_string(SemanticOptions::Policy policy) {
  return policy == SemanticOptions::Policy::kDrop ? "drop" : "static_until_proven";
}

void SemanticOptions::read(const cv::FileNode& node) {
  if (detail::has_key(node, "classes")) {
    const cv::FileNode n = node["classes"];
    const std::string key = detail::key_name(node, "classes");
    if (n.isString()) {
      const std::string s = static_cast<std::string>(n);
      if (s == "voc") ids = voc_movable_classes();
      else if (s == "coco") ids = coco_movable_classes();
      else if (s == "cityscapes") ids = cityscapes_movable_classes();
      else throw InputError("option '" + key + "': unknown class set '" + s + "' (voc, coco, cityscapes or a list of ids)");
      classes = s;
    } else if (n.isSeq()) {
      std::vector<int> list;
      for (const cv::FileNode& item : n) {
        if (!item.isInt() || static_cast<int>(item) < 0 || static_cast<int>(item) > 65535)
          throw InputError("option '" + key + "': class ids must be integers in [0, 65535]");
        list.push_back(static_cast<int>(item));
      }
      if (list.empty()) throw InputError("option '" + key + "': the id list is empty");
      ids = list;
      classes = "list";
    } else {
      throw InputError("option '" + key + "' must be voc, coco, cityscapes or a list of class ids");
    }
  }
  detail::read_option(node, "margin", margin);
  if (margin < 0) throw InputError("option '" + detail::key_name(node, "margin") + "' must be >= 0 px");
  std::string p = to_string(policy);
  detail::read_option(node, "policy", p);
  if (p == "drop") policy = Policy::kDrop;
  else if (p == "static_until_proven") policy = Policy::kStaticUntilProven;
  else
    throw InputError("option '" + detail::key_name(node, "policy") + "': unknown policy '" + p +
                     "' (drop or static_until_proven)");
  if (detail::has_key(node, "drop_unchecked")) {  // stereo and RGB-D; their own keys below override it
    bool both = false;
    detail::read_option(node, "drop_unchecked", both);
    drop_unchecked_stereo = drop_unchecked_rgbd = both;
  }
  detail::read_option(node, "drop_unchecked_stereo", drop_unchecked_stereo);
  detail::read_option(node, "drop_unchecked_rgbd", drop_unchecked_rgbd);
  detail::read_option(node, "drop_unchecked_mono", drop_unchecked_mono);
}

bool SemanticOptions::drop_unchecked_for(Sensor sensor) const {
  switch (sensor) {
    case Sensor::kMono: return drop_unchecked_mono;
    case Sensor::kRGBD: return drop_unchecked_rgbd;
    default: return drop_unchecked_stereo;
  }
}

SemanticStage::SemanticStage(const SemanticOptions& options) : o_(options) { build_lookup(); }

void SemanticStage::set_movable_classes(const std::vector<int>& ids) {
  o_.ids = ids;
  o_.classes = "list";
  build_lookup();
}

void SemanticStage::build_lookup() {
  lut8_ = cv::Mat::zeros(1, 256, CV_8U);
  lut16_.assign(65536, 0);
  for (int id : o_.ids) {
    if (id < 0 || id > 65535) continue;
    lut16_[id] = 255;
    if (id < 256) lut8_.at<unsigned char>(id) = 255;
  }
}

cv::Mat SemanticStage::candidates(const cv::Mat& labels) const {
  if (labels.empty() || labels.channels() != 1) return cv::Mat();
  cv::Mat movable;
  if (labels.depth() == CV_8U) {
    cv::LUT(labels, lut8_, movable);
  } else if (labels.depth() == CV_16U) {
    movable.create(labels.size(), CV_8UC1);
    for (int r = 0; r < labels.rows; ++r) {
      const unsigned short* in = labels.ptr<unsigned short>(r);
      unsigned char* out = movable.ptr<unsigned char>(r);
      for (int c = 0; c < labels.cols; ++c) out[c] = lut16_[in[c]];
    }
  } else {
    return cv::Mat();
  }
  return o_.margin > 0 ? widen_by_disc(movable, o_.margin) : movable;
}

namespace {

// The end of the run of pixels from x on that are all set (set) or all
// unset (!set), 16 at a time where it can.
int run_end(const unsigned char* m, int x, int n, bool set) {
  const cv::v_uint8x16 zero = cv::v_setzero_u8();
  for (; x + 16 <= n; x += 16) {
    const cv::v_uint8x16 is_zero = cv::v_load(m + x) == zero;
    if (set ? cv::v_check_any(is_zero) : !cv::v_check_all(is_zero)) break;
  }
  while (x < n && (m[x] != 0) == set) ++x;
  return x;
}

// Each pixel's distance along its row to the nearest set pixel of `mask`
// (rows of `box`, columns of `cols`), saturated at `cap`. Run by run: a set
// run is 0, an unset one the cap with ramps up from the set pixels on
// either side of it.
template <typename T>
cv::Mat row_distances(const cv::Mat& mask, const cv::Rect& box, const cv::Range& cols, T cap) {
  cv::Mat h(box.height, cols.size(), cv::DataType<T>::type);
  const int n = h.cols;
  for (int y = 0; y < box.height; ++y) {
    const unsigned char* m = mask.ptr<unsigned char>(box.y + y) + cols.start;
    T* d = h.ptr<T>(y);
    for (int x = 0; x < n;) {
      const bool set = m[x] != 0;
      const int end = run_end(m, x, n, set);
      if (set) {
        std::fill(d + x, d + end, T(0));
      } else {
        std::fill(d + x, d + end, cap);
        const int ramp = std::min<int>(end - x, cap - 1);  // distances 1..cap-1 next to a set pixel
        if (x > 0)
          for (int k = 0; k < ramp; ++k) d[x + k] = static_cast<T>(k + 1);
        if (end < n)
          for (int k = 0; k < ramp; ++k) d[end - 1 - k] = std::min(d[end - 1 - k], static_cast<T>(k + 1));
      }
      x = end;
    }
  }
  return h;
}

// out[x] = 255 where h[x] <= w, for one row.
void mark_within(const unsigned char* h, unsigned char w, int n, unsigned char* out) {
  int x = 0;
  const cv::v_uint8x16 vw = cv::v_setall_u8(w);
  for (; x + 16 <= n; x += 16) cv::v_store(out + x, cv::v_load(out + x) | (cv::v_load(h + x) <= vw));
  for (; x < n; ++x)
    if (h[x] <= w) out[x] = 255;
}
void mark_within(const unsigned short* h, unsigned short w, int n, unsigned char* out) {
  for (int x = 0; x < n; ++x)
    if (h[x] <= w) out[x] = 255;
}

template <typename T>
cv::Mat widen(const cv::Mat& mask, const cv::Rect& box, int radius) {
  const cv::Rect roi = (box + cv::Point(-radius, -radius) + cv::Size(2 * radius, 2 * radius)) &
                       cv::Rect(0, 0, mask.cols, mask.rows);
  const cv::Mat h = row_distances<T>(mask, box, cv::Range(roi.x, roi.x + roi.width), static_cast<T>(radius + 1));
  // half[dy]: the disc's half-width dy rows away, the largest w with
  // w^2 + dy^2 <= radius^2.
  std::vector<T> half(radius + 1);
  const int64_t r2 = static_cast<int64_t>(radius) * radius;
  for (int dy = 0, w = radius; dy <= radius; ++dy) {
    while (static_cast<int64_t>(w) * w + static_cast<int64_t>(dy) * dy > r2) --w;
    half[dy] = static_cast<T>(w);
  }
  cv::Mat out = cv::Mat::zeros(mask.size(), CV_8UC1);
  for (int y = roi.y; y < roi.y + roi.height; ++y) {
    unsigned char* o = out.ptr<unsigned char>(y) + roi.x;
    for (int yy = std::max(y - radius, box.y); yy <= std::min(y + radius, box.y + box.height - 1); ++yy)
      mark_within(h.ptr<T>(yy - box.y), half[std::abs(yy - y)], roi.width, o);
  }
  return out;
}

}  // namespace

cv::Mat widen_by_disc(const cv::Mat& mask, int radius) {
  CV_Assert(mask.type() == CV_8UC1);
  cv::Mat out = cv::Mat::zeros(mask.size(), CV_8UC1);
  const cv::Rect box = cv::boundingRect(mask);
  if (box.area() == 0) return out;
  if (radius <= 0) {
    out.setTo(255, mask);
    return out;
  }
  // A pixel is within `radius` of a set pixel dy rows away iff its row
  // distance to that row's nearest set pixel is at most the disc's
  // half-width there: the union of those tests over the disc's rows. Exact
  // (integer squares), and its cost does not depend on the shapes'
  // complexity; over the set pixels' box grown by the radius only. No two
  // pixels are farther apart than cols + rows: a larger radius is that one.
  radius = std::min(radius, mask.cols + mask.rows);
  return radius < 255 ? widen<unsigned char>(mask, box, radius) : widen<unsigned short>(mask, box, radius);
}

void SemanticStage::process(Context& ctx, StageReport& report) {
  FrameData& cur = ctx.current;
  cur.candidates.release();
  if (cur.labels.empty()) {
    report.values["skipped_no_labels"] = 1;
    return;
  }
  if (cur.labels.size() != cur.grey.size() || cur.labels.channels() != 1 ||
      (cur.labels.depth() != CV_8U && cur.labels.depth() != CV_16U)) {
    report.values["skipped_bad_labels"] = 1;
    return;
  }
  cur.candidates = candidates(cur.labels);
  const double n = cv::countNonZero(cur.candidates);
  report.values["candidate_fraction"] = n / static_cast<double>(cur.candidates.total());
  // The blobs are cut once for this and the later stages' regions.
  const int regions = n > 0 ? ctx.regions.get(cur.candidates, cv::Mat(), false).count : 0;
  report.values["candidate_regions"] = regions;
  const bool unchecked = o_.policy == SemanticOptions::Policy::kStaticUntilProven &&
                         o_.drop_unchecked_for(ctx.sensor) && !ctx.previous;
  if (unchecked && n > 0) report.values["unchecked_dropped"] = 1;
  if ((o_.policy == SemanticOptions::Policy::kDrop || unchecked) && n > 0) {
    if (ctx.dynamic.empty()) ctx.dynamic = cv::Mat::zeros(cur.grey.size(), CV_8UC1);
    cv::bitwise_or(ctx.dynamic, cur.candidates, ctx.dynamic);
    report.regions = regions;
  }
}

}  // namespace dynaorb::dynamic
