// Loop correction: neighbourhood correction, loop fusion, essential graph (ORB-SLAM Sec. VI-C, VI-D).
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

#include "loop.h"

namespace dynaorb::loop {

using map::KeyFrame;
using map::MapPoint;

bool LoopCloser::correct(Loop& loop) {
  const auto t0 = Clock::now();
  stop_global_ba();  // a new loop makes a running global BA obsolete
  mapper_.pause();
  bool done = false;
  long edge_ends = 0;  // loop edges counted from both ends
  {
    std::lock_guard<std::mutex> lk(map_.mutex());
    KeyFrame* current = loop.current.get();
    KeyFrame* match = loop.match.get();
    if (!current->erased() && !match->erased()) {
      current->update_connections();
      std::vector<KeyFrame*> connected = current->covisibles();
      connected.push_back(current);

      // Poses of the current side with the loop transform, through their relative poses.
      std::unordered_map<KeyFrame*, Sim3> corrected, uncorrected;
      const Eigen::Isometry3d T_wc = current->T_wc();
      for (KeyFrame* k : connected) {
        uncorrected[k] = pose_of(*k);
        corrected[k] = k == current ? loop.S_cw : Sim3::from_isometry(k->T_cw() * T_wc) * loop.S_cw;
      }
      // Their points (each moved once, by the first keyframe that sees it).
      std::unordered_map<const MapPoint*, KeyFrame*> corrected_by;
      for (KeyFrame* k : connected) {
        for (const auto& p : k->points()) {
          if (!p || p->erased() || corrected_by.count(p.get())) continue;
          p->set_position(optimize::correct_point(uncorrected[k], corrected[k], p->position()));
          corrected_by[p.get()] = k;
          p->update_normal_and_depth();
        }
      }
      for (KeyFrame* k : connected) k->set_pose(optimize::sim3_to_se3(corrected[k]));
      for (KeyFrame* k : connected) k->update_connections();

      // Loop fusion: the current keyframe's matched points are replaced by the loop side's.
      for (size_t i = 0; i < loop.matched.size(); ++i) {
        const std::shared_ptr<MapPoint>& lp = loop.matched[i];
        if (!lp || lp->erased()) continue;
        const std::shared_ptr<MapPoint> cp = current->point(static_cast<int>(i));
        if (cp == lp) continue;
        if (cp && !cp->erased()) {
          map_.replace_point(cp, lp);
        } else if (lp->index_in(current) < 0) {
          map_.add_observation(*current, static_cast<int>(i), lp);
          lp->compute_distinctive_descriptor();
        }
      }
      // The loop points projected into the corrected neighbours (ORB-SLAM2's SearchAndFuse).
      const match::Matcher matcher;
      for (KeyFrame* k : connected) {
        if (k->erased()) continue;
        matcher.fuse(map_, *k, loop.loop_points, o_.fuse_radius);
      }
      // New links across the loop.
      std::unordered_set<const KeyFrame*> connected_set(connected.begin(), connected.end());
      std::vector<std::pair<KeyFrame*, std::vector<KeyFrame*>>> loop_links;
      for (KeyFrame* k : connected) {
        if (k->erased()) continue;
        const std::vector<KeyFrame*> before = k->covisibles();
        k->update_connections();
        std::vector<KeyFrame*> links;
        for (KeyFrame* n : k->covisibles())
          if (!connected_set.count(n) && std::find(before.begin(), before.end(), n) == before.end())
            links.push_back(n);
        loop_links.emplace_back(k, std::move(links));
      }

      // Essential graph.
      const std::vector<std::shared_ptr<KeyFrame>> kfs = map_.keyframes();
      std::unordered_map<const KeyFrame*, int> node;
      optimize::PoseGraphProblem problem;
      std::vector<Sim3> measured;  // the poses the relative measurements come from
      for (const auto& k : kfs) {
        node[k.get()] = static_cast<int>(problem.nodes.size());
        const auto it = corrected.find(k.get());
        optimize::Sim3Node n;
        n.S_iw = it != corrected.end() ? it->second : pose_of(*k);
        n.fixed = k.get() == match || k->id == 0;
        problem.nodes.push_back(n);
        const auto u = uncorrected.find(k.get());
        measured.push_back(u != uncorrected.end() ? u->second : n.S_iw);
      }
      std::set<std::pair<int, int>> inserted;
      auto add_edge = [&](int i, int j, const Sim3& S_ij) {
        const std::pair<int, int> key(std::min(i, j), std::max(i, j));
        if (i == j || !inserted.insert(key).second) return;
        problem.edges.push_back({i, j, S_ij, optimize::Matrix7d::Identity()});
      };
      for (const auto& [k, links] : loop_links) {
        const auto ik = node.find(k);
        if (ik == node.end()) continue;
        for (KeyFrame* n : links) {
          const auto in = node.find(n);
          if (in == node.end()) continue;
          if (!(k == current && n == match) && k->weight(n) < o_.essential_min_weight) continue;
          add_edge(ik->second, in->second,
                   problem.nodes[ik->second].S_iw * problem.nodes[in->second].S_iw.inverse());
        }
      }
      for (const auto& k : kfs) {
        const int i = node[k.get()];
        auto measure = [&](int j) { add_edge(i, j, measured[i] * measured[j].inverse()); };
        if (KeyFrame* p = k->parent(); p && node.count(p)) measure(node[p]);
        if (const auto it = loop_edges_.find(k->id); it != loop_edges_.end())
          for (long id : it->second)
            if (auto other = map_.keyframe(id); other && node.count(other.get())) measure(node[other.get()]);
        for (KeyFrame* n : k->covisibles_min_weight(o_.essential_min_weight))
          if (node.count(n) && n->id < k->id) measure(node[n]);
      }
      optimize::PoseGraphOptions po;
      po.iterations = o_.pose_graph_iterations;
      po.fix_scale = sensor_ != Sensor::kMono;
      po.num_threads = o_.threads;
      const optimize::PoseGraphResult r = optimize::optimize_pose_graph(problem, po);
      for (size_t i = 0; i < kfs.size(); ++i) kfs[i]->set_pose(optimize::sim3_to_se3(r.S_iw[i]));
      for (const auto& p : map_.points()) {
        if (p->erased()) continue;
        const auto cb = corrected_by.find(p.get());
        const KeyFrame* ref = cb != corrected_by.end() ? cb->second : p->reference();
        const auto it = ref ? node.find(ref) : node.end();
        if (it == node.end()) continue;
        p->set_position(optimize::correct_point(problem.nodes[it->second].S_iw, r.S_iw[it->second], p->position()));
        p->update_normal_and_depth();
      }
      // The loop edge, and both ends kept from culling.
      loop_edges_[current->id].insert(match->id);
      loop_edges_[match->id].insert(current->id);
      for (const auto& [id, partners] : loop_edges_) edge_ends += static_cast<long>(partners.size());
      current->not_erase = match->not_erase = true;
      last_loop_kf_ = current->id;
      done = true;
    }
  }
  mapper_.resume();
  if (!done) return false;
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    ++counters_.loops_closed;
    counters_.last_loop_keyframe = loop.current->id;
    counters_.last_loop_match = loop.match->id;
    counters_.last_loop_frame = loop.current->frame_id;
    counters_.last_loop_matches = loop.matches;
    counters_.last_correction_ms = ms_since(t0);
    counters_.loop_edges = edge_ends / 2;
    if (o_.global_ba) gba_running_ = true;
  }
  if (o_.global_ba) {
    abort_gba_ = false;
    gba_thread_ = std::thread([this, id = loop.current->id] { global_ba(id); });
  }
  return true;
}

}  // namespace dynaorb::loop
