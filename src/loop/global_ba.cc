// Global BA after a loop, in its own thread, merged through the spanning tree (ORB-SLAM2 Sec. V).
#include "dynaorb/loop/loop_closer.h"

#include <algorithm>
#include <chrono>
#include <unordered_map>
#include <unordered_set>

#include "dynaorb/map/frame.h"
#include "dynaorb/match/matcher.h"
#include "dynaorb/optimize/bundle_adjuster.h"
#include "dynaorb/optimize/pose_graph.h"
#include "dynaorb/core/stopwatch.h"
#include "dynaorb/core/thread_priority.h"

#include "loop.h"

namespace dynaorb::loop {

using map::KeyFrame;
using map::MapPoint;

void LoopCloser::global_ba(long /*loop_keyframe*/) {
  set_background_priority(o_.thread_nice);  // its own thread (loop_correction.cc)
  const auto t0 = Clock::now();
  optimize::BaProblem problem;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::vector<std::shared_ptr<MapPoint>> points;
  {
    std::lock_guard<std::mutex> lk(map_.mutex());
    kfs = map_.keyframes();
    std::unordered_map<const KeyFrame*, int> kf_index;
    for (const auto& k : kfs) {
      kf_index[k.get()] = static_cast<int>(problem.keyframes.size());
      problem.keyframes.push_back({k->T_cw(), k->id == 0});
    }
    if (!kfs.empty()) {
      const map::Calibration& c = kfs.front()->calib();
      problem.K = {c.fx, c.fy, c.cx, c.cy, c.bf};
    }
    for (const auto& p : map_.points()) {
      if (p->erased()) continue;
      const int pi = static_cast<int>(points.size());
      bool used = false;
      for (const MapPoint::Observation& o : p->observations()) {
        const auto it = kf_index.find(o.keyframe);
        if (it == kf_index.end()) continue;
        const map::Calibration& c = o.keyframe->calib();
        const cv::KeyPoint& k = o.keyframe->f().keys_un[o.index];
        optimize::BaObservation ob;
        ob.keyframe = it->second;
        ob.point = pi;
        ob.obs.uv = {k.pt.x, k.pt.y};
        ob.obs.u_right = o.keyframe->f().u_right[o.index];
        ob.obs.inv_sigma2 = c.scale.inv_sigma2[k.octave];
        problem.observations.push_back(ob);
        used = true;
      }
      if (!used) continue;
      points.push_back(p);
      problem.points.push_back(p->position());
    }
  }
  optimize::BaOptions bo;
  bo.iterations_first = o_.global_ba_iterations;
  bo.iterations_second = o_.global_ba_iterations / 2;
  bo.num_threads = o_.threads;
  const optimize::BaResult r = optimize::bundle_adjust(problem, bo, &abort_gba_);
  bool merged = false;
  if (!r.aborted && !abort_gba_) {
    mapper_.pause();
    {
      std::lock_guard<std::mutex> lk(map_.mutex());
      // New poses: the adjusted ones, and keyframes created meanwhile through their spanning-tree
      // parents (relative pose kept), walking down from the roots.
      std::unordered_map<const KeyFrame*, Eigen::Isometry3d> after;
      for (size_t i = 0; i < kfs.size(); ++i)
        if (!kfs[i]->erased()) after[kfs[i].get()] = r.T_cw[i];
      const std::vector<std::shared_ptr<KeyFrame>> now = map_.keyframes();
      std::deque<KeyFrame*> todo;
      for (const auto& k : now)
        if (!k->parent() && after.count(k.get())) todo.push_back(k.get());
      while (!todo.empty()) {
        KeyFrame* k = todo.front();
        todo.pop_front();
        for (KeyFrame* child : k->children()) {
          if (!after.count(child)) after[child] = child->T_cw() * k->T_wc() * after[k];
          todo.push_back(child);
        }
      }
      std::unordered_map<const KeyFrame*, Eigen::Isometry3d> before;
      for (const auto& k : now) {
        before[k.get()] = k->T_cw();
        if (const auto it = after.find(k.get()); it != after.end()) k->set_pose(it->second);
      }
      std::unordered_set<const MapPoint*> adjusted;
      for (size_t i = 0; i < points.size(); ++i) {
        if (points[i]->erased()) continue;
        points[i]->set_position(r.points[i]);
        adjusted.insert(points[i].get());
      }
      for (const auto& p : map_.points()) {
        if (p->erased()) continue;
        if (!adjusted.count(p.get())) {
          const KeyFrame* ref = p->reference();
          const auto a = ref ? after.find(ref) : after.end();
          const auto b = ref ? before.find(ref) : before.end();
          if (a == after.end() || b == before.end()) continue;
          p->set_position(a->second.inverse() * (b->second * p->position()));
        }
        p->update_normal_and_depth();
      }
    }
    mapper_.resume();
    merged = true;
  }
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    if (merged) {
      ++counters_.global_ba_runs;
      counters_.last_global_ba_ms = ms_since(t0);
    } else {
      ++counters_.global_ba_aborted;
    }
    gba_running_ = false;
  }
  idle_cv_.notify_all();
}

}  // namespace dynaorb::loop
