#include "dynaorb/mapping/local_mapper.h"

#include <chrono>
#include "dynaorb/core/stopwatch.h"
#include "dynaorb/core/thread_priority.h"

namespace dynaorb::mapping {

using map::KeyFrame;
using map::MapPoint;

LocalMapper::LocalMapper(map::Map& map, Sensor sensor, const LocalMapperOptions& options,
                         std::shared_ptr<const vocab::Vocabulary> vocabulary, place::KeyFrameDatabase* database)
    : map_(map), sensor_(sensor), o_(options), vocabulary_(std::move(vocabulary)),
      database_(vocabulary_ ? database : nullptr), thread_([this] { run(); }) {}

LocalMapper::~LocalMapper() {
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    stop_ = true;
    queue_.clear();
  }
  abort_ba_ = true;
  queue_cv_.notify_all();
  thread_.join();
}

void LocalMapper::insert_keyframe(std::shared_ptr<KeyFrame> kf) {
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    queue_.push_back(std::move(kf));
  }
  interrupt_ba();  // a running local BA gives way to the new keyframe
  queue_cv_.notify_one();
}

bool LocalMapper::idle() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return !busy_ && queue_.empty();
}

size_t LocalMapper::queued() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return queue_.size();
}

bool LocalMapper::has_new_keyframes() const { return queued() > 0; }

bool LocalMapper::begin_local_ba() {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  if (stop_ || pause_requests_ > 0 || !queue_.empty() || generation_ != clears_) return false;
  abort_ba_ = false;
  return true;
}

void LocalMapper::wait_idle() {
  std::unique_lock<std::mutex> lk(queue_mutex_);
  idle_cv_.wait(lk, [this] { return stop_ || (!busy_ && queue_.empty()); });
}

void LocalMapper::pause() {
  std::unique_lock<std::mutex> lk(queue_mutex_);
  ++pause_requests_;
  abort_ba_ = true;
  idle_cv_.wait(lk, [this] { return stop_ || !busy_; });
}

void LocalMapper::resume() {
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    if (pause_requests_ > 0) --pause_requests_;
  }
  queue_cv_.notify_all();
}

bool LocalMapper::paused() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return pause_requests_ > 0 && !busy_;
}

void LocalMapper::clear_queue() {
  {
    std::lock_guard<std::mutex> lk(queue_mutex_);
    queue_.clear();
    ++clears_;
  }
  abort_ba_ = true;
  wait_idle();
  std::lock_guard<std::mutex> lk(map_.mutex());
  recent_points_.clear();
}

LocalMapperCounters LocalMapper::counters() const {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  return counters_;
}

std::vector<StageTimes> LocalMapper::take_stage_times() {
  std::lock_guard<std::mutex> lk(queue_mutex_);
  std::vector<StageTimes> out;
  out.swap(stage_times_);
  return out;
}

void LocalMapper::run() {
  set_background_priority(o_.thread_nice);
  for (;;) {
    std::shared_ptr<KeyFrame> kf;
    {
      std::unique_lock<std::mutex> lk(queue_mutex_);
      queue_cv_.wait(lk, [this] { return stop_ || (pause_requests_ == 0 && !queue_.empty()); });
      if (stop_) break;
      kf = queue_.front();
      queue_.pop_front();
      busy_ = true;
      generation_ = clears_;
    }
    StageTimes t;
    const auto t0 = Clock::now();
    process(kf, t);
    t["local_mapping"] = ms_since(t0);
    if (sink_) {
      bool in_map;
      {
        std::lock_guard<std::mutex> lk(map_.mutex());
        in_map = !kf->erased();
      }
      if (in_map) sink_(kf);
    }
    {
      std::lock_guard<std::mutex> lk(queue_mutex_);
      busy_ = false;
      stage_times_.push_back(std::move(t));
      ++counters_.keyframes;
    }
    idle_cv_.notify_all();
  }
  idle_cv_.notify_all();
}

void LocalMapper::process(const std::shared_ptr<KeyFrame>& kf, StageTimes& t) {
  auto t0 = Clock::now();
  // The features are immutable: the bag of words needs no lock (tracking
  // may have set one already; set_bow keeps the first).
  std::shared_ptr<const map::BagOfWords> bow;
  if (vocabulary_) bow = map::BagOfWords::compute(*vocabulary_, kf->f());
  {
    std::lock_guard<std::mutex> lk(map_.mutex());
    if (kf->erased()) return;  // the map was reset meanwhile
    if (bow) kf->set_bow(bow);
    insert_into_graph(*kf);
    if (database_) database_->add(*kf);
    cull_recent_points(*kf);
  }
  t["mapping_insert"] = ms_since(t0);
  t0 = Clock::now();
  create_new_points(kf);
  t["triangulation"] = ms_since(t0);
  if (!has_new_keyframes()) {
    t0 = Clock::now();
    {
      std::lock_guard<std::mutex> lk(map_.mutex());
      if (!kf->erased()) fuse_with_neighbors(*kf);
    }
    t["fuse"] = ms_since(t0);
  }
  if (begin_local_ba()) {
    t0 = Clock::now();
    if (o_.local_ba) local_bundle_adjustment(*kf);
    t["local_ba"] = ms_since(t0);
    t0 = Clock::now();
    {
      std::lock_guard<std::mutex> lk(map_.mutex());
      if (!kf->erased()) cull_keyframes(*kf);
    }
    t["keyframe_culling"] = ms_since(t0);
  }
}

void LocalMapper::insert_into_graph(KeyFrame& kf) {
  // Points matched by tracking gain this observation; points the tracker
  // created with this keyframe are "recent" and go through culling.
  for (int i = 0; i < kf.f().size(); ++i) {
    const std::shared_ptr<MapPoint>& p = kf.point(i);
    if (!p) continue;
    if (p->erased()) {
      kf.clear_point(i);
      continue;
    }
    if (p->index_in(&kf) < 0) {
      p->add_observation(&kf, i);
      p->update_normal_and_depth();
      p->compute_distinctive_descriptor();
    } else if (p->first_keyframe_id == kf.id) {
      recent_points_.push_back(p);
    }
  }
  kf.update_connections();
}

void LocalMapper::cull_recent_points(const KeyFrame& kf) {
  const int min_obs = sensor_ == Sensor::kMono ? o_.min_observations_mono : o_.min_observations_stereo;
  std::vector<std::shared_ptr<MapPoint>> keep;
  for (const auto& p : recent_points_) {
    if (p->erased()) continue;
    const long age = kf.id - p->first_keyframe_id;
    if (p->found_ratio() < o_.min_found_ratio || (age >= 2 && p->observation_count() <= min_obs)) {
      map_.erase_point(p);
      ++counters_.points_culled;
    } else if (age < 3) {
      keep.push_back(p);
    }
  }
  recent_points_.swap(keep);
}

void LocalMapper::cull_keyframes(KeyFrame& kf) {
  // A keyframe whose points (close ones for stereo / RGB-D) are, for the
  // most part, seen by >= 3 other keyframes at the same or a finer scale adds
  // nothing (ORB-SLAM's KeyFrameCulling).
  for (KeyFrame* cand : kf.covisibles()) {
    if (cand->id == 0 || cand->not_erase || cand->erased()) continue;
    const map::Features& f = cand->f();
    int points = 0, redundant = 0;
    for (int i = 0; i < f.size(); ++i) {
      const auto& p = cand->point(i);
      if (!p || p->erased()) continue;
      if (sensor_ != Sensor::kMono && !f.is_close(i)) continue;
      ++points;
      if (p->observation_count() <= o_.redundant_observers) continue;
      const int level = f.keys_un[i].octave;
      int observers = 0;
      for (const MapPoint::Observation& o : p->observations()) {
        if (o.keyframe == cand) continue;
        if (o.keyframe->f().keys_un[o.index].octave <= level + 1 && ++observers >= o_.redundant_observers)
          break;
      }
      if (observers >= o_.redundant_observers) ++redundant;
    }
    if (points > 0 && redundant > o_.redundant_ratio * points) {
      map_.erase_keyframe(map_.keyframe(cand->id));
      std::lock_guard<std::mutex> lk(queue_mutex_);
      ++counters_.keyframes_culled;
    }
  }
}

}  // namespace dynaorb::mapping
