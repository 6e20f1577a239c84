#pragma once
// REP-105 frames for a SLAM node that is also the only odometry source
// (ROS-free, unit-tested). map -> base_link is the SLAM pose; it jumps when
// the map is corrected (loop closure, relocalisation, a new map). odom ->
// base_link must stay continuous, so it integrates the motion between
// consecutive tracked frames only, and map -> odom takes every jump:
//   T_odom_base(k) = T_odom_base(k-1) * T_map_base(k-1)^-1 * T_map_base(k)   (continuous)
//   T_odom_base(k) = T_odom_base(k-1)                                         (after a gap)
//   T_map_odom(k)  = T_map_base(k) * T_odom_base(k)^-1
#include <Eigen/Geometry>

namespace dynaorb::node {

class OdomChain {
 public:
  // A tracked frame's base pose in the map. `continuous`: the previous frame
  // was tracked too and the map was not corrected in between.
  void update(const Eigen::Isometry3d& T_map_base, double stamp, bool continuous) {
    const bool step = has_previous_ && continuous && stamp > previous_stamp_;
    if (step) {
      const Eigen::Isometry3d delta = previous_.inverse() * T_map_base;
      T_odom_base_ = T_odom_base_ * delta;
      const double dt = stamp - previous_stamp_;
      linear_ = delta.translation() / dt;
      const Eigen::AngleAxisd aa(delta.linear());
      angular_ = aa.axis() * aa.angle() / dt;
    } else {
      linear_.setZero();
      angular_.setZero();
    }
    T_map_odom_ = T_map_base * T_odom_base_.inverse();
    previous_ = T_map_base;
    previous_stamp_ = stamp;
    has_previous_ = true;
    velocity_valid_ = step;
  }
  // The next frame starts a new chain (the map was reset or replaced).
  void restart() {
    has_previous_ = false;
    velocity_valid_ = false;
  }

  const Eigen::Isometry3d& T_map_odom() const { return T_map_odom_; }
  const Eigen::Isometry3d& T_odom_base() const { return T_odom_base_; }
  // Body-frame twist over the last step (zero after a gap; see velocity_valid).
  const Eigen::Vector3d& linear() const { return linear_; }
  const Eigen::Vector3d& angular() const { return angular_; }
  bool velocity_valid() const { return velocity_valid_; }

 private:
  Eigen::Isometry3d T_odom_base_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_map_odom_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d previous_ = Eigen::Isometry3d::Identity();
  double previous_stamp_ = 0.0;
  bool has_previous_ = false, velocity_valid_ = false;
  Eigen::Vector3d linear_ = Eigen::Vector3d::Zero(), angular_ = Eigen::Vector3d::Zero();
};

}  // namespace dynaorb::node
