// Local mapping: bundle adjustment of the covisible window (ORB-SLAM Sec.
// VI-E). The problem is copied out under the map lock, solved unlocked (so
// tracking goes on) and written back under the lock.
#include <algorithm>
#include <unordered_map>

#include "dynaorb/mapping/local_mapper.h"
#include "dynaorb/optimize/bundle_adjuster.h"

namespace dynaorb::mapping {

using map::KeyFrame;
using map::MapPoint;

void LocalMapper::local_bundle_adjustment(KeyFrame& kf) {
  optimize::BaProblem problem;
  std::vector<std::shared_ptr<KeyFrame>> kfs;           // index -> keyframe
  std::vector<std::shared_ptr<MapPoint>> points;        // index -> point
  std::vector<std::pair<KeyFrame*, int>> obs_slots;     // index -> (keyframe, keypoint)
  size_t n_local = 0;                                   // kfs[0, n_local): optimised; the rest fixed
  {
    std::lock_guard<std::mutex> lk(map_.mutex());
    if (kf.erased() || map_.keyframe_count() <= 2) return;
    std::unordered_map<const KeyFrame*, int> kf_index;
    auto add_kf = [&](KeyFrame* k, bool fixed) {
      kf_index[k] = static_cast<int>(kfs.size());
      kfs.push_back(map_.keyframe(k->id));
      problem.keyframes.push_back({k->T_cw(), fixed || k->id == 0});
    };
    add_kf(&kf, false);
    for (KeyFrame* k : kf.covisibles())
      if (!k->erased()) add_kf(k, false);
    n_local = kfs.size();
    std::unordered_map<const MapPoint*, int> point_index;
    for (size_t i = 0; i < n_local; ++i) {
      for (const auto& p : kfs[i]->points()) {
        if (!p || p->erased() || point_index.count(p.get())) continue;
        point_index[p.get()] = static_cast<int>(points.size());
        points.push_back(p);
        problem.points.push_back(p->position());
      }
    }
    // Keyframes that see local points but are outside the window hold the gauge.
    for (const auto& p : points)
      for (const MapPoint::Observation& o : p->observations())
        if (!kf_index.count(o.keyframe) && !o.keyframe->erased()) add_kf(o.keyframe, true);
    const map::Calibration& c = kf.calib();
    problem.K = {c.fx, c.fy, c.cx, c.cy, c.bf};
    for (size_t pi = 0; pi < points.size(); ++pi) {
      for (const MapPoint::Observation& o : points[pi]->observations()) {
        auto it = kf_index.find(o.keyframe);
        if (it == kf_index.end()) continue;
        const cv::KeyPoint& k = o.keyframe->f().keys_un[o.index];
        optimize::BaObservation ob;
        ob.keyframe = it->second;
        ob.point = static_cast<int>(pi);
        ob.obs.uv = {k.pt.x, k.pt.y};
        ob.obs.u_right = o.keyframe->f().u_right[o.index];
        ob.obs.inv_sigma2 = c.scale.inv_sigma2[k.octave];
        problem.observations.push_back(ob);
        obs_slots.emplace_back(o.keyframe, o.index);
      }
    }
  }
  if (abort_ba_) return;
  optimize::BaOptions options;
  options.num_threads = o_.ba_threads;
  options.iterations_first = o_.ba_iterations_first;
  options.iterations_second = o_.ba_iterations_second;
  const optimize::BaResult r = optimize::bundle_adjust(problem, options, &abort_ba_);
  {
    std::lock_guard<std::mutex> c_lk(queue_mutex_);
    ++counters_.local_ba_runs;
    if (r.aborted) ++counters_.local_ba_aborted;
    counters_.local_ba_window_last = static_cast<long>(n_local);
    counters_.local_ba_fixed_last = static_cast<long>(kfs.size() - n_local);
    counters_.local_ba_window_max = std::max(counters_.local_ba_window_max, counters_.local_ba_window_last);
  }
  std::lock_guard<std::mutex> lk(map_.mutex());
  // Outlier observations leave the map first, then the estimates go back.
  for (size_t i = 0; i < obs_slots.size(); ++i) {
    if (!r.outlier[i]) continue;
    auto [k, idx] = obs_slots[i];
    const auto& p = points[problem.observations[i].point];
    if (!k->erased() && k->point(idx) == p) map_.erase_observation(*k, idx);
  }
  for (size_t i = 0; i < kfs.size(); ++i)
    if (!problem.keyframes[i].fixed && !kfs[i]->erased()) kfs[i]->set_pose(r.T_cw[i]);
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i]->erased()) continue;
    points[i]->set_position(r.points[i]);
    points[i]->update_normal_and_depth();
  }
}

}  // namespace dynaorb::mapping
