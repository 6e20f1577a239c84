// The DDL stage's pose refinement against the reference keyframes (see
// ddl_keyframes.h).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>  // after Eigen (OpenCV requires it)
#include <opencv2/video/tracking.hpp>

#include "ddl_keyframes.h"

namespace dynaorb::dynamic::ddl {

std::optional<Eigen::Isometry3d> refine_pose(const std::vector<Reference>& refs, const cv::Mat& grey,
                                             const map::Calibration& calib, const Eigen::Isometry3d& T_cw,
                                             const DdlOptions& o, StageReport& report) {
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  const cv::Size size = grey.size();
  const cv::Size window = kRefineWindow;
  constexpr int kLevels = kRefineLevels;
  // The current image's, built once for all keyframes; without derivatives:
  // calcOpticalFlowPyrLK reads only the first image's.
  std::vector<cv::Mat> pyramid;
  cv::buildOpticalFlowPyramid(grey, pyramid, window, kLevels, false);
  for (const Reference& r : refs) {
    const cv::Mat& kf_grey = r.kf->frame->grey;
    if (kf_grey.empty() || kf_grey.type() != CV_8UC1 || kf_grey.size() != size) continue;
    std::vector<cv::Point2f> from, to;
    std::vector<size_t> idx;
    // A few hundred points fix a pose; more only cost time.
    const size_t stride = std::max<size_t>(1, r.px.size() / std::max(1, o.refine_points_per_keyframe));
    for (size_t i = 0; i < r.px.size(); i += stride) {
      if (!view::inside(r.proj[i], size, o.border_px)) continue;
      from.push_back(r.px[i]);
      to.push_back(r.proj[i]);
      idx.push_back(i);
    }
    if (from.empty()) continue;
    std::vector<unsigned char> ok;
    std::vector<float> err;
    // The keyframe's pyramid is made once while it is a reference (same result as from its image).
    const bool kf_pyramid = r.maps && !r.maps->pyramid.empty();
    cv::calcOpticalFlowPyrLK(kf_pyramid ? cv::_InputArray(r.maps->pyramid) : cv::_InputArray(kf_grey), pyramid, from, to, ok, err, window, kLevels,
                             cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01),
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    for (size_t j = 0; j < from.size(); ++j) {
      if (!ok[j] || !view::inside(to[j], size)) continue;
      if (cv::norm(to[j] - r.proj[idx[j]]) > o.refine_max_shift_px) continue;
      const Eigen::Vector3d& X = r.X_w[idx[j]];
      object.emplace_back(static_cast<float>(X.x()), static_cast<float>(X.y()), static_cast<float>(X.z()));
      image.push_back(to[j]);
    }
  }
  report.values["refine_points"] = static_cast<double>(object.size());
  if (static_cast<int>(object.size()) < o.refine_min_inliers) return std::nullopt;
  cv::Mat R;
  cv::eigen2cv(Eigen::Matrix3d(T_cw.linear()), R);
  cv::Mat rvec, tvec;
  cv::Rodrigues(R, rvec);
  cv::eigen2cv(Eigen::Vector3d(T_cw.translation()), tvec);
  const cv::Mat dist = calib.dist.empty() ? cv::Mat() : calib.dist;
  std::vector<int> inliers;
  const bool solved = cv::solvePnPRansac(object, image, calib.K, dist, rvec, tvec, true, 200,
                                         static_cast<float>(o.refine_reprojection_px), 0.99, inliers,
                                         cv::SOLVEPNP_ITERATIVE);
  if (!solved) return std::nullopt;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d Re;
  Eigen::Vector3d te;
  cv::cv2eigen(R, Re);
  cv::cv2eigen(tvec, te);
  Eigen::Isometry3d refined = Eigen::Isometry3d::Identity();
  refined.linear() = Re;
  refined.translation() = te;
  if (!refined.matrix().allFinite()) return std::nullopt;
  // The refined pose must explain more of the points than the given one
  // (RANSAC's final fit can drift, and on a frame full of movers a
  // consensus of moving points can win); points behind the camera count
  // against it.
  const view::Camera camera(calib);
  const auto explained = [&](const Eigen::Isometry3d& T, double threshold) {
    int n = 0;
    for (size_t i = 0; i < object.size(); ++i) {
      const cv::Point2f q = camera.project(T * Eigen::Vector3d(object[i].x, object[i].y, object[i].z));
      if (std::isfinite(q.x) && cv::norm(q - image[i]) <= threshold) ++n;
    }
    return n;
  };
  const int n_refined = explained(refined, o.refine_reprojection_px);
  report.values["refine_inliers"] = n_refined;
  if (n_refined < o.refine_min_inliers) return std::nullopt;
  // Compared at half the threshold, and by a clear margin (5 %): a pose
  // that is right puts the static points within a fraction of a pixel, a
  // compromise with moving ones does not, and a given pose that is already
  // right is kept.
  const int n_close = explained(refined, 0.5 * o.refine_reprojection_px);
  const int n_given = explained(T_cw, 0.5 * o.refine_reprojection_px);
  report.values["refine_close"] = n_close;
  report.values["refine_close_given_pose"] = n_given;
  if (n_close <= n_given + std::max(5, n_given / 20)) return std::nullopt;
  const Eigen::Isometry3d D = refined * T_cw.inverse();
  report.values["pose_correction_m"] = D.translation().norm();
  report.values["pose_correction_deg"] = Eigen::AngleAxisd(D.linear()).angle() * 180.0 / M_PI;
  return refined;
}

}  // namespace dynaorb::dynamic::ddl
