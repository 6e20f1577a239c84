#include "dynaorb/dynamic/li_stage.h"

#include <algorithm>
#include <cmath>

#include "dynaorb/core/stopwatch.h"
#include "dynaorb/dynamic/li_disparity.h"
#include "dynaorb/dynamic/li_rigidity.h"
#include "dynaorb/dynamic/li_superpixels.h"

namespace dynaorb::dynamic {

namespace {

bool is_grey(const cv::Mat& m) { return !m.empty() && m.type() == CV_8UC1; }

// The share of `rect` that the union of `others` covers.
double covered_share(const cv::Rect& rect, const std::vector<cv::Rect>& others) {
  if (rect.area() == 0) return 0;
  cv::Mat covered(rect.size(), CV_8UC1, cv::Scalar(0));
  for (const cv::Rect& r : others) {
    const cv::Rect overlap = r & rect;
    if (overlap.area() > 0) covered(overlap - rect.tl()).setTo(1);
  }
  return cv::countNonZero(covered) / static_cast<double>(rect.area());
}

// The median flow of the tracks that start inside `rect` (previous image):
// of its dynamic ones when there are at least `min_dynamic` (enough to make a
// moving object), else of all; none: no shift.
cv::Point median_flow(const cv::Rect& rect, const std::vector<LiTrack>& tracks, int min_dynamic) {
  std::vector<float> dx, dy, dx_dynamic, dy_dynamic;
  for (const LiTrack& t : tracks)
    if (rect.contains(cv::Point(cvRound(t.prev.x), cvRound(t.prev.y)))) {
      dx.push_back(t.cur.x - t.prev.x);
      dy.push_back(t.cur.y - t.prev.y);
      if (t.dynamic) {
        dx_dynamic.push_back(dx.back());
        dy_dynamic.push_back(dy.back());
      }
    }
  if (static_cast<int>(dx_dynamic.size()) >= min_dynamic) {
    dx.swap(dx_dynamic);
    dy.swap(dy_dynamic);
  }
  if (dx.empty()) return {0, 0};
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
  return {cvRound(dx[dx.size() / 2]), cvRound(dy[dy.size() / 2])};
}

}  // namespace

LiStage::LiStage(LiOptions options) : o_(std::move(options)) { o_.validate(); }

void LiStage::process(Context& ctx, StageReport& report) {
  const auto t_start = Clock::now();
  last_ = LiFrameDetail();
  detect(ctx, report);
  if (o_.keep_frames > 0) carry_rectangles(ctx, report);
  report.values["total_ms"] = ms_since(t_start);
}

void LiStage::detect(Context& ctx, StageReport& report) {
  auto& v = report.values;

  if (!ctx.calib) {
    v["skipped_no_calibration"] = 1;
    return;
  }
  const cv::Mat& grey = ctx.current.grey;
  if (!is_grey(grey) || grey.cols < 32 || grey.rows < 32) {
    v["skipped_bad_input"] = 1;
    return;
  }
  if (!is_grey(ctx.current.right) || ctx.current.right.size() != grey.size()) {
    v["skipped_no_right"] = 1;
    return;
  }
  if (ctx.dynamic.empty() || ctx.dynamic.size() != grey.size() || ctx.dynamic.type() != CV_8UC1)
    ctx.dynamic = cv::Mat::zeros(grey.size(), CV_8UC1);

  try {
    // Step 1: SGBM, and the depth the other stages read.
    auto t0 = Clock::now();
    last_.disparity = li_disparity(grey, ctx.current.right, o_);
    v["disparity_ms"] = ms_since(t0);
    if (last_.disparity.empty()) {
      v["skipped_bad_input"] = 1;
      return;
    }
    v["disparity_valid"] = cv::countNonZero(last_.disparity) / static_cast<double>(grey.total());
    if (ctx.current.depth.empty() && ctx.calib->bf > 0) {
      ctx.current.depth = li_depth_from_disparity(last_.disparity, ctx.calib->bf);
      v["depth_filled"] = 1;
    }

    if (!ctx.previous) {
      v["skipped_no_previous"] = 1;
      return;
    }
    const cv::Mat& prev = ctx.previous->grey;
    if (!is_grey(prev) || prev.size() != grey.size()) {
      v["skipped_previous_mismatch"] = 1;
      return;
    }

    // Step 2: dynamic feature points (eq. 1-3).
    last_.epipolar = li_epipolar_check(prev, grey, last_.disparity, *ctx.calib, o_, ctx.previous->dynamic);
    const LiEpipolarResult& e = last_.epipolar;
    v["corners_ms"] = e.corners_ms;
    v["flow_ms"] = e.flow_ms;
    v["fmatrix_ms"] = e.fmatrix_ms;
    v["corners"] = e.corners;
    v["tracked"] = static_cast<double>(e.tracks.size());
    v["judged"] = e.judged;
    v["f_inliers"] = e.f_inliers;
    if (o_.f_exclude_previous_dynamic) {
      v["f_fitted"] = e.f_fitted;
      v["f_excluded"] = e.f_excluded;
    }
    if (!e.failure.empty()) {
      v[e.failure] = 1;
      return;
    }
    v["epipolar_dynamic"] = e.dynamic;
    if (o_.rigid_check) rigidity_check(ctx, report);
    std::vector<cv::Point2f> dyn_pts;
    std::vector<float> dyn_disp;
    for (size_t i = 0; i < e.tracks.size(); ++i) {
      const LiTrack& t = e.tracks[i];
      if (t.distance < 0) continue;
      if (t.dynamic) {
        last_.dynamic_tracks.push_back(static_cast<int>(i));
        dyn_pts.push_back(t.cur);
        dyn_disp.push_back(t.disparity);
        report.dynamic_points.push_back(t.cur);
      } else {
        report.static_points.push_back(t.cur);
      }
    }
    v["dynamic"] = static_cast<double>(dyn_pts.size());
    v["static"] = static_cast<double>(report.static_points.size());

    // Step 3: ROIs (eq. 4).
    t0 = Clock::now();
    last_.clusters = li_cluster_dynamic_points(dyn_pts, dyn_disp, grey.size(), o_);
    v["rois_ms"] = ms_since(t0);
    v["rois"] = static_cast<double>(last_.clusters.size());
    if (last_.clusters.empty()) {
      v["no_moving_object"] = 1;
      return;
    }
    segment_and_mark(grey, ctx, report);
  } catch (const cv::Exception&) {
    // OpenCV refusing an input it should not have been given: degrade, never crash.
    v["failed_opencv"] = 1;
  }
}

void LiStage::rigidity_check(Context& ctx, StageReport& report) {
  auto& v = report.values;
  const auto t0 = Clock::now();
  std::optional<Eigen::Isometry3d> prior;
  if (ctx.T_cw_predicted && ctx.previous->T_cw) prior = *ctx.T_cw_predicted * ctx.previous->T_cw->inverse();
  last_.rigidity = li_rigidity_check(last_.epipolar, ctx.previous->depth, *ctx.calib, prior, o_);
  const LiRigidityResult& r = last_.rigidity;
  v["rigid_ms"] = ms_since(t0);
  v["rigid_prior"] = r.used_prior ? 1 : 0;
  v["rigid_candidates"] = r.candidates;
  v["rigid_inliers"] = r.inliers;
  v["rigid_judged"] = r.judged;
  v["rigid_over_threshold"] = r.over_threshold;
  v["rigid_added"] = r.added;
  if (!r.failure.empty()) v["rigid_" + r.failure] = 1;
}

void LiStage::carry_rectangles(Context& ctx, StageReport& report) {
  if (!ctx.previous || ctx.dynamic.empty()) {  // no frame to carry them from
    kept_.clear();
    return;
  }
  const cv::Rect image(0, 0, ctx.dynamic.cols, ctx.dynamic.rows);
  std::vector<KeptRectangle> found;  // this frame's new rectangles
  for (size_t i = 0; i < last_.rectangles.size(); ++i)
    found.push_back({last_.rectangles[i] & image, 0, 1, last_.rectangle_disparity[i]});
  std::vector<KeptRectangle> next;
  for (KeptRectangle k : kept_) {
    k.rect += median_flow(k.rect, last_.epipolar.tracks, o_.min_cluster_points);
    k.rect &= image;
    if (k.rect.area() == 0) continue;
    // A new rectangle that mostly covers it, or lies mostly inside it, is
    // the same object found again.
    for (KeptRectangle& f : found)
      if (covered_share(k.rect, {f.rect}) >= o_.keep_covered_fraction ||
          covered_share(f.rect, {k.rect}) >= o_.keep_covered_fraction)
        f.hits = std::max(f.hits, k.hits + 1);
    if (covered_share(k.rect, last_.rectangles) >= o_.keep_covered_fraction) continue;  // found anew
    if (++k.age > o_.keep_frames || k.hits < o_.keep_min_hits) continue;
    li_mark_region(ctx.dynamic, k.rect, last_.disparity, k.disparity, o_);
    last_.kept.push_back(k.rect);
    next.push_back(k);
  }
  next.insert(next.end(), found.begin(), found.end());
  kept_ = std::move(next);
  report.values["kept_rectangles"] = static_cast<double>(last_.kept.size());
  report.regions += static_cast<int>(last_.kept.size());
}

void LiStage::segment_and_mark(const cv::Mat& grey, Context& ctx, StageReport& report) {
  auto& v = report.values;
  std::vector<cv::Point2f> dyn_pts;
  for (int i : last_.dynamic_tracks) dyn_pts.push_back(last_.epipolar.tracks[i].cur);

  // Step 4: improved SLIC on the (merged) ROIs, S_step of eq. 6 from the
  // whole image so superpixels keep one size whatever the ROI.
  auto t0 = Clock::now();
  std::vector<cv::Rect> rois;
  for (const LiCluster& c : last_.clusters) rois.push_back(c.roi);
  last_.slic_areas = li_merge_overlapping(rois);
  const double step = std::sqrt(static_cast<double>(grey.total()) / o_.slic_k);
  last_.labels = cv::Mat(grey.size(), CV_32SC1, cv::Scalar(-1));
  double roi_pixels = 0, iterations = 0, visits = 0;
  for (const cv::Rect& r : last_.slic_areas) {
    const LiSuperpixels sp = li_slic(grey(r), step, o_.slic_nc, o_.slic_max_iterations);
    if (sp.count == 0) continue;
    cv::Mat dst = last_.labels(r);
    cv::add(sp.labels, cv::Scalar(last_.superpixels), dst);
    last_.superpixels += sp.count;
    roi_pixels += r.area();
    iterations = std::max(iterations, static_cast<double>(sp.iterations));
    visits += static_cast<double>(sp.visits);
  }
  v["slic_ms"] = ms_since(t0);
  v["roi_pixels"] = roi_pixels;
  v["superpixels"] = last_.superpixels;
  v["slic_iterations"] = iterations;
  v["slic_visits_per_pixel"] = roi_pixels > 0 ? visits / roi_pixels : 0;

  // Step 5: disparity planes (eq. 8).
  t0 = Clock::now();
  const cv::Mat plane_disparity = o_.fill_occlusions ? li_fill_occlusions(last_.disparity) : last_.disparity;
  last_.planes = li_fit_superpixel_planes(last_.labels, last_.superpixels, plane_disparity,
                                          last_.slic_areas, o_);
  int with_plane = 0;
  for (const LiPlane& p : last_.planes) with_plane += p.valid ? 1 : 0;
  v["planes_ms"] = ms_since(t0);
  v["planes"] = with_plane;

  // Step 6: boundary labels (eq. 9-11).
  t0 = Clock::now();
  last_.boundaries = li_label_boundaries(last_.labels, last_.planes, last_.slic_areas, o_);
  int n_type[5] = {0, 0, 0, 0, 0};
  for (const LiBoundary& b : last_.boundaries.list) ++n_type[static_cast<int>(b.type)];
  v["boundaries_ms"] = ms_since(t0);
  v["boundaries"] = static_cast<double>(last_.boundaries.list.size());
  v["unlabelled_boundaries"] = n_type[static_cast<int>(LiBoundaryType::kUnknown)];
  v["coplanar"] = n_type[static_cast<int>(LiBoundaryType::kCoplanar)];
  v["hinge"] = n_type[static_cast<int>(LiBoundaryType::kHinge)];
  v["occlusion_boundaries"] = n_type[static_cast<int>(LiBoundaryType::kLeftOcclusion)] +
                              n_type[static_cast<int>(LiBoundaryType::kRightOcclusion)];

  // Step 7: rectangles, into the exclusion mask.
  t0 = Clock::now();
  last_.regions = li_dynamic_rectangles(dyn_pts, last_.clusters, last_.labels, last_.boundaries, o_);
  int rejected = 0;
  cv::Mat own(grey.size(), CV_8UC1, cv::Scalar(0));
  for (size_t c = 0; c < last_.regions.size(); ++c) {
    const LiRegion& r = last_.regions[c];
    if (!r.dynamic) {
      ++rejected;
      continue;
    }
    const float object_disparity = last_.clusters[c].min_disparity;
    last_.rectangles.push_back(r.rect);
    last_.rectangle_disparity.push_back(object_disparity);
    li_mark_region(own, r.rect, last_.disparity, object_disparity, o_);
  }
  cv::bitwise_or(ctx.dynamic, own, ctx.dynamic);
  v["rectangles_ms"] = ms_since(t0);
  v["rectangles"] = static_cast<double>(last_.rectangles.size());
  v["rejected_clusters"] = rejected;
  report.regions = static_cast<int>(last_.rectangles.size());
  v["marked_fraction"] = cv::countNonZero(own) / static_cast<double>(grey.total());
}

}  // namespace dynaorb::dynamic
