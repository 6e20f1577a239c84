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
  {
    std::lock_guard<std::mutex> lk(map_.mutex());
    loop_edges_.clear();
  }
  std::lock_guard<std::mutex> lk(queue_mutex_);
  counters_.loop_edges = 0;
}

std::map<long, std::set<long>> LoopCloser::loop_edges() const { return loop_edges_; }

void LoopCloser::restore_loop_edges(std::map<long, std::set<long>> edges) {
  long ends = 0;
  for (const auto& [id, partners] : edges) ends += static_cast<long>(partners.size());
  loop_edges_ = std::move(edges);
  std::lock_guard<std::mutex> lk(queue_mutex_);
  counters_.loop_edges = ends / 2;
}

LoopCloserCounters LoopCloser::counters() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return counters_;
}

void LoopCloser::run() {
  set_background_priority(o_.thread_nice);
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

void LoopCloser::stop_global_ba() {
  if (!gba_thread_.joinable()) return;
  abort_gba_ = true;
  gba_thread_.join();
  abort_gba_ = false;
}

}  // namespace dynaorb::loop
