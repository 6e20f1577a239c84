#include "dynaorb/map/calibration.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>

namespace dynaorb::map {

ScalePyramid ScalePyramid::make(int n_levels, double scale_factor) {
  ScalePyramid p;
  p.n_levels = n_levels;
  p.scale_factor = scale_factor;
  p.log_scale_factor = std::log(scale_factor);
  double s = 1.0;
  for (int i = 0; i < n_levels; ++i, s *= scale_factor) {
    p.scale.push_back(static_cast<float>(s));
    p.inv_scale.push_back(static_cast<float>(1.0 / s));
    p.sigma2.push_back(static_cast<float>(s * s));
    p.inv_sigma2.push_back(static_cast<float>(1.0 / (s * s)));
  }
  return p;
}

int ScalePyramid::predict_level(double distance, double max_distance) const {
  const double ratio = max_distance / distance;
  const int level = static_cast<int>(std::ceil(std::log(ratio) / log_scale_factor));
  return std::clamp(level, 0, n_levels - 1);
}

std::shared_ptr<const Calibration> Calibration::make(const Settings& settings, Sensor sensor,
                                                     int width, int height) {
  auto c = std::make_shared<Calibration>();
  const CameraSettings& cam = settings.camera;
  c->sensor = sensor;
  c->width = width;
  c->height = height;
  c->fx = cam.fx;
  c->fy = cam.fy;
  c->cx = cam.cx;
  c->cy = cam.cy;
  const bool rectified = sensor == Sensor::kStereo && settings.rectification.enabled();
  if (rectified) {  // the tracked image is the rectified left one: intrinsics of P_l
    const cv::Mat& P = settings.rectification.P_l;
    c->fx = P.at<double>(0, 0);
    c->fy = P.at<double>(1, 1);
    c->cx = P.at<double>(0, 2);
    c->cy = P.at<double>(1, 2);
  } else if (cam.has_distortion()) {
    cam.dist.convertTo(c->dist, CV_64F);
  }
  c->inv_fx = 1.0 / c->fx;
  c->inv_fy = 1.0 / c->fy;
  c->K = (cv::Mat_<double>(3, 3) << c->fx, 0, c->cx, 0, c->fy, c->cy, 0, 0, 1);
  if (sensor != Sensor::kMono && cam.bf) {
    c->bf = *cam.bf;
    c->baseline = c->bf / c->fx;
    c->th_depth = c->baseline * cam.th_depth.value_or(40.0);
  }
  // Bounds of the undistorted image: the undistorted corners (ORB-SLAM2).
  c->min_x = 0;
  c->max_x = width;
  c->min_y = 0;
  c->max_y = height;
  if (!c->dist.empty()) {
    std::vector<cv::Point2f> corners{{0, 0}, {float(width), 0}, {0, float(height)},
                                     {float(width), float(height)}};
    std::vector<cv::Point2f> un;
    cv::undistortPoints(corners, un, c->K, c->dist, cv::noArray(), c->K);
    c->min_x = std::min(un[0].x, un[2].x);
    c->max_x = std::max(un[1].x, un[3].x);
    c->min_y = std::min(un[0].y, un[1].y);
    c->max_y = std::max(un[2].y, un[3].y);
  }
  c->scale = ScalePyramid::make(settings.extractor.n_levels, settings.extractor.scale_factor);
  return c;
}

}  // namespace dynaorb::map
