#pragma once
// A keyframe: a frame's features and pose kept in the map, the map points
// matched to its keypoints, its covisibility edges (weight = shared points)
// and its place in the spanning tree. Mutable state is guarded by the Map's
// mutex (see map.h); neighbours are non-owning pointers the Map keeps valid.
#include <Eigen/Geometry>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "dynaorb/map/bag_of_words.h"
#include "dynaorb/map/features.h"

namespace dynaorb::map {

class MapPoint;

class KeyFrame {
 public:
  KeyFrame(long id, long frame_id, double stamp, std::shared_ptr<const Features> features,
           const Eigen::Isometry3d& T_cw);

  const long id;
  const long frame_id;
  const double stamp;
  const std::shared_ptr<const Features> features;
  const Features& f() const { return *features; }
  const Calibration& calib() const { return *features->calib; }

  const Eigen::Isometry3d& T_cw() const { return T_cw_; }
  Eigen::Isometry3d T_wc() const { return T_cw_.inverse(); }
  Eigen::Vector3d center() const { return T_wc().translation(); }
  void set_pose(const Eigen::Isometry3d& T_cw) { T_cw_ = T_cw; }

  // Map points by keypoint index (null where none).
  const std::vector<std::shared_ptr<MapPoint>>& points() const { return points_; }
  const std::shared_ptr<MapPoint>& point(int i) const { return points_[i]; }
  void set_point(int i, std::shared_ptr<MapPoint> p) { points_[i] = std::move(p); }
  void clear_point(int i) { points_[i].reset(); }
  // Points seen by at least min_obs keyframes (ORB-SLAM's TrackedMapPoints).
  int tracked_points(int min_obs) const;
  // The depth below which a quantile of the points lies, in this camera.
  double median_depth(double quantile = 0.5) const;
  // World point from a keypoint with depth (stereo / RGB-D).
  Eigen::Vector3d unproject(int i) const;

  // Bag of words, null until computed (local mapping on insertion, or
  // tracking when it needs it first); set once, then read-only.
  const std::shared_ptr<const BagOfWords>& bow() const { return bow_; }
  void set_bow(std::shared_ptr<const BagOfWords> bow) {
    if (!bow_) bow_ = std::move(bow);
  }

  // Covisibility graph (weights recomputed from shared observations).
  void update_connections(int min_weight = 15);
  void erase_connection(KeyFrame* kf);
  std::vector<KeyFrame*> covisibles(int n = -1) const;  // by weight, descending
  std::vector<KeyFrame*> covisibles_min_weight(int w) const;
  int weight(KeyFrame* kf) const;

  // Spanning tree.
  KeyFrame* parent() const { return parent_; }
  const std::set<KeyFrame*>& children() const { return children_; }
  void set_parent(KeyFrame* p);

  bool erased() const { return erased_; }
  // The pose, also for a keyframe culled from the map: through the parent it
  // had then (pose relative to it kept), so frames tracked against it keep
  // following the map's corrections (ORB-SLAM's trajectory through the tree).
  Eigen::Isometry3d current_T_cw() const;
  bool not_erase = false;          // protected from culling (loop closing will use it)
  long track_reference_frame = -1;  // tracker's scratch: frame whose local map lists this keyframe

 private:
  friend class Map;
  friend class MapIo;  // map_io.cc: restores state on loading
  Eigen::Isometry3d T_cw_;
  std::vector<std::shared_ptr<MapPoint>> points_;
  std::shared_ptr<const BagOfWords> bow_;
  std::map<KeyFrame*, int> weights_;
  std::vector<std::pair<int, KeyFrame*>> ordered_;  // (weight, kf) descending
  KeyFrame* parent_ = nullptr;
  std::set<KeyFrame*> children_;
  bool first_connection_ = true;
  bool erased_ = false;
  std::shared_ptr<KeyFrame> erased_parent_;
  Eigen::Isometry3d T_c_parent_ = Eigen::Isometry3d::Identity();
  void order_connections();
};

}  // namespace dynaorb::map
