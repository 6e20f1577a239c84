#include "dynaorb/dynamic/li_rigidity.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "view_geometry.h"

namespace dynaorb::dynamic {

namespace {

// Reprojection error (px) of X (previous camera) under T at `image`;
// infinite behind the camera.
double residual(const map::Calibration& calib, const Eigen::Isometry3d& T, const Eigen::Vector3d& X,
                const cv::Point2f& image) {
  const Eigen::Vector3d Y = T * X;
  if (!(Y.z() > 1e-6)) return std::numeric_limits<double>::infinity();
  return (calib.project(Y) - Eigen::Vector2d(image.x, image.y)).norm();
}

// How far (px) X's reprojection under T moves when its previous disparity is
// off by sigma_d either way: the part of the residual that SGBM's disparity
// error explains (it grows with the camera's translation and the point's
// distance from the epipole).
// `at`: X's reprojection under T (in front of the camera).
double depth_spread(const map::Calibration& calib, const Eigen::Isometry3d& T, const Eigen::Vector3d& X,
                    const Eigen::Vector2d& at, double sigma_d) {
  if (!(sigma_d > 0) || !(calib.bf > 0)) return 0;
  const double d = calib.bf / X.z();
  double spread = 0;
  for (double dd : {d - sigma_d, d + sigma_d}) {
    if (!(dd > 0)) continue;
    const Eigen::Vector3d Yd = T * (X * (d / dd));  // the same ray at depth bf / dd
    if (Yd.z() > 1e-6) spread = std::max(spread, (calib.project(Yd) - at).norm());
  }
  return spread;
}

}  // namespace

LiRigidityResult li_rigidity_check(LiEpipolarResult& e, const cv::Mat& prev_depth,
                                   const map::Calibration& calib,
                                   const std::optional<Eigen::Isometry3d>& prior, const LiOptions& o) {
  LiRigidityResult r;
  if (prev_depth.empty() || prev_depth.type() != CV_32FC1) {
    r.failure = "no_previous_depth";
    return r;
  }
  // The judged pairs with a previous depth, as 3-D points of the previous camera.
  std::vector<int> which;
  std::vector<Eigen::Vector3d> X;
  for (size_t i = 0; i < e.tracks.size(); ++i) {
    const LiTrack& t = e.tracks[i];
    if (t.distance < 0) continue;
    const float z = li_disparity_at(prev_depth, t.prev, o.disparity_patch_radius);
    if (!(z > 0.f) || !std::isfinite(z)) continue;
    which.push_back(static_cast<int>(i));
    X.push_back(calib.unproject(t.prev_u.x, t.prev_u.y, z));
  }
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  auto gather = [&](bool gate) {
    object.clear();
    image.clear();
    for (size_t k = 0; k < which.size(); ++k) {
      const LiTrack& t = e.tracks[which[k]];
      if (gate ? residual(calib, *prior, X[k], t.cur_u) > o.rigid_gate_px : t.dynamic) continue;
      object.emplace_back(static_cast<float>(X[k].x()), static_cast<float>(X[k].y()), static_cast<float>(X[k].z()));
      image.push_back(t.cur_u);
    }
  };
  // A prediction that explains too few pairs (the camera turned or sped up)
  // is no guide: then the pairs eq. 3 left static.
  r.used_prior = prior.has_value() && prior->matrix().allFinite();
  if (r.used_prior) gather(true);
  if (!r.used_prior || static_cast<int>(object.size()) < o.min_points) {
    r.used_prior = false;
    gather(false);
  }
  r.candidates = static_cast<int>(object.size());
  if (r.candidates < o.min_points) {
    r.failure = "too_few_points";
    return r;
  }
  try {
    std::vector<int> inl;
    if (!view::pnp_ransac_refined(object, image, calib, o.rigid_ransac_iterations,
                                  static_cast<float>(o.rigid_threshold_px), 0.99, o.min_points, inl, r.T_cur_prev) ||
        !r.T_cur_prev.matrix().allFinite()) {
      r.failure = "pnp_failed";
      return r;
    }
    r.inliers = static_cast<int>(inl.size());
  } catch (const cv::Exception&) {
    r.failure = "pnp_failed";
    return r;
  }
  r.has_motion = true;
  // The residual vectors of the pairs over their thresholds: candidates.
  std::vector<int> flagged;
  std::vector<Eigen::Vector2d> offset(which.size(), Eigen::Vector2d::Zero());
  for (size_t k = 0; k < which.size(); ++k) {
    LiTrack& t = e.tracks[which[k]];
    const Eigen::Vector3d Y = r.T_cur_prev * X[k];
    if (!(Y.z() > 1e-6)) continue;
    const Eigen::Vector2d at = calib.project(Y);
    offset[k] = Eigen::Vector2d(t.cur_u.x, t.cur_u.y) - at;
    t.rigid_residual = offset[k].norm();
    t.rigid_threshold = o.rigid_threshold_px + depth_spread(calib, r.T_cur_prev, X[k], at, o.rigid_disparity_sigma_px);
    ++r.judged;
    if (t.rigid_residual > t.rigid_threshold && !t.dynamic) flagged.push_back(static_cast<int>(k));
  }
  r.over_threshold = static_cast<int>(flagged.size());
  // A moving object moves its points alike: a candidate becomes dynamic when
  // at least rigid_min_agreeing others near it (eq. 4's relation: within T_s
  // and T_disp) are off in about the same direction and by about as much. A
  // tracking or disparity error is off on its own.
  const double cos_max = std::cos(o.rigid_max_angle_deg * CV_PI / 180.0);
  std::vector<int> added;
  for (int a : flagged) {
    const LiTrack& ta = e.tracks[which[a]];
    int agreeing = 0;
    for (int b : flagged) {
      if (b == a) continue;
      const LiTrack& tb = e.tracks[which[b]];
      if (std::abs(ta.disparity - tb.disparity) > o.t_disp) continue;
      const double ts = o.alpha_s + o.beta_s * 0.5 * (ta.disparity + tb.disparity);
      if (cv::norm(ta.cur - tb.cur) > ts) continue;
      const double na = offset[a].norm(), nb = offset[b].norm();
      if (!(na > 0) || !(nb > 0)) continue;
      if (offset[a].dot(offset[b]) < cos_max * na * nb) continue;
      if (nb > o.rigid_max_ratio * na || na > o.rigid_max_ratio * nb) continue;
      ++agreeing;
    }
    if (agreeing >= o.rigid_min_agreeing) added.push_back(a);
  }
  for (int a : added) {
    e.tracks[which[a]].dynamic = true;
    ++r.added;
    ++e.dynamic;
  }
  return r;
}

}  // namespace dynaorb::dynamic
