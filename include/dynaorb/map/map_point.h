#pragma once
// A 3-D landmark: position, the keyframes that observe it (and at which
// keypoint), a representative descriptor, the mean viewing direction and the
// distance range over which ORB can see it scale invariantly.
//
// Ownership and threads: the Map owns every MapPoint (shared_ptr); keyframes
// co-own the points they observe; everything mutable here is read and written
// only while the Map's mutex is held (see map.h).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

namespace dynaorb::map {

class KeyFrame;

class MapPoint {
 public:
  struct Observation {
    KeyFrame* keyframe;  // non-owning: the map removes the observation before the keyframe goes
    int index;           // keypoint index in that keyframe
  };
  using Descriptor = std::array<std::uint8_t, 32>;

  MapPoint(long id, const Eigen::Vector3d& position, KeyFrame* reference, long first_keyframe_id);

  const long id;
  const long first_keyframe_id;

  const Eigen::Vector3d& position() const { return position_; }
  void set_position(const Eigen::Vector3d& p) { position_ = p; }

  const std::vector<Observation>& observations() const { return observations_; }
  int observation_count() const { return n_obs_; }  // stereo observations count twice
  int index_in(const KeyFrame* kf) const;           // -1 when not observed by kf
  void add_observation(KeyFrame* kf, int index);
  void erase_observation(KeyFrame* kf);             // reassigns the reference keyframe if needed
  KeyFrame* reference() const { return reference_; }

  const Descriptor& descriptor() const { return descriptor_; }
  const std::uint8_t* descriptor_data() const { return descriptor_.data(); }
  void set_descriptor(const std::uint8_t* d);
  // The descriptor with the least median distance to the others (ORB-SLAM).
  void compute_distinctive_descriptor();
  // Mean viewing direction and scale-invariance distance range from the observations.
  void update_normal_and_depth();

  const Eigen::Vector3d& normal() const { return normal_; }
  double min_distance() const { return 0.8 * min_distance_; }
  double max_distance() const { return 1.2 * max_distance_; }
  void set_normal_and_depth(const Eigen::Vector3d& normal, double min_d, double max_d);

  // Tracking statistics: in the view frustum of a frame vs. actually matched.
  void increase_visible(int n = 1) { visible_ += n; }
  void increase_found(int n = 1) { found_ += n; }
  int visible() const { return visible_; }
  int found() const { return found_; }
  double found_ratio() const { return static_cast<double>(found_) / visible_; }

  bool erased() const { return erased_; }
  const std::shared_ptr<MapPoint>& replaced_by() const { return replaced_by_; }

  // Scratch space of the tracker (frame ids stamp which frame filled them).
  struct TrackScratch {
    long in_view_frame = -1;     // frame id for which the projection below is valid
    long matched_frame = -1;     // frame id that already matched this point
    long local_map_frame = -1;   // frame id whose local map already lists this point
    double proj_x = 0, proj_y = 0, proj_xr = 0, view_cos = 0;
    int predicted_level = 0;
  } track;
  long fuse_keyframe = -1;       // keyframe id whose fusion last visited this point

 private:
  friend class Map;
  friend class MapIo;  // map_io.cc: restores state on loading
  Eigen::Vector3d position_;
  std::vector<Observation> observations_;
  int n_obs_ = 0;
  KeyFrame* reference_;
  Descriptor descriptor_{};
  Eigen::Vector3d normal_ = Eigen::Vector3d::Zero();
  double min_distance_ = 0, max_distance_ = 0;
  int visible_ = 1, found_ = 1;
  bool erased_ = false;
  std::shared_ptr<MapPoint> replaced_by_;
};

}  // namespace dynaorb::map
