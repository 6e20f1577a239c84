#pragma once
// Pixels of the tracked image <-> camera rays, for the stages that move
// points between views (DDL-SLAM's multi-view check, background inpainting).
// The tracked image may be distorted (TUM RGB-D): rays go through
// calib.dist both ways, so depth images are read at the pixels the camera
// really recorded.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic::view {

// A usable metric depth value (RGB-D holes are 0, stereo disparity holes may be NaN).
inline bool valid_depth(float z) { return std::isfinite(z) && z > 0.f; }

// The pose of OpenCV's (rvec, tvec), e.g. from solvePnP.
inline Eigen::Isometry3d isometry(const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = R(r, c);
  T.translation() = Eigen::Vector3d(tvec[0], tvec[1], tvec[2]);
  return T;
}

// The pinhole matrix of the tracked image.
inline cv::Matx33d camera_matrix(const map::Calibration& c) {
  return cv::Matx33d(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}

// T_cur_prev from points of the previous camera (`object`) seen at `image`
// (undistorted pixels of the current one): solvePnPRansac with EPnP for the
// samples and for the final fit on all inliers (within `threshold` px), then
// Levenberg-Marquardt from that fit on them. (With the default flag OpenCV
// refits the inliers by its iterative solver started from a DLT or
// homography guess, not from the RANSAC model; on rendered rooms that
// converged to poses metres or kilometres off, with every point behind the
// camera, while still reporting all the inliers.) False, T and `inliers` as
// RANSAC left them, when RANSAC fails or keeps fewer than min_inliers. May
// throw cv::Exception.
inline bool pnp_ransac_refined(const std::vector<cv::Point3f>& object, const std::vector<cv::Point2f>& image,
                               const map::Calibration& calib, int iterations, float threshold, double confidence,
                               int min_inliers, std::vector<int>& inliers, Eigen::Isometry3d& T) {
  const cv::Matx33d K = camera_matrix(calib);
  cv::Vec3d rvec, tvec;
  const bool ok = cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, iterations, threshold,
                                     confidence, inliers, cv::SOLVEPNP_EPNP);
  if (!ok || static_cast<int>(inliers.size()) < min_inliers) return false;
  std::vector<cv::Point3f> obj_in;
  std::vector<cv::Point2f> img_in;
  for (int k : inliers) {
    obj_in.push_back(object[k]);
    img_in.push_back(image[k]);
  }
  cv::solvePnPRefineLM(obj_in, img_in, K, cv::noArray(), rvec, tvec);
  T = isometry(rvec, tvec);
  return true;
}

// Whether a CV_8UC1 mask is set at p's nearest pixel: false off the mask,
// for a non-finite p and for an empty mask or another type.
inline bool mask_at(const cv::Mat& mask, const cv::Point2f& p) {
  if (mask.empty() || mask.type() != CV_8UC1 || !std::isfinite(p.x) || !std::isfinite(p.y)) return false;
  const int x = cvRound(p.x), y = cvRound(p.y);
  if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows) return false;
  return mask.at<unsigned char>(y, x) != 0;
}

inline bool inside(const cv::Point2f& p, const cv::Size& size, int border = 0) {
  return std::isfinite(p.x) && std::isfinite(p.y) && p.x >= border && p.y >= border &&
         p.x <= size.width - 1 - border && p.y <= size.height - 1 - border;
}

class Camera {
 public:
  // margin: a distortion polynomial folds back far outside the field of
  // view, so points whose undistorted pixel lies more than `margin` px
  // outside the image do not project (NaN).
  explicit Camera(const map::Calibration& c, double margin = 50.0) : c_(c) {
    if (!c.dist.empty()) {
      cv::Mat d;
      c.dist.reshape(1, 1).convertTo(d, CV_64F);
      n_ = static_cast<int>(d.total());
      for (int i = 0; i < std::min(n_, 5); ++i) k_[i] = d.at<double>(0, i);
    }
    lo_x_ = std::min(0.0, c.min_x) - margin;
    hi_x_ = std::max<double>(c.width, c.max_x) + margin;
    lo_y_ = std::min(0.0, c.min_y) - margin;
    hi_y_ = std::max<double>(c.height, c.max_y) + margin;
  }

  // Normalised rays (x/z, y/z) of raw image pixels.
  std::vector<cv::Point2f> rays(const std::vector<cv::Point2f>& px) const {
    std::vector<cv::Point2f> out(px.size());
    if (px.empty()) return out;
    if (n_ == 0) {
      for (size_t i = 0; i < px.size(); ++i)
        out[i] = {static_cast<float>((px[i].x - c_.cx) / c_.fx), static_cast<float>((px[i].y - c_.cy) / c_.fy)};
    } else {
      const cv::Matx33d K(c_.fx, 0, c_.cx, 0, c_.fy, c_.cy, 0, 0, 1);
      cv::undistortPoints(px, out, K, c_.dist);
    }
    return out;
  }

  // The rays of every pixel of a width x height image, row-major.
  std::vector<cv::Point2f> image_rays(int width, int height) const {
    std::vector<cv::Point2f> px;
    px.reserve(static_cast<size_t>(width) * height);
    for (int v = 0; v < height; ++v)
      for (int u = 0; u < width; ++u) px.emplace_back(static_cast<float>(u), static_cast<float>(v));
    return rays(px);
  }

  // The raw pixel of a camera point; NaN behind the camera or out of reach.
  cv::Point2f project(const Eigen::Vector3d& p) const {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    if (!(p.z() > 1e-9)) return {nan, nan};
    const double x = p.x() / p.z(), y = p.y() / p.z();
    if (n_ == 0) return {static_cast<float>(c_.fx * x + c_.cx), static_cast<float>(c_.fy * y + c_.cy)};
    const double u = c_.fx * x + c_.cx, v = c_.fy * y + c_.cy;
    if (u < lo_x_ || u > hi_x_ || v < lo_y_ || v > hi_y_) return {nan, nan};
    if (n_ > 5) {  // rational / thin-prism models: OpenCV's own projection
      std::vector<cv::Point3f> in{cv::Point3f(static_cast<float>(x), static_cast<float>(y), 1.f)};
      std::vector<cv::Point2f> out;
      const cv::Matx33d K(c_.fx, 0, c_.cx, 0, c_.fy, c_.cy, 0, 0, 1);
      cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, c_.dist, out);
      return out[0];
    }
    // Brown-Conrady, k1 k2 p1 p2 [k3], as cv::projectPoints.
    const double r2 = x * x + y * y;
    const double radial = 1 + r2 * (k_[0] + r2 * (k_[1] + r2 * k_[4]));
    const double xd = x * radial + 2 * k_[2] * x * y + k_[3] * (r2 + 2 * x * x);
    const double yd = y * radial + k_[2] * (r2 + 2 * y * y) + 2 * k_[3] * x * y;
    return {static_cast<float>(c_.fx * xd + c_.cx), static_cast<float>(c_.fy * yd + c_.cy)};
  }

  std::vector<cv::Point2f> project(const std::vector<Eigen::Vector3d>& p) const {
    std::vector<cv::Point2f> out(p.size());
    for (size_t i = 0; i < p.size(); ++i) out[i] = project(p[i]);
    return out;
  }

 private:
  const map::Calibration& c_;
  int n_ = 0;
  double k_[5] = {0, 0, 0, 0, 0};
  double lo_x_, hi_x_, lo_y_, hi_y_;
};

}  // namespace dynaorb::dynamic::view
