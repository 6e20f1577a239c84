// Loop candidate detection: the covisibility consistency of ORB-SLAM's DetectLoop
// (ConsistentGroups) on hand-made groups, and KeyFrameDatabase::loop_candidates on real
// KITTI 06 keyframes (the query and its covisible keyframes are never candidates; the score bar).
#include <gtest/gtest.h>

#include <algorithm>

#include "../place/place_test_util.h"
#include "dynaorb/loop/loop_closer.h"
#include "dynaorb/place/keyframe_database.h"

namespace dynaorb::loop {
namespace {

using Group = ConsistentGroups::Group;

TEST(ConsistentGroups, ACandidateIsConsistentAfterThreeConsecutiveOverlappingGroups) {
  ConsistentGroups g;
  EXPECT_TRUE(g.update({{6, {5, 6, 7}}}, 3).empty());   // new group, consistency 0
  EXPECT_TRUE(g.update({{7, {6, 7, 8}}}, 3).empty());   // 1
  EXPECT_TRUE(g.update({{8, {7, 8, 9}}}, 3).empty());   // 2
  EXPECT_EQ(g.update({{9, {8, 9, 10}}}, 3), std::vector<long>{9});  // 3
  ASSERT_EQ(g.groups().size(), 1u);
  EXPECT_EQ(g.groups()[0].second, 3);
}

TEST(ConsistentGroups, ADisjointGroupOrAnEmptyKeyframeStartsAgain) {
  ConsistentGroups g;
  g.update({{6, {5, 6}}}, 3);
  g.update({{6, {6, 7}}}, 3);
  g.update({{40, {40, 41}}}, 3);  // disjoint: the chain breaks
  ASSERT_EQ(g.groups().size(), 1u);
  EXPECT_EQ(g.groups()[0].second, 0);
  g.clear();                      // a keyframe without candidates
  EXPECT_TRUE(g.groups().empty());
  EXPECT_TRUE(g.update({{41, {40, 41}}}, 3).empty());
  EXPECT_EQ(g.groups()[0].second, 0);
}

TEST(ConsistentGroups, EachPreviousGroupExtendsOneNewGroupOnly) {
  ConsistentGroups g;
  g.update({{1, {1, 2}}}, 1);
  // Both candidates overlap the one previous group: only the first extends it, but both are
  // consistent enough with threshold 1.
  const std::vector<long> c = g.update({{2, {2, 3}}, {3, {1, 4}}}, 1);
  EXPECT_EQ(c, (std::vector<long>{2, 3}));
  ASSERT_EQ(g.groups().size(), 1u);
  EXPECT_EQ(g.groups()[0].first, (Group{2, 3}));
}

TEST(LoopCandidates, NeitherTheQueryNorItsCovisiblesAndOnlyAboveTheBar) {
  REQUIRE_PLACE_DATA();
  map::Map map;
  place::KeyFrameDatabase db(map, test::place_data().vocabulary);
  std::lock_guard<std::mutex> lk(map.mutex());
  std::vector<std::shared_ptr<map::KeyFrame>> kfs;
  for (int i = 0; i < test::PlaceData::kFrames; i += 2) {
    kfs.push_back(test::make_keyframe(map, i));
    db.add(*kfs.back());
  }
  auto& query = kfs[3];  // frame 6
  auto ids = [](const std::vector<place::PlaceCandidate>& c) {
    std::vector<long> out;
    for (const auto& x : c) out.push_back(x.keyframe->id);
    return out;
  };
  auto c = db.loop_candidates(*query, 0.0);
  ASSERT_FALSE(c.empty());
  for (const auto& x : c) EXPECT_NE(x.keyframe, query.get());
  const long best = c.front().keyframe->id;
  EXPECT_TRUE(best == kfs[2]->id || best == kfs[4]->id) << ::testing::PrintToString(ids(c));

  // Make the best candidate covisible with the query (20 shared points): it is excluded.
  map::KeyFrame* other = c.front().keyframe;
  int shared = 0;
  for (int k = 0; k < query->f().size() && shared < 20; ++k) {
    if (query->point(k)) continue;
    for (int j = shared * 7; j < other->f().size(); ++j) {
      if (!other->point(j)) continue;
      map.add_observation(*query, k, other->point(j));
      ++shared;
      break;
    }
  }
  ASSERT_EQ(shared, 20);
  query->update_connections();
  ASSERT_GE(query->weight(other), 15);
  c = db.loop_candidates(*query, 0.0);
  for (const auto& x : c) EXPECT_NE(x.keyframe, other);
  // Nothing scores above a bar of 1.
  EXPECT_TRUE(db.loop_candidates(*query, 1.0 + 1e-9).empty());
}

}  // namespace
}  // namespace dynaorb::loop
