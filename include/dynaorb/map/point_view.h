#pragma once
// How a map point would be seen from a camera pose (ORB-SLAM's frustum
// test): projected inside the image, within its scale-invariance distance
// range and under a viewing angle with cos >= view_cos_limit. Shared by the
// tracker's local-map search and the mapper's fusion.
#include <Eigen/Geometry>
#include <optional>

#include "dynaorb/map/calibration.h"
#include "dynaorb/map/map_point.h"

namespace dynaorb::map {

struct PointView {
  Eigen::Vector2d uv;     // projection (undistorted pixels)
  double u_right = 0;     // virtual right coordinate
  double view_cos = 0;
  int predicted_level = 0;
};

inline std::optional<PointView> view_point(const Calibration& c, const Eigen::Isometry3d& T_cw,
                                           const Eigen::Vector3d& center, const MapPoint& p,
                                           double view_cos_limit) {
  const Eigen::Vector3d pc = T_cw * p.position();
  if (pc.z() <= 0) return std::nullopt;
  PointView v;
  v.uv = c.project(pc);
  if (!c.in_image(v.uv)) return std::nullopt;
  const Eigen::Vector3d po = p.position() - center;
  const double dist = po.norm();
  if (dist < p.min_distance() || dist > p.max_distance()) return std::nullopt;
  v.view_cos = po.dot(p.normal()) / dist;
  if (v.view_cos < view_cos_limit) return std::nullopt;
  v.u_right = v.uv.x() - c.bf / pc.z();
  v.predicted_level = c.scale.predict_level(dist, p.max_distance());
  return v;
}

}  // namespace dynaorb::map
