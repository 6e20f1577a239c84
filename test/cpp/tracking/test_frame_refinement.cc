// A tracked frame's pose solved again against its points' current positions
// (tracking/frame_refinement.h, TrackerOptions::refine_lag_keyframes).
#include <gtest/gtest.h>

#include <cmath>

#include "dynaorb/map/map.h"
#include "dynaorb/tracking/frame_refinement.h"
#include "../map/map_test_util.h"

namespace dynaorb::tracking {
namespace {

using map::KeyFrame;
using map::MapPoint;

Eigen::Isometry3d pose(double yaw_deg, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = t;
  return T;
}

double translation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

// 80 points 3-8 m in front of the camera at T_cw; the frame's keypoints are
// their exact projections (fx 500, cx 320, cy 240), every other one with its
// stereo right coordinate (bf 40), all at level 0; points 0-4 are marked
// outliers and their keypoints are garbage.
struct FrameRefinement : ::testing::Test {
  map::Map map;
  std::shared_ptr<KeyFrame> kf;
  std::vector<std::shared_ptr<MapPoint>> pts;
  map::Frame frame{7, 1.0, test::synthetic_features(80)};
  const Eigen::Isometry3d T_cw = pose(4.0, {0.3, -0.1, 0.5});
  const optimize::Intrinsics K{500, 500, 320, 240, 40};

  void SetUp() override {
    kf = std::make_shared<KeyFrame>(map.new_keyframe_id(), 0, 0.0, test::synthetic_features(80),
                                    Eigen::Isometry3d::Identity());
    map.add_keyframe(kf);
    auto features = std::make_shared<map::Features>(*test::synthetic_features(80));
    for (int i = 0; i < 80; ++i) {
      const Eigen::Vector3d pc(-1.5 + 3.0 * ((i * 37) % 80) / 80.0, -1.0 + 2.0 * ((i * 53) % 80) / 80.0,
                               3.0 + 5.0 * ((i * 29) % 80) / 80.0);
      auto p = std::make_shared<MapPoint>(map.new_point_id(), T_cw.inverse() * pc, kf.get(), 0);
      map.add_point(p);
      pts.push_back(p);
      const float u = static_cast<float>(500 * pc.x() / pc.z() + 320), v = static_cast<float>(500 * pc.y() / pc.z() + 240);
      features->keys_un[i].pt = i < 5 ? cv::Point2f(5.f, 5.f) : cv::Point2f(u, v);
      features->u_right[i] = i % 2 ? static_cast<float>(u - 40 / pc.z()) : -1.f;
    }
    frame = map::Frame(7, 1.0, features);
    for (int i = 0; i < 80; ++i) {
      frame.points[i] = pts[i];
      frame.outlier[i] = i < 5;
    }
  }
};

TEST_F(FrameRefinement, KeepsTheInliersWithTheirKeypoints) {
  const std::vector<FrameObservation> obs = frame_observations(frame);
  ASSERT_EQ(obs.size(), 75u);
  EXPECT_EQ(obs[0].point, pts[5]);
  EXPECT_FLOAT_EQ(static_cast<float>(obs[0].obs.uv.x()), frame.f().keys_un[5].pt.x);
  EXPECT_FLOAT_EQ(static_cast<float>(obs[0].obs.u_right), frame.f().u_right[5]);
  EXPECT_TRUE(obs[0].obs.stereo());
  EXPECT_FALSE(obs[1].obs.stereo());
  EXPECT_DOUBLE_EQ(obs[0].obs.inv_sigma2, 1.0);  // level 0
  // Unmatched keypoints are left out too.
  frame.points[10].reset();
  EXPECT_EQ(frame_observations(frame).size(), 74u);
}

TEST_F(FrameRefinement, FindsThePoseTheRefinedPointsGive) {
  // Tracking's pose was pulled 4 cm and 1 degree off; the points are right now.
  const Eigen::Isometry3d off = pose(1.0, {0.04, 0.0, -0.02}) * T_cw;
  std::vector<optimize::PoseObservation> obs;
  {
    std::lock_guard<std::mutex> lk(map.mutex());
    obs = current_observations(frame_observations(frame));
  }
  ASSERT_EQ(obs.size(), 75u);
  const auto refined = refine_pose(K, off, obs, 30);
  ASSERT_TRUE(refined.has_value());
  EXPECT_GT(translation_error(off, T_cw), 0.03);
  EXPECT_LT(translation_error(*refined, T_cw), 1e-4);
}

TEST_F(FrameRefinement, OnlyPointsStillInTheMapCountAtTheirNewPositions) {
  const std::vector<FrameObservation> kept = frame_observations(frame);
  // Local BA moved one point; culling erased 50 others after the frame was tracked.
  const Eigen::Vector3d moved(0.1, 0.2, 5.0);
  for (int i = 5; i < 55; ++i) map.erase_point(pts[i]);
  std::vector<optimize::PoseObservation> obs;
  {
    std::lock_guard<std::mutex> lk(map.mutex());
    pts[60]->set_position(moved);
    obs = current_observations(kept);
  }
  ASSERT_EQ(obs.size(), 25u);
  bool found = false;
  for (const optimize::PoseObservation& o : obs) found = found || o.point_world.isApprox(moved);
  EXPECT_TRUE(found);
  // A point fused into another since counts as that one.
  auto keep = std::make_shared<MapPoint>(map.new_point_id(), Eigen::Vector3d(1, 2, 9), kf.get(), 0);
  map.add_point(keep);
  map.replace_point(pts[61], keep);
  ASSERT_TRUE(pts[61]->erased());
  {
    std::lock_guard<std::mutex> lk(map.mutex());
    obs = current_observations(kept);
  }
  ASSERT_EQ(obs.size(), 25u);
  found = false;
  for (const optimize::PoseObservation& o : obs) found = found || o.point_world.isApprox(keep->position());
  EXPECT_TRUE(found);
  // Too few points left for the frame's minimum: tracking's pose stays.
  EXPECT_FALSE(refine_pose(K, T_cw, obs, 30).has_value());
  EXPECT_TRUE(refine_pose(K, T_cw, obs, 20).has_value());
  EXPECT_FALSE(refine_pose(K, T_cw, {}, 1).has_value());
}

TEST_F(FrameRefinement, AWrongPointIsRejectedNotFollowed) {
  // A point matched on the wrong stereo feature: at a tenth of its depth.
  std::vector<optimize::PoseObservation> obs;
  {
    std::lock_guard<std::mutex> lk(map.mutex());
    obs = current_observations(frame_observations(frame));
  }
  const Eigen::Vector3d c = T_cw.inverse().translation();
  obs[3].point_world = c + 0.1 * (obs[3].point_world - c);
  obs[3].point_world.x() += 0.05;
  const auto refined = refine_pose(K, T_cw, obs, 30);
  ASSERT_TRUE(refined.has_value());
  EXPECT_LT(translation_error(*refined, T_cw), 1e-3);
}

}  // namespace
}  // namespace dynaorb::tracking
