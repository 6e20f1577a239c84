// STDyn-SLAM / DS-SLAM moving consistency check: epipolar distance of LK-
// tracked corners under a RANSAC fundamental matrix, then whole segmented
// objects marked moving when they carry dynamic points.
#include "dynaorb/dynamic/stdyn_stage.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "dynaorb/core/stopwatch.h"
#include "dynaorb/dynamic/candidate_regions.h"
#include "dynaorb/io/errors.h"
#include "file_node_options.h"
#include "../core/option_checks.h"

namespace dynaorb::dynamic {

void StdynOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "epipolar_threshold_px", epipolar_threshold_px);
  read_option(node, "f_ransac_threshold_px", f_ransac_threshold_px);
  read_option(node, "f_ransac_confidence", f_ransac_confidence);
  read_option(node, "f_ransac_iterations", f_ransac_iterations);
  read_option(node, "f_method", f_method);
  read_option(node, "f_exclude_candidates", f_exclude_candidates);
  read_option(node, "f_refine_on_inliers", f_refine_on_inliers);
  read_option(node, "min_points", min_points);
  read_option(node, "edge_margin_px", edge_margin_px);
  read_option(node, "patch_max_abs_diff", patch_max_abs_diff);
  read_option(node, "min_dynamic_points", min_dynamic_points);
  read_option(node, "min_dynamic_ratio", min_dynamic_ratio);
  read_option(node, "object_search_radius_px", object_search_radius_px);
  read_option(node, "keep_moving_frames", keep_moving_frames);
  read_option(node, "keep_moving_overlap", keep_moving_overlap);
  read_option(node, "mark_points_without_labels", mark_points_without_labels);
  read_option(node, "no_labels_point_radius_px", no_labels_point_radius_px);
  if (detail::has_key(node, "movable_labels")) {
    const cv::FileNode n = node["movable_labels"];
    if (!n.isSeq())
      throw InputError("option '" + detail::key_name(node, "movable_labels") + "' must be a list");
    std::vector<int> ids;
    for (const cv::FileNode& item : n) {
      if (!item.isInt() || static_cast<int>(item) < 0 || static_cast<int>(item) > 255)
        throw InputError("option '" + detail::key_name(node, "movable_labels") +
                         "' must list class ids 0..255");
      ids.push_back(static_cast<int>(item));
    }
    movable_labels = ids;
  }
  validate();
}

void StdynOptions::validate() const {
  const dynaorb::detail::OptionChecks c("Dynamic.stdyn");
  c.positive("epipolar_threshold_px", epipolar_threshold_px);
  c.positive("f_ransac_threshold_px", f_ransac_threshold_px);
  c.between("f_ransac_confidence", f_ransac_confidence, 0, 1, false);
  c.at_least("f_ransac_iterations", f_ransac_iterations, 1);
  if (f_method != "ransac" && f_method != "usac")
    throw InputError("Dynamic.stdyn option 'f_method' is '" + f_method + "'; it must be ransac or usac");
  c.at_least("min_points", min_points, 8);  // the 8-point algorithm
  c.at_least("edge_margin_px", edge_margin_px, 0);
  c.finite("patch_max_abs_diff", patch_max_abs_diff, "a finite number (<= 0: no patch check)");
  c.at_least("min_dynamic_points", min_dynamic_points, 1);
  if (!(min_dynamic_ratio >= 0 && min_dynamic_ratio <= 1))
    c.fail("min_dynamic_ratio", min_dynamic_ratio, "in [0, 1] (0: no ratio)");
  c.at_least("object_search_radius_px", object_search_radius_px, 0);
  c.at_least("keep_moving_frames", keep_moving_frames, 0);
  c.between("keep_moving_overlap", keep_moving_overlap, 0, 1, true);
  c.at_least("no_labels_point_radius_px", no_labels_point_radius_px, 1);
  for (int id : movable_labels)
    if (id < 0 || id > 255) c.fail("movable_labels", id, "a list of class ids 0..255");
}

namespace {

bool finite(const cv::Point2f& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

bool is_mask(const cv::Mat& m, const cv::Size& size) {
  return !m.empty() && m.type() == CV_8UC1 && m.size() == size;
}

bool mask_at(const cv::Mat& m, const cv::Point2f& p) {
  const int x = std::clamp(cvRound(p.x), 0, m.cols - 1), y = std::clamp(cvRound(p.y), 0, m.rows - 1);
  return m.at<unsigned char>(y, x) != 0;
}

bool inside(const cv::Point2f& p, const cv::Size& size, int margin) {
  return p.x >= margin && p.y >= margin && p.x < size.width - margin && p.y < size.height - margin;
}

// DS-SLAM's block check: the sum of absolute grey differences over the 3x3
// blocks centred on the two ends (integer pixels, as its code truncates).
double patch_difference(const cv::Mat& a, const cv::Point2f& pa, const cv::Mat& b, const cv::Point2f& pb) {
  const int x1 = static_cast<int>(pa.x), y1 = static_cast<int>(pa.y);
  const int x2 = static_cast<int>(pb.x), y2 = static_cast<int>(pb.y);
  double sum = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      sum += std::abs(static_cast<int>(a.at<unsigned char>(y1 + dy, x1 + dx)) -
                      static_cast<int>(b.at<unsigned char>(y2 + dy, x2 + dx)));
  return sum;
}

// Distance (px) of q to the epipolar line F p in the current image (DS-SLAM
// code: |q^T F p| / sqrt(A^2 + B^2) with (A, B, C) = F p). A point at the
// epipole has no line: NaN.
double epipolar_distance(const cv::Matx33d& F, const cv::Point2f& p, const cv::Point2f& q) {
  const cv::Vec3d l = F * cv::Vec3d(p.x, p.y, 1.0);
  const double n = std::sqrt(l[0] * l[0] + l[1] * l[1]);
  if (!(n > 0) || !std::isfinite(n)) return std::numeric_limits<double>::quiet_NaN();
  return std::abs(l[0] * q.x + l[1] * q.y + l[2]) / n;
}

// The object a point belongs to: the one under it, else the nearest object
// pixel within `radius` (square window, as the released codes search).
int object_at(const cv::Mat& ids, const cv::Point2f& p, int radius) {
  const int x = cvRound(p.x), y = cvRound(p.y);
  if (x < 0 || y < 0 || x >= ids.cols || y >= ids.rows) return 0;
  const int here = ids.at<int>(y, x);
  if (here > 0 || radius <= 0) return here;
  int best = 0, best_d2 = std::numeric_limits<int>::max();
  const int x0 = std::max(0, x - radius), x1 = std::min(ids.cols - 1, x + radius);
  const int y0 = std::max(0, y - radius), y1 = std::min(ids.rows - 1, y + radius);
  for (int v = y0; v <= y1; ++v) {
    const int* row = ids.ptr<int>(v);
    for (int u = x0; u <= x1; ++u) {
      if (row[u] <= 0) continue;
      const int d2 = (u - x) * (u - x) + (v - y) * (v - y);
      if (d2 < best_d2) {
        best_d2 = d2;
        best = row[u];
      }
    }
  }
  return best;
}

// Class id -> the id itself for the movable classes, 0 for the others.
cv::Mat movable_lut(const std::vector<int>& movable_labels) {
  cv::Mat lut(1, 256, CV_8UC1, cv::Scalar(0));
  for (int id : movable_labels)
    if (id > 0 && id < 256) lut.at<unsigned char>(id) = static_cast<unsigned char>(id);
  return lut;
}

// The image size: the current image, else the dynamic mask, else the calibration.
cv::Size frame_size(const Context& ctx) {
  if (!ctx.current.grey.empty()) return ctx.current.grey.size();
  if (!ctx.dynamic.empty()) return ctx.dynamic.size();
  if (ctx.calib && ctx.calib->width > 0 && ctx.calib->height > 0)
    return cv::Size(ctx.calib->width, ctx.calib->height);
  return cv::Size();
}

}  // namespace

StdynStage::StdynStage(StdynOptions options) : o_(std::move(options)), movable_lut_(movable_lut(o_.movable_labels)) {
  o_.validate();
}

bool StdynStage::has_objects(const Context& ctx, const cv::Size& size) const {
  // The objects process() decides on: the candidate regions, else the
  // movable classes' pixels in the labels.
  const cv::Mat& cand = ctx.current.candidates;
  if (is_mask(cand, size)) return cv::countNonZero(cand) > 0;
  const cv::Mat& labels = ctx.current.labels;
  if (is_mask(labels, size)) {
    const unsigned char* movable = movable_lut_.ptr<unsigned char>();
    for (int v = 0; v < labels.rows; ++v) {
      const unsigned char* row = labels.ptr<unsigned char>(v);
      for (int u = 0; u < labels.cols; ++u)
        if (movable[row[u]]) return true;
    }
    return false;
  }
  return o_.mark_points_without_labels && o_.no_labels_point_radius_px > 0;
}

bool StdynStage::needs_motion_cues_for(const Context& ctx) const {
  const cv::Size size = frame_size(ctx);
  return size.area() > 0 && has_objects(ctx, size);
}

void StdynStage::process(Context& ctx, StageReport& report) {
  auto& val = report.values;
  val["threshold_px"] = o_.epipolar_threshold_px;
  // The memory only speaks for the frame right before this one; a frame
  // that decides nothing leaves none.
  const bool memory_usable = o_.keep_moving_frames > 0 && ctx.previous &&
                             memory_.holds(ctx.previous->id, frame_size(ctx));
  const RegionMemory previous = std::move(memory_);
  memory_.reset();
  if (!ctx.previous) {
    val["skipped_no_previous"] = 1;
    return;
  }
  const cv::Size size = frame_size(ctx);
  if (size.area() <= 0 || (!ctx.dynamic.empty() && !is_mask(ctx.dynamic, size))) {
    val["skipped_bad_input"] = 1;
    return;
  }
  if (!has_objects(ctx, size)) {
    // Nothing the check could mark: no movable object in the labels (or no
    // labels, without mark_points_without_labels). The filter computed no
    // motion cues for it.
    val[is_mask(ctx.current.candidates, size) || is_mask(ctx.current.labels, size) ? "no_objects"
                                                                                  : "skipped_no_labels"] = 1;
    val["moving_objects"] = 0;
    return;
  }
  if (!ctx.tracked) {
    val["skipped_no_motion_cues"] = 1;
    return;
  }
  if (ctx.dynamic.empty()) ctx.dynamic = cv::Mat(size, CV_8UC1, cv::Scalar(0));

  const std::vector<TrackedPoint>& tracked = *ctx.tracked;
  val["tracked"] = static_cast<double>(tracked.size());

  // DS-SLAM's pair rejection: near the image edge, or 3x3 blocks too different.
  const cv::Mat& prev_grey = ctx.previous->grey;
  const cv::Mat& cur_grey = ctx.current.grey;
  const bool can_patch = o_.patch_max_abs_diff > 0 && is_mask(prev_grey, size) && is_mask(cur_grey, size);
  if (o_.patch_max_abs_diff > 0 && !can_patch) val["patch_check_skipped"] = 1;
  const int margin = std::max(o_.edge_margin_px, can_patch ? 1 : 0);  // the 3x3 block must fit
  std::vector<int> used;
  int rejected_edge = 0, rejected_patch = 0;
  for (size_t i = 0; i < tracked.size(); ++i) {
    const TrackedPoint& t = tracked[i];
    if (!finite(t.prev) || !finite(t.cur) || !inside(t.prev, size, margin) || !inside(t.cur, size, margin)) {
      ++rejected_edge;
      continue;
    }
    if (can_patch && patch_difference(prev_grey, t.prev, cur_grey, t.cur) > o_.patch_max_abs_diff) {
      ++rejected_patch;
      continue;
    }
    used.push_back(static_cast<int>(i));
  }
  val["rejected_edge"] = rejected_edge;
  val["rejected_patch"] = rejected_patch;
  val["used"] = static_cast<double>(used.size());

  const cv::Mat& cand = ctx.current.candidates;
  const bool cand_ok = is_mask(cand, size);
  const int min_points = std::max(o_.min_points, 8);
  if (static_cast<int>(used.size()) < min_points) {
    val["too_few_points"] = 1;
    return;
  }

  // Geometry on undistorted pixels (TUM / raw monocular images carry distortion).
  std::vector<cv::Point2f> prev_px, cur_px;
  prev_px.reserve(used.size());
  cur_px.reserve(used.size());
  for (int i : used) {
    prev_px.push_back(tracked[i].prev);
    cur_px.push_back(tracked[i].cur);
  }
  std::vector<cv::Point2f> prev_u = prev_px, cur_u = cur_px;
  try {
    if (ctx.calib && !ctx.calib->dist.empty() && !ctx.calib->K.empty()) {
      cv::undistortPoints(prev_px, prev_u, ctx.calib->K, ctx.calib->dist, cv::noArray(), ctx.calib->K);
      cv::undistortPoints(cur_px, cur_u, ctx.calib->K, ctx.calib->dist, cv::noArray(), ctx.calib->K);
    }
  } catch (const cv::Exception&) {
    val["skipped_bad_input"] = 1;
    return;
  }

  // The F: from every usable pair (DS-SLAM), or from those outside the candidates.
  std::vector<cv::Point2f> f_prev, f_cur;
  for (size_t k = 0; k < used.size(); ++k) {
    if (o_.f_exclude_candidates) {
      const TrackedPoint& t = tracked[used[k]];
      const bool in_cand = t.in_candidate || (cand_ok && mask_at(cand, t.cur));
      if (in_cand) continue;
    }
    f_prev.push_back(prev_u[k]);
    f_cur.push_back(cur_u[k]);
  }
  if (static_cast<int>(f_prev.size()) < min_points) {
    val["too_few_points"] = 1;
    return;
  }
  cv::Matx33d F;
  int f_inliers = 0;
  const auto t_f = Clock::now();
  try {
    std::vector<unsigned char> mask;
    const int method = o_.f_method == "usac" ? static_cast<int>(cv::USAC_ACCURATE) : static_cast<int>(cv::FM_RANSAC);
    const cv::Mat Fm = cv::findFundamentalMat(f_prev, f_cur, method,
                                              o_.f_ransac_threshold_px,
                                              std::clamp(o_.f_ransac_confidence, 0.0, 1.0),
                                              std::max(o_.f_ransac_iterations, 1), mask);
    // The 7-point fallback can stack up to three solutions: only one 3x3 F is an estimate.
    if (Fm.rows != 3 || Fm.cols != 3 || !cv::checkRange(Fm)) {
      val["f_failed"] = 1;
      return;
    }
    cv::Mat F64;
    Fm.convertTo(F64, CV_64F);
    for (unsigned char m : mask) f_inliers += m != 0;
    if (o_.f_refine_on_inliers && f_inliers >= 8 && mask.size() == f_prev.size()) {
      std::vector<cv::Point2f> in_prev, in_cur;
      for (size_t k = 0; k < mask.size(); ++k)
        if (mask[k]) {
          in_prev.push_back(f_prev[k]);
          in_cur.push_back(f_cur[k]);
        }
      const cv::Mat Fr = cv::findFundamentalMat(in_prev, in_cur, cv::FM_8POINT);
      if (Fr.rows == 3 && Fr.cols == 3 && cv::checkRange(Fr)) {
        Fr.convertTo(F64, CV_64F);
        val["f_refined"] = 1;
      }
    }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) F(r, c) = F64.at<double>(r, c);
  } catch (const cv::Exception&) {
    val["f_failed"] = 1;
    return;
  }
  val["f_inliers"] = f_inliers;
  val["f_ms"] = ms_since(t_f);

  // STDyn Sec. III-B.1 (Fig. 3): a point farther than the threshold from its
  // epipolar line is an outlier, i.e. dynamic.
  std::vector<unsigned char> dynamic(used.size(), 0);
  int n_dynamic = 0;
  for (size_t k = 0; k < used.size(); ++k) {
    const double d = epipolar_distance(F, prev_u[k], cur_u[k]);
    dynamic[k] = std::isfinite(d) && d > o_.epipolar_threshold_px;
    n_dynamic += dynamic[k];
    (dynamic[k] ? report.dynamic_points : report.static_points).push_back(cur_px[k]);
  }
  val["dynamic"] = n_dynamic;
  val["static"] = static_cast<double>(used.size()) - n_dynamic;

  // The objects: segmented regions of the current frame.
  const cv::Mat& labels = ctx.current.labels;
  const bool labels_ok = is_mask(labels, size);
  if ((!cand.empty() && !cand_ok) || (!labels.empty() && !labels_ok)) val["bad_labels"] = 1;
  if (!cand_ok && !labels_ok) {
    // No network: the method has no objects to decide on.
    val["skipped_no_labels"] = 1;
    if (o_.mark_points_without_labels && o_.no_labels_point_radius_px > 0) {
      for (size_t k = 0; k < used.size(); ++k)
        if (dynamic[k])
          cv::circle(ctx.dynamic, cur_px[k], o_.no_labels_point_radius_px, cv::Scalar(255), cv::FILLED);
      val["marked_points_without_labels"] = n_dynamic;
    }
    return;
  }
  // Only the movable classes split objects (a chair touching a person is no object).
  cv::Mat movable_labels;
  if (labels_ok) cv::LUT(labels, movable_lut_, movable_labels);
  // No candidates from an earlier stage: the movable classes' own regions.
  const cv::Mat regions_of = cand_ok ? cand : cv::Mat(movable_labels != 0);
  const auto t_regions = Clock::now();
  const CandidateRegions& objects = ctx.regions.get(regions_of, movable_labels, true);
  val["regions_ms"] = ms_since(t_regions);
  const cv::Mat& ids = objects.ids;
  const int n_objects = objects.count;
  val["objects"] = n_objects;
  if (n_objects <= 0) {
    val["no_objects"] = 1;
    val["moving_objects"] = 0;
    return;
  }

  std::vector<int> n_dyn(n_objects + 1, 0), n_all(n_objects + 1, 0);
  for (size_t k = 0; k < used.size(); ++k) {
    const int id = object_at(ids, cur_px[k], o_.object_search_radius_px);
    if (id <= 0) continue;
    ++n_all[id];
    n_dyn[id] += dynamic[k];
  }
  const RegionInheritance inherited = previous.inherit(objects, memory_usable);
  std::vector<unsigned char> moving(n_objects + 1, 0);  // the age of a moving object's decision
  int n_moving = 0, kept_moving = 0;
  for (int id = 1; id <= n_objects; ++id) {
    const bool enough = n_dyn[id] >= std::max(o_.min_dynamic_points, 1);
    const bool ratio =
        o_.min_dynamic_ratio <= 0 || (n_all[id] > 0 && n_dyn[id] >= o_.min_dynamic_ratio * n_all[id]);
    const bool proven = enough && ratio;
    const bool kept = !proven && inherited.keeps_moving(objects, id, o_.keep_moving_frames, o_.keep_moving_overlap);
    if (proven || kept) moving[id] = region_age(proven, inherited.least_age[id]);
    n_moving += moving[id] != 0;
    kept_moving += kept;
  }
  val["kept_moving"] = kept_moving;
  if (o_.keep_moving_frames > 0) memory_.remember(ctx.current.id, objects, moving);
  // Whole objects go into the mask: "ORB features inside segmented objects ... are rejected".
  if (n_moving > 0) {
    for (int v = 0; v < ids.rows; ++v) {
      const int* row = ids.ptr<int>(v);
      unsigned char* out = ctx.dynamic.ptr<unsigned char>(v);
      for (int u = 0; u < ids.cols; ++u)
        if (row[u] > 0 && moving[row[u]]) out[u] = 255;
    }
  }
  report.regions += n_moving;
  val["moving_objects"] = n_moving;
}

}  // namespace dynaorb::dynamic
