#include "dynaorb/map/frame.h"

#include "dynaorb/map/point_view.h"

namespace dynaorb::map {

int Frame::matched_points() const {
  int n = 0;
  for (int i = 0; i < size(); ++i)
    if (points[i] && !outlier[i]) ++n;
  return n;
}

bool Frame::in_frustum(MapPoint& p, double view_cos_limit) const {
  const std::optional<PointView> v = view_point(calib(), T_cw, center(), p, view_cos_limit);
  if (!v) return false;
  p.track.in_view_frame = id;
  p.track.proj_x = v->uv.x();
  p.track.proj_y = v->uv.y();
  p.track.proj_xr = v->u_right;
  p.track.view_cos = v->view_cos;
  p.track.predicted_level = v->predicted_level;
  return true;
}

}  // namespace dynaorb::map
