#pragma once
// A small ray-cast renderer for the dynamic-stage tests: textured rectangles
// (walls, floor, boxes, a parked car, movers) seen by a pinhole camera with
// optional lens distortion. It gives the grey image, the depth (metres), the
// label of each pixel and which rectangle it shows, so tests know the truth.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "../stats_util.h"
#include "dynaorb/core/sensor.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::test::synth {

// A textured rectangle: in its own frame the plane z = 0, x in [-half_w,
// half_w], y in [-half_h, half_h]; the texture covers it at px_per_m.
struct TexturedQuad {
  Eigen::Isometry3d T_wq = Eigen::Isometry3d::Identity();
  double half_w = 1, half_h = 1;
  cv::Mat texture;  // CV_8UC1
  double px_per_m = 100;
  unsigned char label = 0;  // semantic class id (0 = background)
};

struct RenderedView {
  cv::Mat grey;    // CV_8UC1
  cv::Mat depth;   // CV_32FC1 metres, 0 = nothing
  cv::Mat labels;  // CV_8UC1
  cv::Mat object;  // CV_32SC1 index of the quad seen, -1 = none
};

// Random rectangles and discs of random grey on a random background, slightly
// blurred so LK and Harris see corners but no aliasing noise.
inline cv::Mat random_texture(int width, int height, std::uint64_t seed, int shapes = 0) {
  cv::RNG rng(seed);
  cv::Mat t(height, width, CV_8UC1, cv::Scalar(rng.uniform(60, 200)));
  if (shapes <= 0) shapes = width * height / 80;
  for (int i = 0; i < shapes; ++i) {
    const cv::Scalar grey(rng.uniform(0, 256));
    const int x = rng.uniform(0, width), y = rng.uniform(0, height);
    if (rng.uniform(0, 3) == 0) {
      cv::circle(t, {x, y}, rng.uniform(2, 8), grey, cv::FILLED);
    } else {
      cv::rectangle(t, cv::Rect(x, y, rng.uniform(3, 16), rng.uniform(3, 16)), grey, cv::FILLED);
    }
  }
  cv::GaussianBlur(t, t, cv::Size(5, 5), 1.0);
  return t;
}

inline TexturedQuad make_quad(const Eigen::Vector3d& centre, const Eigen::Matrix3d& R_wq, double half_w,
                              double half_h, double px_per_m, std::uint64_t seed, unsigned char label = 0) {
  TexturedQuad q;
  q.T_wq = Eigen::Isometry3d::Identity();
  q.T_wq.linear() = R_wq;
  q.T_wq.translation() = centre;
  q.half_w = half_w;
  q.half_h = half_h;
  q.px_per_m = px_per_m;
  q.label = label;
  q.texture = random_texture(static_cast<int>(std::ceil(2 * half_w * px_per_m)) + 2,
                             static_cast<int>(std::ceil(2 * half_h * px_per_m)) + 2, seed);
  return q;
}

// A fronto-parallel rectangle (normal along the camera axis at identity pose).
inline TexturedQuad facing_quad(const Eigen::Vector3d& centre, double half_w, double half_h,
                                double px_per_m, std::uint64_t seed, unsigned char label = 0) {
  return make_quad(centre, Eigen::Matrix3d::Identity(), half_w, half_h, px_per_m, seed, label);
}

// A horizontal floor at camera height y (y points down).
inline TexturedQuad floor_quad(double y, double z_centre, double half_w, double half_d, double px_per_m,
                               std::uint64_t seed) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return make_quad({0, y, z_centre}, R, half_w, half_d, px_per_m, seed);
}

inline std::shared_ptr<map::Calibration> make_calibration(Sensor sensor, int width = 640, int height = 480,
                                                          double f = 500, double baseline = 0.1,
                                                          cv::Mat dist = cv::Mat()) {
  auto c = std::make_shared<map::Calibration>();
  c->sensor = sensor;
  c->fx = c->fy = f;
  c->cx = (width - 1) / 2.0;
  c->cy = (height - 1) / 2.0;
  c->inv_fx = c->inv_fy = 1.0 / f;
  c->K = (cv::Mat_<double>(3, 3) << f, 0, c->cx, 0, f, c->cy, 0, 0, 1);
  c->dist = dist;
  c->baseline = sensor == Sensor::kMono ? 0.0 : baseline;
  c->bf = c->baseline * f;
  c->th_depth = 40 * c->baseline;
  c->width = width;
  c->height = height;
  c->min_x = 0;
  c->max_x = width;
  c->min_y = 0;
  c->max_y = height;
  c->scale = map::ScalePyramid::make(8, 1.2);
  return c;
}

// Ray-casts every pixel (distorted pixels are undistorted into rays first).
inline RenderedView render(const std::vector<TexturedQuad>& quads, const Eigen::Isometry3d& T_cw,
                           const map::Calibration& calib) {
  const int w = calib.width, h = calib.height;
  std::vector<cv::Point2f> px;
  px.reserve(static_cast<size_t>(w) * h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) px.emplace_back(static_cast<float>(u), static_cast<float>(v));
  std::vector<cv::Point2f> ray(px.size());
  if (calib.dist.empty()) {
    for (size_t i = 0; i < px.size(); ++i)
      ray[i] = {static_cast<float>((px[i].x - calib.cx) / calib.fx),
                static_cast<float>((px[i].y - calib.cy) / calib.fy)};
  } else {
    const cv::Matx33d K(calib.fx, 0, calib.cx, 0, calib.fy, calib.cy, 0, 0, 1);
    cv::undistortPoints(px, ray, K, calib.dist);
  }

  RenderedView out;
  out.grey = cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
  out.depth = cv::Mat(h, w, CV_32FC1, cv::Scalar(0));
  out.labels = cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
  out.object = cv::Mat(h, w, CV_32SC1, cv::Scalar(-1));
  const Eigen::Isometry3d T_wc = T_cw.inverse();
  for (size_t qi = 0; qi < quads.size(); ++qi) {
    const TexturedQuad& q = quads[qi];
    const Eigen::Isometry3d T_qc = q.T_wq.inverse() * T_wc;
    const Eigen::Vector3d o = T_qc.translation();
    const Eigen::Matrix3d R = T_qc.linear();
    cv::Mat map_x(h, w, CV_32FC1, cv::Scalar(-1)), map_y(h, w, CV_32FC1, cv::Scalar(-1));
    cv::Mat z_q(h, w, CV_32FC1, cv::Scalar(0));
    for (int v = 0; v < h; ++v)
      for (int u = 0; u < w; ++u) {
        const cv::Point2f& r = ray[static_cast<size_t>(v) * w + u];
        const Eigen::Vector3d d = R * Eigen::Vector3d(r.x, r.y, 1.0);
        if (std::abs(d.z()) < 1e-12) continue;
        const double t = -o.z() / d.z();  // = depth, the ray has unit z in the camera
        if (t <= 1e-3) continue;
        const Eigen::Vector3d p = o + t * d;
        if (std::abs(p.x()) > q.half_w || std::abs(p.y()) > q.half_h) continue;
        const float zb = out.depth.at<float>(v, u);
        if (zb > 0 && zb <= t) continue;
        map_x.at<float>(v, u) = static_cast<float>((p.x() + q.half_w) * q.px_per_m);
        map_y.at<float>(v, u) = static_cast<float>((p.y() + q.half_h) * q.px_per_m);
        z_q.at<float>(v, u) = static_cast<float>(t);
      }
    cv::Mat img;
    cv::remap(q.texture, img, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    const cv::Mat hit = z_q > 0;
    img.copyTo(out.grey, hit);
    z_q.copyTo(out.depth, hit);
    out.labels.setTo(q.label, hit);
    out.object.setTo(static_cast<int>(qi), hit);
  }
  return out;
}

// A room seen from the origin looking along +z: back wall, floor and two
// boxes at different depths, so the scene is far from planar.
inline std::vector<TexturedQuad> room(std::uint64_t seed = 1) {
  std::vector<TexturedQuad> s;
  s.push_back(facing_quad({0, 0, 6}, 5, 4, 60, seed));
  s.push_back(floor_quad(1.2, 3.5, 5, 3.5, 80, seed + 1));
  s.push_back(facing_quad({-1.25, 0.35, 3.0}, 0.75, 0.85, 120, seed + 2));
  s.push_back(facing_quad({1.0, 0.3, 2.2}, 0.5, 0.6, 160, seed + 3));
  return s;
}

inline Eigen::Isometry3d make_motion(double rx_deg, double ry_deg, double rz_deg, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(rz_deg * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(ry_deg * M_PI / 180, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(rx_deg * M_PI / 180, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}

inline double rotation_error_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180 / M_PI;
}

// Distance of q to the epipolar line F p (undistorted pixels).
inline double epipolar_distance(const cv::Matx33d& F, const cv::Point2f& p, const cv::Point2f& q) {
  const cv::Vec3d l = F * cv::Vec3d(p.x, p.y, 1.0);
  const double n = std::hypot(l[0], l[1]);
  return n > 0 ? std::abs(q.x * l[0] + q.y * l[1] + l[2]) / n : std::numeric_limits<double>::infinity();
}

// The order statistics, for the tests that use this namespace.
using dynaorb::test::median;
using dynaorb::test::percentile;

}  // namespace dynaorb::test::synth
