// DM-SLAM dynamic point detection (Sec. 3.2.4, eq. 6-10) and the per-mask
// motion decision.
#include "dynaorb/dynamic/dm_stage.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "dynaorb/core/stopwatch.h"
#include "dynaorb/dynamic/candidate_regions.h"
#include "dynaorb/io/errors.h"
#include "file_node_options.h"
#include "../core/option_checks.h"

namespace dynaorb::dynamic {

void DmOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "min_static_points", min_static_points);
  read_option(node, "min_dynamic_offset_px", min_dynamic_offset_px);
  read_option(node, "epipolar_threshold_px", epipolar_threshold_px);
  read_option(node, "region_dynamic_fraction", region_dynamic_fraction);
  read_option(node, "region_dynamic_fraction_mono", region_dynamic_fraction_mono);
  read_option(node, "min_region_points", min_region_points);
  read_option(node, "few_points_policy", few_points_policy);
  read_option(node, "split_by_label", split_by_label);
  read_option(node, "keep_moving_frames", keep_moving_frames);
  read_option(node, "keep_moving_frames_mono", keep_moving_frames_mono);
  read_option(node, "keep_moving_overlap", keep_moving_overlap);
  validate();
}

void DmOptions::validate() const {
  const dynaorb::detail::OptionChecks c("Dynamic.dm");
  c.at_least("min_static_points", min_static_points, 1);
  c.non_negative("min_dynamic_offset_px", min_dynamic_offset_px, "eq. 8 alone");
  c.positive("epipolar_threshold_px", epipolar_threshold_px);
  c.between("region_dynamic_fraction", region_dynamic_fraction, 0, 1, true);
  c.between("region_dynamic_fraction_mono", region_dynamic_fraction_mono, 0, 1, true);
  c.at_least("min_region_points", min_region_points, 1);
  if (few_points_policy != "previous" && few_points_policy != "static" && few_points_policy != "dynamic")
    throw InputError("Dynamic.dm option 'few_points_policy' is '" + few_points_policy +
                     "'; it must be previous, static or dynamic");
  c.at_least("keep_moving_frames", keep_moving_frames, 0);
  c.at_least("keep_moving_frames_mono", keep_moving_frames_mono, 0);
  c.between("keep_moving_overlap", keep_moving_overlap, 0, 1, true);
}

bool DmStage::needs_motion_cues_for(const Context& ctx) const {
  const cv::Mat& cand = ctx.current.candidates;
  return !cand.empty() && cand.type() == CV_8UC1 && cv::countNonZero(cand) > 0;
}

std::optional<RegionsRequest> DmStage::regions_wanted(const Context& ctx) const {
  if (!needs_motion_cues_for(ctx)) return std::nullopt;
  return regions_request(ctx);
}

void DmStage::reset() { memory_.reset(); }

namespace {

enum class Judgement { kNone, kStatic, kDynamic };

bool finite(const cv::Point2f& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// Non-finite pixels stay non-finite (and are counted by the caller) rather
// than reaching OpenCV.
std::vector<cv::Point2f> undistorted(const std::vector<cv::Point2f>& px, const map::Calibration& c) {
  if (c.dist.empty() || px.empty()) return px;
  std::vector<cv::Point2f> in, u;
  std::vector<size_t> where;
  for (size_t i = 0; i < px.size(); ++i)
    if (finite(px[i])) {
      in.push_back(px[i]);
      where.push_back(i);
    }
  std::vector<cv::Point2f> out(px.size(), cv::Point2f(NAN, NAN));
  if (in.empty()) return out;
  const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  cv::undistortPoints(in, u, K, c.dist, cv::noArray(), K);
  for (size_t k = 0; k < where.size(); ++k) out[where[k]] = u[k];
  return out;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

void DmStage::process(Context& ctx, StageReport& report) {
  auto& val = report.values;
  const DmOptions& o = options_;
  const bool mono = ctx.sensor == Sensor::kMono;
  // The memory only speaks for the frame right before this one.
  const bool memory_usable = ctx.previous && memory_.holds(ctx.previous->id, ctx.current.candidates.size());
  const RegionMemory previous = std::move(memory_);
  reset();
  auto skip = [&](const char* why) { val[why] = 1; };

  if (!ctx.calib || !(ctx.calib->fx > 0) || !(ctx.calib->fy > 0)) return skip("skipped_no_calibration");
  if (!ctx.previous) return skip("skipped_no_previous");
  const cv::Mat& cand = ctx.current.candidates;
  if (cand.empty() || cand.type() != CV_8UC1) return skip("skipped_no_candidates");
  if (cv::countNonZero(cand) == 0) return skip("skipped_no_candidates");
  if (!ctx.dynamic.empty() && (ctx.dynamic.size() != cand.size() || ctx.dynamic.type() != CV_8UC1))
    return skip("skipped_bad_dynamic_mask");
  if (!ctx.tracked || !ctx.ego) return skip("skipped_no_motion_cues");
  const std::vector<TrackedPoint>& pts = *ctx.tracked;
  const EgoMotion& ego = *ctx.ego;
  if (pts.empty()) return skip("skipped_no_points");
  if (mono ? !ego.has_F : !ego.valid) return skip("skipped_no_ego_motion");
  const map::Calibration& calib = *ctx.calib;

  std::vector<cv::Point2f> prev_px(pts.size()), cur_px(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    prev_px[i] = pts[i].prev;
    cur_px[i] = pts[i].cur;
  }
  const std::vector<cv::Point2f> p_u = undistorted(prev_px, calib);
  const std::vector<cv::Point2f> q_u = undistorted(cur_px, calib);

  std::vector<Judgement> judged(pts.size(), Judgement::kNone);
  int candidate_points = 0, no_depth = 0, behind = 0, non_finite = 0;
  if (mono) {
    // Eq. 9-10: distance of q to the epipolar line F p.
    std::vector<double> static_d;
    for (size_t i = 0; i < pts.size(); ++i) {
      if (pts[i].in_candidate) ++candidate_points;
      if (!finite(p_u[i]) || !finite(q_u[i])) {
        ++non_finite;
        continue;
      }
      const cv::Vec3d l = ego.F * cv::Vec3d(p_u[i].x, p_u[i].y, 1.0);
      const double norm = std::hypot(l[0], l[1]);
      if (!(norm > 0)) {
        ++non_finite;
        continue;
      }
      const double D = std::abs(q_u[i].x * l[0] + q_u[i].y * l[1] + l[2]) / norm;
      if (!pts[i].in_candidate) {
        static_d.push_back(D);
        continue;
      }
      judged[i] = D > o.epipolar_threshold_px ? Judgement::kDynamic : Judgement::kStatic;
    }
    val["static_median_epipolar_px"] = median_of(static_d);
    val["static_set_points"] = static_cast<double>(static_d.size());
  } else {
    // Offset vectors q - q_hat of every previous point with depth.
    std::vector<double> eps(pts.size(), 0), abs_theta(pts.size(), 0);
    std::vector<unsigned char> has_offset(pts.size(), 0);
    for (size_t i = 0; i < pts.size(); ++i) {
      if (pts[i].in_candidate) ++candidate_points;
      const float z = pts[i].prev_depth;
      if (!finite(p_u[i]) || !finite(q_u[i])) {
        ++non_finite;
        continue;
      }
      if (!std::isfinite(z) || z <= 0.f) {
        no_depth += pts[i].in_candidate;
        continue;
      }
      const Eigen::Vector3d X = ego.T_cur_prev * calib.unproject(p_u[i].x, p_u[i].y, z);
      if (!(X.z() > 1e-6)) {
        behind += pts[i].in_candidate;
        continue;
      }
      const Eigen::Vector2d q_hat = calib.project(X);
      const double du = q_u[i].x - q_hat.x(), dv = q_u[i].y - q_hat.y();
      eps[i] = std::hypot(du, dv);
      abs_theta[i] = std::abs(std::atan2(dv, du));
      has_offset[i] = 1;
    }
    // Eq. 6-7 over V_state, the offsets outside the candidate regions.
    double sum_eps = 0, sum_theta = 0;
    int n = 0;
    for (size_t i = 0; i < pts.size(); ++i)
      if (has_offset[i] && !pts[i].in_candidate) {
        sum_eps += eps[i];
        sum_theta += abs_theta[i];
        ++n;
      }
    val["static_set_points"] = n;
    if (n < std::max(o.min_static_points, 1)) return skip("skipped_few_static_points");
    // A perfect ego-motion (all static offsets 0) would divide by zero: any
    // offset is then infinitely larger than the static ones.
    const double tiny = 1e-12;
    auto T = [&](size_t i) {
      return eps[i] / std::max(sum_eps, tiny) + abs_theta[i] / std::max(sum_theta, tiny);
    };
    double sum_T = 0;
    for (size_t i = 0; i < pts.size(); ++i)
      if (has_offset[i] && !pts[i].in_candidate) sum_T += T(i);
    const double phi_s = sum_T / n;
    val["phi_s"] = phi_s;
    val["static_mean_offset_px"] = sum_eps / n;
    val["static_mean_abs_angle_rad"] = sum_theta / n;
    // Eq. 8, T_j normalised by the static sums (see dm_stage.h).
    for (size_t i = 0; i < pts.size(); ++i)
      if (has_offset[i] && pts[i].in_candidate)
        judged[i] = T(i) > phi_s && eps[i] > o.min_dynamic_offset_px ? Judgement::kDynamic
                                                                      : Judgement::kStatic;
  }

  // Per-region decision.
  const auto t_regions = Clock::now();
  const CandidateRegions& regions = ctx.regions.get(regions_request(ctx));
  val["regions_ms"] = ms_since(t_regions);
  // The vote is the segmented object's (DM-SLAM: the points that "fall in the
  // potentially moving area"): points in the margin the candidates add around
  // the labels are background more often than not and would dilute it.
  const cv::Mat& labels = ctx.current.labels;
  const bool vote_on_labels = !labels.empty() && labels.type() == CV_8UC1 && labels.size() == cand.size();
  std::vector<int> n_judged(regions.count + 1, 0), n_dynamic(regions.count + 1, 0);
  int dynamic_points = 0, static_points = 0, outside_regions = 0, in_margin = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (judged[i] == Judgement::kNone) {
      if (!pts[i].in_candidate && finite(pts[i].cur)) report.static_points.push_back(pts[i].cur);
      continue;
    }
    const bool dyn = judged[i] == Judgement::kDynamic;
    (dyn ? report.dynamic_points : report.static_points).push_back(pts[i].cur);
    (dyn ? dynamic_points : static_points) += 1;
    // Regions live in the current image: a point counts for the region its
    // current position falls in.
    const int x = cvRound(pts[i].cur.x), y = cvRound(pts[i].cur.y);
    if (x < 0 || y < 0 || x >= cand.cols || y >= cand.rows || regions.ids.at<int>(y, x) == 0) {
      ++outside_regions;
      continue;
    }
    if (vote_on_labels && labels.at<unsigned char>(y, x) == 0) {
      ++in_margin;
      continue;
    }
    const int r = regions.ids.at<int>(y, x);
    ++n_judged[r];
    n_dynamic[r] += dyn;
  }

  if (ctx.dynamic.empty()) ctx.dynamic = cv::Mat(cand.size(), CV_8UC1, cv::Scalar(0));
  // Under the "previous" policy a region with too few points takes the
  // decision that covered more of it in the frame before, and a region that
  // keeps moving is one mostly covered by a region found moving then: its
  // overlaps with both, and the least age of the dynamic pixels it covers,
  // counted in one pass over the region image.
  const int keep_frames = mono ? o.keep_moving_frames_mono : o.keep_moving_frames;
  const RegionInheritance inherited =
      previous.inherit(regions, memory_usable && (o.few_points_policy == "previous" || keep_frames > 0));
  const double fraction = mono ? o.region_dynamic_fraction_mono : o.region_dynamic_fraction;
  // Age of each dynamic region: 1 when its own points proved it moving in
  // this frame, else one more than the least age of what it inherited.
  std::vector<unsigned char> ages(regions.count + 1, 0);
  int marked = 0, few = 0, few_kept_dynamic = 0, kept_moving = 0;
  for (int r = 1; r <= regions.count; ++r) {
    bool dyn = false, proven = false;
    if (n_judged[r] >= std::max(o.min_region_points, 1)) {
      dyn = proven = static_cast<double>(n_dynamic[r]) >= fraction * n_judged[r];
    } else {
      ++few;
      if (o.few_points_policy == "dynamic") {
        dyn = proven = true;
      } else if (o.few_points_policy == "previous" && memory_usable) {
        dyn = inherited.dynamic_pixels[r] > 0 && inherited.dynamic_pixels[r] >= inherited.static_pixels[r];
      }
      few_kept_dynamic += dyn;
    }
    if (!dyn && inherited.keeps_moving(regions, r, keep_frames, o.keep_moving_overlap)) {
      dyn = true;
      ++kept_moving;
    }
    if (dyn) ages[r] = region_age(proven, inherited.least_age[r]);
    marked += dyn;
  }
  cv::bitwise_or(ctx.dynamic, memory_.remember(ctx.current.id, regions, ages), ctx.dynamic);

  report.regions = marked;
  val["regions"] = regions.count;
  val["regions_dynamic"] = marked;
  val["regions_few_points"] = few;
  val["regions_few_points_dynamic"] = few_kept_dynamic;
  val["regions_kept_moving"] = kept_moving;
  val["candidate_points"] = candidate_points;
  val["dynamic_points"] = dynamic_points;
  val["static_points"] = static_points;
  val["points_outside_regions"] = outside_regions;
  val["points_in_margin"] = in_margin;
  val["candidate_points_no_depth"] = no_depth;
  val["candidate_points_behind_camera"] = behind;
  val["points_non_finite"] = non_finite;
}

}  // namespace dynaorb::dynamic
