#pragma once
// What every frame of one camera shares: the pinhole model the keypoints are
// undistorted into, the stereo baseline, the close/far depth threshold and
// the ORB scale pyramid. Immutable once built; frames hold it by shared_ptr.
#include <Eigen/Core>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/core/sensor.h"
#include "dynaorb/io/settings.h"

namespace dynaorb::map {

struct ScalePyramid {
  int n_levels = 8;
  double scale_factor = 1.2;
  double log_scale_factor = 0.0;
  std::vector<float> scale, inv_scale, sigma2, inv_sigma2;

  static ScalePyramid make(int n_levels, double scale_factor);
  // The pyramid level a point at `distance` is expected at, given the
  // largest distance it is seen at scale invariantly (ORB-SLAM's PredictScale).
  int predict_level(double distance, double max_distance) const;
};

struct Calibration {
  Sensor sensor = Sensor::kStereo;
  double fx = 0, fy = 0, cx = 0, cy = 0, inv_fx = 0, inv_fy = 0;
  cv::Mat K;                 // 3x3 CV_64F
  Eigen::Matrix3d K_eigen() const {
    Eigen::Matrix3d k;
    k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
    return k;
  }
  cv::Mat dist;              // distortion of the tracked image (empty: none)
  double bf = 0;             // baseline * fx (0 for monocular)
  double baseline = 0;
  double th_depth = 0;       // metres: points closer than this are "close" (ORB-SLAM2 ThDepth * b)
  int width = 0, height = 0;
  double min_x = 0, max_x = 0, min_y = 0, max_y = 0;  // undistorted image bounds
  ScalePyramid scale;

  // The tracked image is the rectified left image for stereo with LEFT./RIGHT.
  // blocks, so its intrinsics are those of P_l and there is no distortion.
  static std::shared_ptr<const Calibration> make(const Settings& settings, Sensor sensor,
                                                 int width, int height);

  Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const {
    const double iz = 1.0 / p_cam.z();
    return {fx * p_cam.x() * iz + cx, fy * p_cam.y() * iz + cy};
  }
  Eigen::Vector3d unproject(double u, double v, double z) const {
    return {(u - cx) * z * inv_fx, (v - cy) * z * inv_fy, z};
  }
  bool in_image(const Eigen::Vector2d& uv) const {
    return uv.x() >= min_x && uv.x() < max_x && uv.y() >= min_y && uv.y() < max_y;
  }
};

}  // namespace dynaorb::map
