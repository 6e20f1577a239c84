#include "dynaorb/map/frame.h"

namespace dynaorb::map {

int Frame::matched_points() const {
  int n = 0;
  for (int i = 0; i < size(); ++i)
    if (points[i] && !outlier[i]) ++n;
  return n;
}

bool Frame::in_frustum(MapPoint& p, double view_cos_limit) const {
  const Eigen::Vector3d pc = T_cw * p.position();
  if (pc.z() <= 0) return false;
  const Calibration& c = calib();
  const Eigen::Vector2d uv = c.project(pc);
  if (!c.in_image(uv)) return false;
  const Eigen::Vector3d po = p.position() - center();
  const double dist = po.norm();
  if (dist < p.min_distance() || dist > p.max_distance()) return false;
  const double view_cos = po.dot(p.normal()) / dist;
  if (view_cos < view_cos_limit) return false;
  p.track.in_view_frame = id;
  p.track.proj_x = uv.x();
  p.track.proj_y = uv.y();
  p.track.proj_xr = uv.x() - c.bf / pc.z();
  p.track.view_cos = view_cos;
  p.track.predicted_level = c.scale.predict_level(dist, p.max_distance());
  return true;
}

}  // namespace dynaorb::map
