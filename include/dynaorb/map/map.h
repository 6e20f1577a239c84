#pragma once
// The map: owner of every keyframe and map point, and the one place that
// changes the links between them (observations, replacements, erasures).
//
// Thread contract: tracking and local mapping share one Map. Whoever reads or
// changes keyframes, points or their links holds mutex() for the whole step;
// the expensive solves (local BA) copy what they need out, solve unlocked, and
// write back under the lock, checking that nothing they touch was erased.
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "dynaorb/map/keyframe.h"
#include "dynaorb/map/map_point.h"

namespace dynaorb::map {

// Told, with the map's mutex held, when keyframes leave the map: one culled,
// or all of them on clear(). Indices over keyframes (the keyframe database)
// stay in step through it.
class MapObserver {
 public:
  virtual ~MapObserver() = default;
  virtual void keyframe_erased(const KeyFrame& kf) = 0;
  virtual void map_cleared() = 0;
};

class Map {
 public:
  std::mutex& mutex() const { return mutex_; }

  // Non-owning; null detaches. Set and reset with the mutex held.
  void set_observer(MapObserver* observer) { observer_ = observer; }

  long new_keyframe_id() { return next_keyframe_id_++; }
  long new_point_id() { return next_point_id_++; }

  void add_keyframe(const std::shared_ptr<KeyFrame>& kf);
  void add_point(const std::shared_ptr<MapPoint>& p);

  // Links keypoint `index` of kf and point p both ways.
  void add_observation(KeyFrame& kf, int index, const std::shared_ptr<MapPoint>& p);
  // Unlinks keypoint `index` of kf; a point left with <= 2 observations goes (ORB-SLAM).
  void erase_observation(KeyFrame& kf, int index);
  // Removes the point from the map and from every keyframe that observes it.
  void erase_point(const std::shared_ptr<MapPoint>& p);
  // Moves the observations of `old_point` to `keep` (duplicate fusion).
  void replace_point(const std::shared_ptr<MapPoint>& old_point, const std::shared_ptr<MapPoint>& keep);
  // Removes a keyframe: its observations, its covisibility edges, and re-links
  // its spanning-tree children to the remaining keyframes (ORB-SLAM's SetBadFlag).
  void erase_keyframe(const std::shared_ptr<KeyFrame>& kf);

  std::shared_ptr<KeyFrame> keyframe(long id) const;  // null when not in the map
  std::shared_ptr<MapPoint> point(long id) const;
  std::vector<std::shared_ptr<KeyFrame>> keyframes() const;  // by id
  std::vector<std::shared_ptr<MapPoint>> points() const;     // by id
  size_t keyframe_count() const { return keyframes_.size(); }
  size_t point_count() const { return points_.size(); }
  long max_keyframe_id() const { return next_keyframe_id_ - 1; }

  void clear();

 private:
  friend class MapIo;  // map_io.cc: restores the id counters on loading
  mutable std::mutex mutex_;
  MapObserver* observer_ = nullptr;
  std::map<long, std::shared_ptr<KeyFrame>> keyframes_;
  std::map<long, std::shared_ptr<MapPoint>> points_;
  long next_keyframe_id_ = 0;
  long next_point_id_ = 0;
};

}  // namespace dynaorb::map
