#pragma once
// Rigid poses (double precision, Eigen) and stamped trajectories.
#include <Eigen/Geometry>
#include <vector>

namespace dynaorb {

using Pose = Eigen::Isometry3d;  // T_world_camera unless a name says otherwise

struct StampedPose {
  double stamp = 0.0;  // seconds
  Pose pose = Pose::Identity();
};

using Trajectory = std::vector<StampedPose>;

// Pose from translation and unit quaternion (x y z w order as in TUM files).
Pose pose_from_tq(const Eigen::Vector3d& t, const Eigen::Quaterniond& q);

}  // namespace dynaorb
