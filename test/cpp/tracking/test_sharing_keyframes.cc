// The local map's first ring: the keyframes observing the frame's tracked
// points, and its cap (TrackerOptions::max_sharing_keyframes).
#include <gtest/gtest.h>

#include "dynaorb/map/map.h"
#include "dynaorb/tracking/sharing_keyframes.h"
#include "../map/map_test_util.h"

namespace dynaorb::tracking {
namespace {

using map::KeyFrame;
using map::MapPoint;

// Keyframe k (0..5) observes the frame's points 0 .. 10 * (k + 1) - 1, so
// keyframe 5 shares the most (60) and keyframe 0 the fewest (10); keyframe
// 6 observes the points 0..9 too, a tie with keyframe 0.
struct SharingKeyframes : ::testing::Test {
  map::Map map;
  std::vector<std::shared_ptr<KeyFrame>> kfs;
  std::vector<std::shared_ptr<MapPoint>> pts;
  map::Frame frame{100, 5.0, test::synthetic_features(80)};

  void SetUp() override {
    for (int k = 0; k < 7; ++k) {
      kfs.push_back(std::make_shared<KeyFrame>(map.new_keyframe_id(), k, k, test::synthetic_features(80),
                                               Eigen::Isometry3d::Identity()));
      map.add_keyframe(kfs.back());
    }
    for (int i = 0; i < 70; ++i) {
      auto p = std::make_shared<MapPoint>(map.new_point_id(), Eigen::Vector3d(0, 0, 5), kfs[0].get(), 0);
      map.add_point(p);
      pts.push_back(p);
      for (int k = 0; k < 6; ++k)
        if (i < 10 * (k + 1)) map.add_observation(*kfs[k], i, p);
      if (i < 10) map.add_observation(*kfs[6], i, p);
      frame.points[i] = p;
    }
  }

  static std::vector<std::pair<long, int>> ids(const std::vector<std::pair<KeyFrame*, int>>& ring) {
    std::vector<std::pair<long, int>> out;
    for (const auto& [k, n] : ring) out.emplace_back(k->id, n);
    return out;
  }
};

TEST_F(SharingKeyframes, AllByIdWithTheirSharedCounts) {
  const std::vector<std::pair<long, int>> all = {{kfs[0]->id, 10}, {kfs[1]->id, 20}, {kfs[2]->id, 30}, {kfs[3]->id, 40},
                                                 {kfs[4]->id, 50}, {kfs[5]->id, 60}, {kfs[6]->id, 10}};
  EXPECT_EQ(ids(sharing_keyframes(frame, 0)), all);
  EXPECT_EQ(ids(sharing_keyframes(frame, 7)), all);  // no more than the cap: all
}

TEST_F(SharingKeyframes, TheCapKeepsThoseSharingTheMostStillById) {
  EXPECT_EQ(ids(sharing_keyframes(frame, 3)),
            (std::vector<std::pair<long, int>>{{kfs[3]->id, 40}, {kfs[4]->id, 50}, {kfs[5]->id, 60}}));
  // A tie at the cut (keyframes 0 and 6 share 10 points each): the lower id stays.
  const auto six = ids(sharing_keyframes(frame, 6));
  ASSERT_EQ(six.size(), 6u);
  EXPECT_EQ(six.front(), std::make_pair(kfs[0]->id, 10));
  EXPECT_EQ(six.back(), std::make_pair(kfs[5]->id, 60));
}

TEST_F(SharingKeyframes, OutliersUnmatchedAndErasedPointsDoNotCount) {
  for (int i = 0; i < 10; ++i) frame.outlier[i] = true;  // the only points keyframes 0 and 6 observe
  frame.points[10].reset();                               // unmatched
  map.erase_point(pts[11]);                               // erased
  const auto ring = ids(sharing_keyframes(frame, 0));
  ASSERT_EQ(ring.size(), 5u);
  EXPECT_EQ(ring.front(), std::make_pair(kfs[1]->id, 8));
  EXPECT_EQ(ring.back(), std::make_pair(kfs[5]->id, 48));  // 60 less the ten outliers and points 10, 11
}

TEST_F(SharingKeyframes, AFrameWithoutTrackedPointsHasNone) {
  for (auto& p : frame.points) p.reset();
  EXPECT_TRUE(sharing_keyframes(frame, 80).empty());
}

}  // namespace
}  // namespace dynaorb::tracking
