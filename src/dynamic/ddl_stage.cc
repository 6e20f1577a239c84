// DDL-SLAM's multi-view geometry (Algorithm 1) and the region growing that
// turns its dynamic points into dynamic regions.
#include "dynaorb/dynamic/ddl_stage.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "ddl_keyframes.h"
#include "dynaorb/core/stopwatch.h"
#include "file_node_options.h"
#include "../core/option_checks.h"
#include "view_geometry.h"

namespace dynaorb::dynamic {

using ddl::KeyframeEvidence;
using ddl::Reference;
using ddl::Seen;

void DdlOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "reference_keyframes", reference_keyframes);
  read_option(node, "min_overlap", min_overlap);
  read_option(node, "parallax_threshold_deg", parallax_threshold_deg);
  read_option(node, "parallax_marks_dynamic", parallax_marks_dynamic);
  read_option(node, "depth_threshold_m", depth_threshold_m);
  read_option(node, "max_depth_m", max_depth_m);
  read_option(node, "depth_search_radius_px", depth_search_radius_px);
  read_option(node, "border_px", border_px);
  read_option(node, "refine_pose", refine_pose);
  read_option(node, "refine_reprojection_px", refine_reprojection_px);
  read_option(node, "refine_max_shift_px", refine_max_shift_px);
  read_option(node, "refine_min_inliers", refine_min_inliers);
  read_option(node, "refine_points_per_keyframe", refine_points_per_keyframe);
  read_option(node, "vanished_points_dynamic", vanished_points_dynamic);
  read_option(node, "seed_sliding_surfaces", seed_sliding_surfaces);
  read_option(node, "confirm_with_keyframes", confirm_with_keyframes);
  read_option(node, "confirm_search_radius_px", confirm_search_radius_px);
  read_option(node, "confirm_min_zncc", confirm_min_zncc);
  read_option(node, "confirm_min_std_grey", confirm_min_std_grey);
  read_option(node, "confirm_patch_radius_px", confirm_patch_radius_px);
  read_option(node, "confirm_blur_sigma_px", confirm_blur_sigma_px);
  read_option(node, "grow_max_step_inv_depth", grow_max_step_inv_depth);
  read_option(node, "grow_max_from_seed_m", grow_max_from_seed_m);
  read_option(node, "dilation_px", dilation_px);
  read_option(node, "combine_semantic", combine_semantic);
  validate();
}

void DdlOptions::validate() const {
  const dynaorb::detail::OptionChecks c("Dynamic.ddl");
  c.at_least("reference_keyframes", reference_keyframes, 1);
  if (!(min_overlap >= 0 && min_overlap <= 1)) c.fail("min_overlap", min_overlap, "in [0, 1] (0: any overlap)");
  c.between("parallax_threshold_deg", parallax_threshold_deg, 0, 180, false);
  c.positive("depth_threshold_m", depth_threshold_m);
  c.non_negative("max_depth_m", max_depth_m, "no limit");
  c.at_least("depth_search_radius_px", depth_search_radius_px, 0);
  c.at_least("border_px", border_px, 0);
  c.positive("refine_reprojection_px", refine_reprojection_px);
  c.positive("refine_max_shift_px", refine_max_shift_px);
  c.at_least("refine_min_inliers", refine_min_inliers, 4);  // a PnP pose
  c.at_least("refine_points_per_keyframe", refine_points_per_keyframe, 1);
  c.at_least("confirm_search_radius_px", confirm_search_radius_px, 0);
  if (!(confirm_min_zncc <= 1) || std::isinf(confirm_min_zncc))
    c.fail("confirm_min_zncc", confirm_min_zncc, "a finite number <= 1 (<= -1: no texture test)");
  c.non_negative("confirm_min_std_grey", confirm_min_std_grey, "no contrast floor");
  c.at_least("confirm_patch_radius_px", confirm_patch_radius_px, 1);
  c.non_negative("confirm_blur_sigma_px", confirm_blur_sigma_px, "no blur");
  c.positive("grow_max_step_inv_depth", grow_max_step_inv_depth);
  c.non_negative("grow_max_from_seed_m", grow_max_from_seed_m, "no limit");
  c.at_least("dilation_px", dilation_px, 0);
}

namespace {

bool is_depth(const cv::Mat& m, const cv::Size& size) {
  return !m.empty() && m.type() == CV_32FC1 && m.size() == size;
}

bool is_mask(const cv::Mat& m, const cv::Size& size) {
  return !m.empty() && m.type() == CV_8UC1 && m.size() == size;
}

// The pose of the low-cost tracking (DDL-SLAM Fig. 2: "the camera poses are
// tracked utilizing the static part of the frame", before the multi-view
// check). source: 1 tracked, 2 ego-motion, 3 SLAM's prediction.
std::optional<Eigen::Isometry3d> current_pose(const Context& ctx, int& source) {
  if (ctx.current.T_cw) {
    source = 1;
    return ctx.current.T_cw;
  }
  // The ego-motion comes from the points outside the movable-class regions:
  // the paper's tracking on the static part. The constant-velocity
  // prediction ignores this frame's images altogether, so it comes last.
  if (ctx.ego && ctx.ego->valid && ctx.previous && ctx.previous->T_cw) {
    source = 2;
    return ctx.ego->T_cur_prev * *ctx.previous->T_cw;
  }
  if (ctx.T_cw_predicted) {
    source = 3;
    return ctx.T_cw_predicted;
  }
  source = 0;
  return std::nullopt;
}

}  // namespace

namespace {

// ddl_grow_regions with the test for a pixel kept out as a template
// parameter: the stage's test is asked for every neighbour the region
// reaches, and a call through std::function there costs more than the
// cached answer.
template <class Blocked>
cv::Mat grow_regions(const cv::Mat& depth, const std::vector<cv::Point>& seeds, const DdlOptions& o,
                     Blocked&& blocked) {
  cv::Mat region(depth.size(), CV_8UC1, cv::Scalar(0));
  if (depth.empty() || depth.type() != CV_32FC1) return region;
  const int w = depth.cols, h = depth.rows;
  std::vector<int> queue;
  const double step = o.grow_max_step_inv_depth;
  const double band = o.grow_max_from_seed_m;
  for (const cv::Point& s : seeds) {
    if (s.x < 0 || s.y < 0 || s.x >= w || s.y >= h) continue;
    if (region.at<unsigned char>(s) != 0) continue;
    const float zs = depth.at<float>(s);
    if (!view::valid_depth(zs)) continue;
    queue.clear();
    queue.push_back(s.y * w + s.x);
    region.at<unsigned char>(s) = 255;
    for (size_t head = 0; head < queue.size(); ++head) {
      const int x = queue[head] % w, y = queue[head] / w;
      const float zp = depth.at<float>(y, x);
      const int nx[4] = {x - 1, x + 1, x, x};
      const int ny[4] = {y, y, y - 1, y + 1};
      for (int k = 0; k < 4; ++k) {
        if (nx[k] < 0 || ny[k] < 0 || nx[k] >= w || ny[k] >= h) continue;
        unsigned char& m = region.at<unsigned char>(ny[k], nx[k]);
        if (m != 0) continue;
        const float zq = depth.at<float>(ny[k], nx[k]);
        if (!view::valid_depth(zq)) continue;
        if (std::abs(1.0 / zq - 1.0 / zp) > step) continue;
        if (band > 0 && std::abs(zq - zs) > band) continue;
        if (blocked(nx[k], ny[k])) continue;
        m = 255;
        queue.push_back(ny[k] * w + nx[k]);
      }
    }
  }
  return region;
}

}  // namespace

cv::Mat ddl_grow_regions(const cv::Mat& depth, const std::vector<cv::Point>& seeds, const DdlOptions& o,
                         const std::function<bool(int, int)>& blocked) {
  if (!blocked) return grow_regions(depth, seeds, o, [](int, int) { return false; });
  return grow_regions(depth, seeds, o, blocked);
}

void DdlStage::reset() { keyframe_maps_.clear(); }

std::shared_ptr<const ddl::KeyframeMaps> DdlStage::keyframe_maps(const std::shared_ptr<const FrameData>& frame,
                                                                 const std::vector<KeyFrameData>& keyframes,
                                                                 bool check, bool pyramid) {
  // Frames no longer among the keyframes are not asked for again.
  keyframe_maps_.erase(std::remove_if(keyframe_maps_.begin(), keyframe_maps_.end(),
                                      [&](const auto& e) {
                                        return std::none_of(keyframes.begin(), keyframes.end(),
                                                            [&](const KeyFrameData& k) { return k.frame == e.first; });
                                      }),
                       keyframe_maps_.end());
  auto it = std::find_if(keyframe_maps_.begin(), keyframe_maps_.end(), [&](const auto& e) { return e.first == frame; });
  if (it == keyframe_maps_.end())
    it = keyframe_maps_.insert(keyframe_maps_.end(), {frame, std::make_shared<ddl::KeyframeMaps>()});
  ddl::prepare_keyframe_maps(*frame, o_, check, pyramid, *it->second);
  return it->second;
}

void DdlStage::process(Context& ctx, StageReport& report) {
  report.values["tau_alpha_deg"] = o_.parallax_threshold_deg;
  report.values["tau_d_m"] = o_.depth_threshold_m;
  FrameData& cur = ctx.current;
  if (!ctx.calib || cur.grey.empty()) {
    report.values["skipped_bad_input"] = 1;
    return;
  }
  const map::Calibration& calib = *ctx.calib;
  const cv::Size size = cur.grey.size();
  if (cur.depth.empty()) {
    // Stereo without a disparity stage before this one, or RGB-D without depth.
    report.values["skipped_no_depth"] = 1;
    return;
  }
  if (!is_depth(cur.depth, size)) {
    report.values["skipped_bad_input"] = 1;
    return;
  }
  if (ctx.dynamic.empty()) ctx.dynamic = cv::Mat(size, CV_8UC1, cv::Scalar(0));
  if (!is_mask(ctx.dynamic, size)) {
    report.values["skipped_bad_input"] = 1;
    return;
  }

  // The semantic half of the combined mask does not depend on the geometry:
  // it is applied even when the geometric check cannot run.
  const bool semantic = o_.combine_semantic && is_mask(cur.candidates, size);
  const auto combine = [&](const cv::Mat& geometric) {
    double semantic_pixels = 0;
    if (semantic) {
      cv::bitwise_or(ctx.dynamic, cur.candidates, ctx.dynamic);
      semantic_pixels = cv::countNonZero(cur.candidates);
    }
    report.values["semantic_pixels"] = semantic_pixels;
    if (!geometric.empty()) cv::bitwise_or(ctx.dynamic, geometric, ctx.dynamic);
    cv::Mat both = geometric.empty() ? cv::Mat(size, CV_8UC1, cv::Scalar(0)) : geometric.clone();
    if (semantic) cv::bitwise_or(both, cur.candidates, both);
    report.values["combined_pixels"] = cv::countNonZero(both);
  };

  int source = 0;
  std::optional<Eigen::Isometry3d> T_cw = current_pose(ctx, source);
  report.values["pose_source"] = source;
  if (!T_cw) {
    report.values["skipped_no_pose"] = 1;
    combine(cv::Mat());
    return;
  }
  if (!ctx.keyframes || ctx.keyframes->empty()) {
    report.values["skipped_no_keyframes"] = 1;
    combine(cv::Mat());
    return;
  }

  // GetRefFrames: overlap = the share of a keyframe's points that land in
  // the current image in front of the camera.
  const view::Camera camera(calib);
  Eigen::Isometry3d T_wc = T_cw->inverse();
  std::vector<Reference> refs;
  for (size_t k = 0; k < ctx.keyframes->size(); ++k) {
    const KeyFrameData& kf = (*ctx.keyframes)[k];
    if (kf.frame && kf.frame->id == cur.id && cur.id >= 0) continue;
    Reference r;
    if (!ddl::back_project(kf, camera, o_.max_depth_m, r)) continue;
    r.order = static_cast<int>(k);
    r.T_kc = *kf.frame->T_cw * T_wc;
    r.dense = is_depth(kf.frame->depth, size);
    r.X_c.reserve(r.X_w.size());
    for (const Eigen::Vector3d& X : r.X_w) r.X_c.push_back(*T_cw * X);
    r.proj = camera.project(r.X_c);
    for (const cv::Point2f& p : r.proj)
      if (view::inside(p, size, o_.border_px)) ++r.in_view;
    r.overlap = static_cast<double>(r.in_view) / static_cast<double>(r.X_w.size());
    if (r.in_view > 0 && r.overlap >= o_.min_overlap) refs.push_back(std::move(r));
  }
  if (refs.empty()) {
    report.values["skipped_no_keyframes"] = 1;
    combine(cv::Mat());
    return;
  }
  std::stable_sort(refs.begin(), refs.end(), [](const Reference& a, const Reference& b) {
    return a.overlap != b.overlap ? a.overlap > b.overlap : a.order > b.order;
  });
  if (o_.reference_keyframes > 0 && static_cast<int>(refs.size()) > o_.reference_keyframes)
    refs.resize(static_cast<size_t>(o_.reference_keyframes));
  report.values["keyframes_used"] = static_cast<double>(refs.size());

  report.values["pose_refined"] = 0;
  auto t_part = Clock::now();
  if (o_.refine_pose) {
    for (Reference& r : refs) r.maps = keyframe_maps(r.kf->frame, *ctx.keyframes, false, true);
    std::optional<Eigen::Isometry3d> refined;
    try {
      refined = ddl::refine_pose(refs, cur.grey, calib, *T_cw, o_, report);
    } catch (const cv::Exception&) {
      report.values["refine_failed"] = 1;  // degenerate point sets: keep the given pose
    }
    if (refined) {
      T_cw = refined;
      T_wc = T_cw->inverse();
      for (Reference& r : refs) {
        r.T_kc = *r.kf->frame->T_cw * T_wc;
        for (size_t i = 0; i < r.X_w.size(); ++i) r.X_c[i] = *T_cw * r.X_w[i];
        r.proj = camera.project(r.X_c);
      }
      report.values["pose_refined"] = 1;
    }
  }

  if (o_.confirm_with_keyframes && (rays_calib_ != ctx.calib || rays_size_ != size)) {
    rays_ = camera.image_rays(size.width, size.height);
    rays_calib_ = ctx.calib;
    rays_size_ = size;
  }
  report.values["refine_ms"] = ms_since(t_part);
  // Built at the first dynamic point that needs it.
  std::optional<KeyframeEvidence> keyframe_evidence;
  double evidence_ms = 0;
  const auto evidence = [&](int x, int y) {
    if (!keyframe_evidence) {
      const auto t0 = Clock::now();
      for (Reference& r : refs)
        if (r.dense) r.maps = keyframe_maps(r.kf->frame, *ctx.keyframes, true, false);
      keyframe_evidence.emplace(cur.depth, cur.grey, rays_, refs, camera, o_);
      evidence_ms = ms_since(t0);
    }
    return (*keyframe_evidence)(x, y);
  };
  // Motion evidence of its own at (x, y) (KeyframeEvidence::moving_area), the
  // evidence built on first use.
  const auto moving_at = [&](int x, int y) {
    evidence(x, y);
    return keyframe_evidence->moving_area(x, y);
  };
  t_part = Clock::now();

  const double cos_tau_alpha = std::cos(o_.parallax_threshold_deg * M_PI / 180.0);
  int projected = 0, parallax_rejected = 0, no_depth = 0, vanished = 0, seen_static_rejected = 0,
      vanished_rejected = 0, sliding_points = 0;
  std::vector<cv::Point> seeds;
  for (const Reference& r : refs) {
    for (size_t i = 0; i < r.X_w.size(); ++i) {
      const cv::Point2f& p = r.proj[i];
      if (!view::inside(p, size, o_.border_px)) continue;
      const double z_proj = r.X_c[i].z();
      if (o_.max_depth_m > 0 && z_proj > o_.max_depth_m) continue;
      ++projected;
      const cv::Point q(cvRound(p.x), cvRound(p.y));
      // alpha = angle xXx': between the rays from X to both camera centres.
      const Eigen::Vector3d a = r.centre_w - r.X_w[i], b = T_wc.translation() - r.X_w[i];
      const double na = a.norm(), nb = b.norm();
      if (na > 0 && nb > 0 && a.dot(b) / (na * nb) < cos_tau_alpha) {
        ++parallax_rejected;
        if (o_.parallax_marks_dynamic) {
          report.dynamic_points.push_back(p);
          seeds.push_back(q);
        }
        continue;
      }
      const float z_meas =
          ddl::closest_depth(cur.depth, q, static_cast<float>(z_proj), o_.depth_search_radius_px);
      if (z_meas <= 0.f) {
        ++no_depth;
        continue;
      }
      const double dz = z_proj - z_meas;  // Algorithm 1 line 11: Delta d = d_p - d_x'
      const bool covered = dz > o_.depth_threshold_m;
      const bool gone = o_.vanished_points_dynamic && -dz > o_.depth_threshold_m;
      if ((covered || gone) && o_.confirm_with_keyframes) {
        const Seen seen = evidence(q.x, q.y);
        if (seen == Seen::kStatic) {
          ++seen_static_rejected;
          report.static_points.push_back(p);
          continue;
        }
        // X is gone, but what the current frame shows at x' may be
        // background it had hidden (always unseen by the keyframes, or
        // static): only a pixel with motion evidence of its own is dynamic.
        if (!covered && !keyframe_evidence->moving_area(q.x, q.y)) {
          ++vanished_rejected;
          continue;
        }
      }
      // A keyframe point that lands on a surface at its own depth which the
      // keyframes show moving (other texture at that depth: a surface
      // sliding along itself) passes both depth tests; with
      // seed_sliding_surfaces it is dynamic too.
      const bool sliding = !covered && !gone && o_.seed_sliding_surfaces && o_.confirm_with_keyframes &&
                           moving_at(q.x, q.y);
      if (sliding) ++sliding_points;
      if (covered || gone || sliding) {
        if (gone) ++vanished;
        report.dynamic_points.push_back(p);
        seeds.push_back(q);
      } else {
        report.static_points.push_back(p);
      }
    }
  }
  report.values["check_ms"] = ms_since(t_part);
  report.values["projected"] = projected;
  report.values["parallax_rejected"] = parallax_rejected;
  report.values["no_depth"] = no_depth;
  report.values["vanished"] = vanished;
  report.values["seen_static_rejected"] = seen_static_rejected;
  report.values["vanished_rejected"] = vanished_rejected;
  report.values["sliding"] = sliding_points;
  report.values["dynamic"] = static_cast<double>(report.dynamic_points.size());
  report.values["static"] = static_cast<double>(report.static_points.size());

  // Growing needs evidence of motion at every pixel it takes: seen static
  // stops it, and so does a place no keyframe saw (background that was
  // always hidden continues the floor's depth as much as the object does).
  t_part = Clock::now();
  cv::Mat region;
  if (o_.confirm_with_keyframes) {
    region = grow_regions(cur.depth, seeds, o_, [&](int x, int y) { return !moving_at(x, y); });
  } else {
    region = grow_regions(cur.depth, seeds, o_, [](int, int) { return false; });
  }
  report.values["grow_ms"] = ms_since(t_part);
  // Part of check_ms or grow_ms, whichever built it first.
  report.values["evidence_build_ms"] = evidence_ms;
  report.values["region_pixels"] = cv::countNonZero(region);
  if (o_.dilation_px > 0 && !seeds.empty()) {
    const int d = o_.dilation_px;
    cv::dilate(region, region, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * d + 1, 2 * d + 1)));
  }
  cv::Mat labels;
  report.regions = seeds.empty() ? 0 : cv::connectedComponents(region, labels, 8, CV_32S) - 1;
  combine(region);
}

}  // namespace dynaorb::dynamic
