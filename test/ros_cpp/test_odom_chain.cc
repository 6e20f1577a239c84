#include <gtest/gtest.h>

#include "support/odom_chain.h"

namespace dynaorb::node {
namespace {

Eigen::Isometry3d pose(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, 0.0);
  return T;
}

void expect_near(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), 1e-9) << a.matrix() << "\nvs\n" << b.matrix();
}

TEST(OdomChain, FollowsTheMapWhileTrackingIsContinuous) {
  OdomChain c;
  c.update(pose(0, 0, 0), 0.0, true);
  c.update(pose(1, 0, 0.1), 0.5, true);
  c.update(pose(2, 0.5, 0.2), 1.0, true);
  expect_near(c.T_odom_base(), pose(2, 0.5, 0.2));
  expect_near(c.T_map_odom(), Eigen::Isometry3d::Identity());
  ASSERT_TRUE(c.velocity_valid());
  // Body-frame velocity over the last step.
  const Eigen::Vector3d expected = pose(1, 0, 0.1).linear().transpose() * Eigen::Vector3d(1, 0.5, 0) / 0.5;
  EXPECT_LT((c.linear() - expected).norm(), 1e-9);
  EXPECT_NEAR(c.angular().z(), 0.2, 1e-9);
}

TEST(OdomChain, AJumpGoesIntoMapToOdom) {
  OdomChain c;
  c.update(pose(0, 0, 0), 0.0, true);
  c.update(pose(1, 0, 0), 0.1, true);
  // A loop correction moves the map pose by 0.3 m: odom does not jump.
  c.update(pose(1.3, 0.2, 0.05), 0.2, false);
  expect_near(c.T_odom_base(), pose(1, 0, 0));
  expect_near(c.T_map_odom() * c.T_odom_base(), pose(1.3, 0.2, 0.05));
  EXPECT_FALSE(c.velocity_valid());
  // Continuous again: odom integrates the step from the corrected pose.
  c.update(pose(1.4, 0.2, 0.05), 0.3, true);
  expect_near(c.T_odom_base(), pose(1, 0, 0) * pose(1.3, 0.2, 0.05).inverse() * pose(1.4, 0.2, 0.05));
  expect_near(c.T_map_odom() * c.T_odom_base(), pose(1.4, 0.2, 0.05));
}

TEST(OdomChain, RestartHoldsOdomStill) {
  OdomChain c;
  c.update(pose(0, 0, 0), 0.0, true);
  c.update(pose(0.5, 0, 0), 0.1, true);
  c.restart();
  c.update(pose(5, 5, 1), 0.2, true);  // a new map's pose: no relation to the last one
  expect_near(c.T_odom_base(), pose(0.5, 0, 0));
  expect_near(c.T_map_odom() * c.T_odom_base(), pose(5, 5, 1));
}

TEST(OdomChain, NonIncreasingStampsAreAGap) {
  OdomChain c;
  c.update(pose(0, 0, 0), 1.0, true);
  c.update(pose(1, 0, 0), 1.0, true);
  expect_near(c.T_odom_base(), pose(0, 0, 0));
  EXPECT_FALSE(c.velocity_valid());
}

}  // namespace
}  // namespace dynaorb::node
