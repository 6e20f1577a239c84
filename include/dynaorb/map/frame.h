#pragma once
// The frame being tracked: its features, the map points matched to them
// (with outlier flags from pose optimisation), its pose and reference keyframe.
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "dynaorb/map/bag_of_words.h"
#include "dynaorb/map/features.h"
#include "dynaorb/map/keyframe.h"
#include "dynaorb/map/map_point.h"

namespace dynaorb::map {

struct Frame {
  long id = -1;
  double stamp = 0;
  std::shared_ptr<const Features> features;
  std::vector<std::shared_ptr<MapPoint>> points;  // per keypoint, null when unmatched
  std::vector<bool> outlier;                      // per keypoint, from pose optimisation
  Eigen::Isometry3d T_cw = Eigen::Isometry3d::Identity();
  bool has_pose = false;
  std::shared_ptr<KeyFrame> reference;
  std::shared_ptr<const BagOfWords> bow;          // null until tracking needs it

  Frame() = default;
  Frame(long id_, double stamp_, std::shared_ptr<const Features> f)
      : id(id_), stamp(stamp_), features(std::move(f)), points(features->size()),
        outlier(features->size(), false) {}

  const Features& f() const { return *features; }
  const Calibration& calib() const { return *features->calib; }
  int size() const { return features->size(); }
  Eigen::Vector3d center() const { return T_cw.inverse().translation(); }
  void set_pose(const Eigen::Isometry3d& T) {
    T_cw = T;
    has_pose = true;
  }
  Eigen::Vector3d unproject(int i) const {
    const cv::KeyPoint& k = features->keys_un[i];
    return T_cw.inverse() * calib().unproject(k.pt.x, k.pt.y, features->depth[i]);
  }
  int matched_points() const;  // non-null, non-outlier slots

  // ORB-SLAM's isInFrustum: projects p, checks the image bounds, the
  // scale-invariance distance range and the viewing angle (cos >= view_cos_limit);
  // fills p.track for this frame when it passes.
  bool in_frustum(MapPoint& p, double view_cos_limit) const;
};

}  // namespace dynaorb::map
