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

namespace dynaorb::loop {

using map::KeyFrame;
using map::MapPoint;

namespace {

Sim3 pose_of(const KeyFrame& kf) { return Sim3::from_isometry(kf.T_cw()); }
}  // namespace

// ---------------------------------------------------------------------------------------------
std::vector<long> ConsistentGroups::update(const std::vector<std::pair<long, Group>>& candidates,
                                           int threshold) {
  std::vector<std::pair<Group, int>> current;
  std::vector<bool> extended(groups_.size(), false);
  std::vector<long> consistent;
  for (const auto& [id, group] : candidates) {
    bool enough = false, consistent_for_some = false;
    for (size_t g = 0; g < groups_.size(); ++g) {
      const Group& previous = groups_[g].first;
      const bool shares = std::any_of(group.begin(), group.end(), [&](long k) { return previous.count(k) > 0; });
      if (!shares) continue;
      consistent_for_some = true;
      const int consistency = groups_[g].second + 1;
      if (!extended[g]) {
        current.emplace_back(group, consistency);
        extended[g] = true;
      }
      if (consistency >= threshold && !enough) {
        consistent.push_back(id);
        enough = true;
      }
    }
    if (!consistent_for_some) current.emplace_back(group, 0);
  }
  groups_.swap(current);
  return consistent;
}

// ---------------------------------------------------------------------------------------------
struct LoopCloser::Loop {
  std::shared_ptr<KeyFrame> current, match;
  Sim3 S_cw;                                         // corrected pose of the current keyframe
  std::vector<std::shared_ptr<MapPoint>> matched;    // per keypoint of current: loop-side point
  std::vector<std::shared_ptr<MapPoint>> loop_points;  // points of match and its covisibles
  int matches = 0;
};

LoopCloser::LoopCloser(map::Map& map, Sensor sensor, place::KeyFrameDatabase& database,
                       mapping::LocalMapper& mapper, const LoopCloserOptions& options)
    : map_(map), sensor_(sensor), database_(database), mapper_(mapper), o_(options) {
  o_.ransac.fix_scale = sensor_ != Sensor::kMono;
  thread_ = std::thread([this] { run(); });
}

LoopCloser::~LoopCloser() {
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    stop_ = true;
    queue_.clear();
  }
  queue_cv_.notify_all();
  thread_.join();
  stop_global_ba();
}

void LoopCloser::insert_keyframe(std::shared_ptr<KeyFrame> kf) {
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    queue_.push_back(std::move(kf));
  }
  queue_cv_.notify_one();
}

bool LoopCloser::idle() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return !busy_ && queue_.empty() && !gba_running_;
}

void LoopCloser::wait_idle() {
  std::unique_lock<std::mutex> lk(queue_mutex_);
  idle_cv_.wait(lk, [this] { return stop_ || (!busy_ && queue_.empty() && !gba_running_); });
}

void LoopCloser::reset() {
  {
    std::unique_lock<std::mutex> lk(queue_mutex_);
    queue_.clear();
    idle_cv_.wait(lk, [this] { return stop_ || !busy_; });
  }
  stop_global_ba();
  // The loop thread is waiting on an empty queue: its state can be touched.
  groups_.clear();
  last_loop_kf_ = -1;
  std::lock_guard<std::mutex> lk(map_.mutex());
  loop_edges_.clear();
}

LoopCloserCounters LoopCloser::counters() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return counters_;
}

void LoopCloser::run() {
  for (;;) {
    std::shared_ptr<KeyFrame> kf;
    {
      std::unique_lock<std::mutex> lk(queue_mutex_);
      queue_cv_.wait(lk, [this] { return stop_ || !queue_.empty(); });
      if (stop_) break;
      kf = queue_.front();
      queue_.pop_front();
      busy_ = true;
    }
    process(kf);
    {
      std::lock_guard<std::mutex> lk(queue_mutex_);
      busy_ = false;
    }
    idle_cv_.notify_all();
  }
  idle_cv_.notify_all();
}

void LoopCloser::process(const std::shared_ptr<KeyFrame>& kf) {
  Loop loop;
  bool found = false;
  {
    std::lock_guard<std::mutex> lk(map_.mutex());
    if (kf->erased()) return;
    {
      std::lock_guard<std::mutex> c_lk(queue_mutex_);
      ++counters_.keyframes;
    }
    const std::vector<std::shared_ptr<KeyFrame>> candidates = detect(*kf);
    if (!candidates.empty()) {
      {
        std::lock_guard<std::mutex> c_lk(queue_mutex_);
        counters_.candidates += static_cast<long>(candidates.size());
      }
      found = compute_sim3(kf, candidates, loop);
    }
  }
  if (found) correct(loop);
}

std::vector<std::shared_ptr<KeyFrame>> LoopCloser::detect(KeyFrame& kf) {
  if ((last_loop_kf_ >= 0 && kf.id < last_loop_kf_ + o_.min_keyframes_after_loop) ||
      static_cast<int>(map_.keyframe_count()) <= o_.min_map_keyframes || !kf.bow())
    return {};
  // The bar: the lowest score against the covisible keyframes (ORB-SLAM: starts at 1).
  double min_score = 1.0;
  for (const KeyFrame* n : kf.covisibles()) {
    if (n->erased() || !n->bow()) continue;
    min_score = std::min(min_score, database_.vocabulary().score(kf.bow()->words, n->bow()->words));
  }
  const std::vector<place::PlaceCandidate> found = database_.loop_candidates(kf, min_score);
  if (found.empty()) {
    groups_.clear();
    return {};
  }
  std::vector<std::pair<long, ConsistentGroups::Group>> groups;
  for (const place::PlaceCandidate& c : found) {
    ConsistentGroups::Group g{c.keyframe->id};
    for (const KeyFrame* n : c.keyframe->covisibles()) g.insert(n->id);
    groups.emplace_back(c.keyframe->id, std::move(g));
  }
  std::vector<std::shared_ptr<KeyFrame>> out;
  for (long id : groups_.update(groups, o_.consistency))
    if (auto k = map_.keyframe(id)) out.push_back(std::move(k));
  return out;
}

bool LoopCloser::compute_sim3(const std::shared_ptr<KeyFrame>& kf,
                              const std::vector<std::shared_ptr<KeyFrame>>& candidates, Loop& loop) {
  const match::Matcher matcher;
  const map::Calibration& c1 = kf->calib();
  const map::Features& f1 = kf->f();
  const Eigen::Matrix3d K1 = c1.K_eigen();
  for (const auto& cand : candidates) {
    if (cand->erased() || !cand->bow()) continue;
    map::Frame bow_frame(kf->frame_id, kf->stamp, kf->features);
    bow_frame.bow = kf->bow();
    if (matcher.search_by_bow(*cand, bow_frame, o_.bow_nn_ratio) < o_.min_bow_matches) continue;
    const map::Calibration& c2 = cand->calib();
    std::vector<Sim3Match> matches;
    std::vector<int> keypoint;  // match -> keypoint of kf
    for (int i = 0; i < f1.size(); ++i) {
      const auto& p2 = bow_frame.points[i];
      const auto& p1 = kf->point(i);
      if (!p1 || !p2 || p1->erased() || p2->erased()) continue;
      const int j = p2->index_in(cand.get());
      if (j < 0) continue;
      Sim3Match m;
      m.X1 = kf->T_cw() * p1->position();
      m.X2 = cand->T_cw() * p2->position();
      const cv::KeyPoint& k1 = f1.keys_un[i];
      const cv::KeyPoint& k2 = cand->f().keys_un[j];
      m.uv1 = {k1.pt.x, k1.pt.y};
      m.uv2 = {k2.pt.x, k2.pt.y};
      m.sigma2_1 = c1.scale.sigma2[k1.octave];
      m.sigma2_2 = c2.scale.sigma2[k2.octave];
      matches.push_back(m);
      keypoint.push_back(i);
    }
    if (static_cast<int>(matches.size()) < o_.min_bow_matches) continue;
    Sim3RansacOptions ro = o_.ransac;
    ro.seed = static_cast<unsigned>(kf->id * 7919 + cand->id);
    const Sim3RansacResult r = sim3_ransac(matches, K1, c2.K_eigen(), ro);
    if (!r.ok) continue;

    // Guided matching with the estimate: the points of the candidate and its covisibles
    // projected into the current keyframe (ORB-SLAM2's SearchByProjection with Scw).
    const Sim3 S_cw = r.S12 * pose_of(*cand);
    map::Frame guided(kf->frame_id, kf->stamp, kf->features);
    guided.set_pose(optimize::sim3_to_se3(S_cw));
    for (size_t m = 0; m < matches.size(); ++m)
      if (r.inlier[m]) guided.points[keypoint[m]] = bow_frame.points[keypoint[m]];
    std::vector<KeyFrame*> group{cand.get()};
    for (KeyFrame* n : cand->covisibles())
      if (!n->erased()) group.push_back(n);
    for (KeyFrame* k : group)
      matcher.search_by_projection(guided, *k, o_.projection_radius, o_.projection_max_distance);
    int total = 0;
    for (const auto& p : guided.points)
      if (p) ++total;
    if (total < o_.min_projection_matches) continue;

    loop.current = kf;
    loop.match = cand;
    loop.S_cw = S_cw;
    loop.matched = guided.points;
    loop.matches = total;
    std::unordered_set<const MapPoint*> seen;
    for (KeyFrame* k : group)
      for (const auto& p : k->points())
        if (p && !p->erased() && seen.insert(p.get()).second) loop.loop_points.push_back(p);
    return true;
  }
  return false;
}

void LoopCloser::stop_global_ba() {
  if (!gba_thread_.joinable()) return;
  abort_gba_ = true;
  gba_thread_.join();
  abort_gba_ = false;
}

bool LoopCloser::correct(Loop& loop) {
  const auto t0 = Clock::now();
  stop_global_ba();  // a new loop makes a running global BA obsolete
  mapper_.pause();
  bool done = false;
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
    if (o_.global_ba) gba_running_ = true;
  }
  if (o_.global_ba) {
    abort_gba_ = false;
    gba_thread_ = std::thread([this, id = loop.current->id] { global_ba(id); });
  }
  return true;
}

void LoopCloser::global_ba(long /*loop_keyframe*/) {
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
