#pragma once
// A tracked frame's pose estimated again once the map around it has been
// refined (ours; TrackerOptions::refine_lag_keyframes). ORB-SLAM2 keeps each
// frame's pose relative to its reference keyframe as tracking found it. A
// frame is tracked against points that the newest keyframes made moments
// before, from one stereo pair or two views, before a local BA has seen them
// from a second keyframe; local BA then moves the keyframes and the points,
// and the frames between the keyframes only follow their reference keyframe.
// Here each frame keeps the map points it tracked as inliers, with its
// keypoints, and once later keyframes have been mapped its pose is solved
// again (the motion-only BA of tracking) against those points' new
// positions. Synthetic stereo sequences show what it corrects: a point
// matched on the wrong stereo row feature (0.49 m deep on a wall 4.5 m away)
// pulled one frame 15 mm off while the points around it were right.
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "dynaorb/map/frame.h"
#include "dynaorb/optimize/pose_optimizer.h"

namespace dynaorb::tracking {

// One tracked keypoint of a frame and the map point it matched.
struct FrameObservation {
  std::shared_ptr<map::MapPoint> point;
  optimize::Observation obs;  // undistorted pixel, right coordinate (-1: none), level weight
};

// Keypoint i of f as pose optimisation observes it: its undistorted pixel,
// its right coordinate (-1: none) and its level's weight.
optimize::Observation keypoint_observation(const map::Frame& f, int i);

// f's matched map points that pose optimisation kept (not outliers), with
// their keypoints. Reads the frame only.
std::vector<FrameObservation> frame_observations(const map::Frame& f);

// The observations whose map points are still in the map, or were fused
// into one that is (Map::replace_point), each with that point's current
// position. The caller holds the map's mutex.
std::vector<optimize::PoseObservation> current_observations(const std::vector<FrameObservation>& obs);

// Motion-only BA (optimize::optimize_pose: Huber, `rounds` rounds of outlier
// classification; tracking runs four; final_huber as tracking's
// TrackerOptions::pose_final_huber) from T_cw_init. nullopt, for the
// caller to keep the pose it had, when fewer than min_points observations
// are given or fewer than min_points of them end as inliers.
std::optional<Eigen::Isometry3d> refine_pose(const optimize::Intrinsics& K, const Eigen::Isometry3d& T_cw_init,
                                             const std::vector<optimize::PoseObservation>& obs, int min_points,
                                             int rounds = 4, double final_huber = 0);

}  // namespace dynaorb::tracking
