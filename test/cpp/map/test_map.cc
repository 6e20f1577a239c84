// Map bookkeeping: observations, covisibility weights, spanning tree,
// point replacement and keyframe erasure.
#include <gtest/gtest.h>

#include "dynaorb/map/map.h"
#include "map_test_util.h"

namespace dynaorb::map {
namespace {

struct Fixture : ::testing::Test {
  Map map;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::vector<std::shared_ptr<MapPoint>> pts;

  // kf0..kf3; points 0..39 seen by kf0,kf1; 20..59 by kf1,kf2; 40..79 by kf2,kf3 (and kf1 for 40..59).
  void SetUp() override {
    for (int k = 0; k < 4; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = Eigen::Vector3d(-0.1 * k, 0, 0);
      kfs.push_back(std::make_shared<KeyFrame>(map.new_keyframe_id(), k, k, test::synthetic_features(100), T));
      map.add_keyframe(kfs.back());
    }
    for (int i = 0; i < 80; ++i) {
      auto p = std::make_shared<MapPoint>(map.new_point_id(), Eigen::Vector3d(0, 0, 5), kfs[0].get(), 0);
      map.add_point(p);
      pts.push_back(p);
      for (int k = 0; k < 4; ++k) {
        const bool sees = (k == 0 && i < 40) || (k == 1 && i >= 0 && i < 60) || (k == 2 && i >= 20) ||
                          (k == 3 && i >= 40);
        if (sees) map.add_observation(*kfs[k], i, p);
      }
    }
    for (auto& kf : kfs) kf->update_connections();
  }
};

TEST_F(Fixture, CovisibilityWeightsCountSharedPoints) {
  EXPECT_EQ(kfs[0]->weight(kfs[1].get()), 40);
  EXPECT_EQ(kfs[1]->weight(kfs[2].get()), 40);
  EXPECT_EQ(kfs[2]->weight(kfs[3].get()), 40);
  EXPECT_EQ(kfs[1]->weight(kfs[3].get()), 20);
  EXPECT_EQ(kfs[0]->weight(kfs[3].get()), 0);  // nothing shared
  const auto cov = kfs[1]->covisibles();
  ASSERT_EQ(cov.size(), 3u);
  EXPECT_EQ(cov.back(), kfs[3].get());  // lightest last
  EXPECT_EQ(kfs[1]->parent(), kfs[0].get());
}

TEST_F(Fixture, ErasingObservationsDropsPointsSeenTwiceOrLess) {
  map.erase_observation(*kfs[0], 0);  // point 0 is left with one observation: erased
  EXPECT_TRUE(pts[0]->erased());
  EXPECT_EQ(kfs[1]->point(0), nullptr);
  EXPECT_EQ(map.point_count(), 79u);
}

TEST_F(Fixture, ReplacePointMovesObservations) {
  map.replace_point(pts[0], pts[70]);  // 0: kf0, kf1; 70: kf2, kf3
  EXPECT_TRUE(pts[0]->erased());
  EXPECT_EQ(pts[0]->replaced_by(), pts[70]);
  EXPECT_EQ(pts[70]->observations().size(), 4u);
  EXPECT_EQ(kfs[0]->point(0), pts[70]);
  // A keyframe that already sees the kept point loses the duplicate slot.
  map.replace_point(pts[60], pts[70]);  // 60: kf2, kf3 already see 70
  EXPECT_EQ(kfs[2]->point(60), nullptr);
  EXPECT_EQ(pts[70]->observations().size(), 4u);
}

TEST_F(Fixture, ErasedKeyframeKeepsItsPoseThroughTheParent) {
  kfs[3]->update_connections();
  kfs[2]->update_connections();
  ASSERT_EQ(kfs[2]->parent(), kfs[1].get());
  const Eigen::Isometry3d before = kfs[2]->T_cw();
  map.erase_keyframe(kfs[2]);
  EXPECT_TRUE(kfs[2]->erased());
  EXPECT_EQ(map.keyframe_count(), 3u);
  EXPECT_EQ(kfs[3]->parent(), kfs[1].get());  // re-linked to a remaining keyframe
  EXPECT_EQ(kfs[1]->weight(kfs[2].get()), 0);
  // Moving the parent moves the erased keyframe's pose with it.
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0, 0.5, 0);
  kfs[1]->set_pose(kfs[1]->T_cw() * shift);
  const Eigen::Isometry3d after = kfs[2]->current_T_cw();
  EXPECT_NEAR((after.translation() - (before * shift).translation()).norm(), 0.0, 1e-12);
  // The first keyframe anchors the map and is never erased.
  map.erase_keyframe(kfs[0]);
  EXPECT_FALSE(kfs[0]->erased());
}

TEST(Features, GridSearchFindsExactlyThePointsInTheWindow) {
  auto f = test::synthetic_features(300);
  const auto found = f->in_area(320, 240, 50);
  int expected = 0;
  for (int i = 0; i < f->size(); ++i)
    if (std::abs(f->keys_un[i].pt.x - 320) < 50 && std::abs(f->keys_un[i].pt.y - 240) < 50) ++expected;
  EXPECT_EQ(static_cast<int>(found.size()), expected);
  EXPECT_GT(expected, 0);
}

}  // namespace
}  // namespace dynaorb::map
