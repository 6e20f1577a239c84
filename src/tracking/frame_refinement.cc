#include "dynaorb/tracking/frame_refinement.h"

#include <algorithm>

namespace dynaorb::tracking {

optimize::Observation keypoint_observation(const map::Frame& f, int i) {
  const cv::KeyPoint& k = f.f().keys_un[i];
  optimize::Observation o;
  o.uv = {k.pt.x, k.pt.y};
  o.u_right = f.f().u_right[i];
  o.inv_sigma2 = f.calib().scale.inv_sigma2[k.octave];
  return o;
}

std::vector<FrameObservation> frame_observations(const map::Frame& f) {
  std::vector<FrameObservation> out;
  for (int i = 0; i < f.size(); ++i)
    if (f.points[i] && !f.outlier[i]) out.push_back({f.points[i], keypoint_observation(f, i)});
  return out;
}

std::vector<optimize::PoseObservation> current_observations(const std::vector<FrameObservation>& obs) {
  std::vector<optimize::PoseObservation> out;
  out.reserve(obs.size());
  for (const FrameObservation& o : obs) {
    // A point fused into another since goes on as that one (ORB-SLAM2 follows
    // one replacement for the last frame; here the frame may be older).
    const map::MapPoint* p = o.point.get();
    for (int hops = 0; p && p->erased() && p->replaced_by() && hops < 8; ++hops) p = p->replaced_by().get();
    if (p && !p->erased()) out.push_back({p->position(), o.obs});
  }
  return out;
}

std::optional<Eigen::Isometry3d> refine_pose(const optimize::Intrinsics& K, const Eigen::Isometry3d& T_cw_init,
                                             const std::vector<optimize::PoseObservation>& obs, int min_points,
                                             int rounds, double final_huber) {
  if (static_cast<int>(obs.size()) < std::max(min_points, 1)) return std::nullopt;
  optimize::PoseOptimizerOptions o;
  o.rounds = std::max(rounds, 1);
  o.final_huber = final_huber;
  const optimize::PoseOptimizerResult r = optimize::optimize_pose(K, T_cw_init, obs, o);
  if (r.inliers < min_points) return std::nullopt;
  return r.T_cw;
}

}  // namespace dynaorb::tracking
