// The semantic prior (STDyn-SLAM Sec. III-B, DM-SLAM Sec. 3.2.1, DDL-SLAM
// Sec. III-A): movable-class pixels of the label image, widened by a margin.
#include "dynaorb/dynamic/semantic_stage.h"

#include <algorithm>
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
  detail::read_option(node, "drop_unchecked", drop_unchecked);
  detail::read_option(node, "drop_unchecked_mono", drop_unchecked_mono);
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
  if (o_.margin <= 0) return movable;
  const cv::Rect box = cv::boundingRect(movable);
  if (box.area() == 0) return movable;
  // Widening by a disc of radius `margin`: pixels within `margin` of a movable
  // pixel, by the exact Euclidean distance transform (its cost does not grow
  // with the margin, a 31x31 elliptic dilation's does), over the movable
  // pixels' bounding box grown by the margin only.
  const cv::Rect roi = (box + cv::Point(-o_.margin, -o_.margin) + cv::Size(2 * o_.margin, 2 * o_.margin)) &
                       cv::Rect(0, 0, movable.cols, movable.rows);
  cv::Mat dist;
  cv::distanceTransform(~movable(roi), dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  cv::Mat widened = cv::Mat::zeros(movable.size(), CV_8UC1);
  widened(roi).setTo(255, dist <= static_cast<float>(o_.margin));
  return widened;
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
  const bool drop_unchecked = ctx.sensor == Sensor::kMono ? o_.drop_unchecked_mono : o_.drop_unchecked;
  const bool unchecked = o_.policy == SemanticOptions::Policy::kStaticUntilProven && drop_unchecked &&
                         !ctx.previous;
  if (unchecked && n > 0) report.values["unchecked_dropped"] = 1;
  if ((o_.policy == SemanticOptions::Policy::kDrop || unchecked) && n > 0) {
    if (ctx.dynamic.empty()) ctx.dynamic = cv::Mat::zeros(cur.grey.size(), CV_8UC1);
    cv::bitwise_or(ctx.dynamic, cur.candidates, ctx.dynamic);
    report.regions = regions;
  }
}

}  // namespace dynaorb::dynamic
