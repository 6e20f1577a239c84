// Keyframe database: the inverse index and ORB-SLAM's relocalisation
// candidates on real KITTI 06 keyframes (own bag of words, a nearby frame,
// culled keyframes, a cleared map) and on hand-made bags of words for the
// covisibility grouping.
#include <gtest/gtest.h>

#include <algorithm>

#include "dynaorb/place/keyframe_database.h"
#include "place_test_util.h"

namespace dynaorb::place {
namespace {

using map::KeyFrame;
using test::make_frame;
using test::make_keyframe;
using test::place_data;

std::vector<long> ids(const std::vector<PlaceCandidate>& c) {
  std::vector<long> out;
  for (const auto& x : c) out.push_back(x.keyframe->id);
  return out;
}

bool contains(const std::vector<PlaceCandidate>& c, const KeyFrame* kf) {
  return std::any_of(c.begin(), c.end(), [&](const PlaceCandidate& x) { return x.keyframe == kf; });
}

struct Kitti : ::testing::Test {
  map::Map map;
  std::unique_ptr<KeyFrameDatabase> db;
  std::vector<std::shared_ptr<KeyFrame>> kfs;  // frames 0, 3, 6, 9

  void SetUp() override {
    REQUIRE_PLACE_DATA();
    db = std::make_unique<KeyFrameDatabase>(map, place_data().vocabulary);
    std::lock_guard<std::mutex> lk(map.mutex());
    for (int i = 0; i < test::PlaceData::kFrames; i += 3) {
      kfs.push_back(make_keyframe(map, i));
      db->add(*kfs.back());
    }
  }
};

TEST_F(Kitti, AKeyframesOwnBagOfWordsFindsItFirst) {
  std::lock_guard<std::mutex> lk(map.mutex());
  EXPECT_EQ(db->size(), kfs.size());
  for (const auto& kf : kfs) {
    const auto c = db->relocalization_candidates(kf->bow()->words);
    ASSERT_FALSE(c.empty());
    EXPECT_EQ(c.front().keyframe, kf.get()) << "candidates " << ::testing::PrintToString(ids(c));
    EXPECT_NEAR(c.front().score, 1.0, 1e-9);
  }
}

TEST_F(Kitti, AFrameBetweenKeyframesFindsTheNearestOnes) {
  // Frame 7 (~1 m/frame): keyframe 6 is one frame behind, 9 two ahead.
  const map::Frame f = make_frame(7);
  std::lock_guard<std::mutex> lk(map.mutex());
  const auto c = db->relocalization_candidates(f.bow->words);
  ASSERT_FALSE(c.empty());
  EXPECT_EQ(c.front().keyframe, kfs[2].get()) << ::testing::PrintToString(ids(c));
  EXPECT_FALSE(contains(c, kfs[0].get()));  // 7 frames away
}

TEST_F(Kitti, CulledKeyframesLeaveTheIndexAndAClearedMapEmptiesIt) {
  std::lock_guard<std::mutex> lk(map.mutex());
  const auto bow6 = kfs[2]->bow();
  map.erase_keyframe(kfs[2]);  // what keyframe culling does
  EXPECT_EQ(db->size(), kfs.size() - 1);
  auto c = db->relocalization_candidates(bow6->words);
  EXPECT_FALSE(contains(c, kfs[2].get()));
  ASSERT_FALSE(c.empty());  // its neighbours still look alike
  db->erase(*kfs[2]);       // twice: no effect
  EXPECT_EQ(db->size(), kfs.size() - 1);
  map.clear();
  EXPECT_EQ(db->size(), 0u);
  EXPECT_TRUE(db->relocalization_candidates(bow6->words).empty());
}

TEST_F(Kitti, AddingIsIdempotentAndNeedsABagOfWords) {
  std::lock_guard<std::mutex> lk(map.mutex());
  db->add(*kfs[0]);
  EXPECT_EQ(db->size(), kfs.size());
  KeyFrame bare(99, 99, 99, place_data().frames[0], Eigen::Isometry3d::Identity());
  EXPECT_THROW(db->add(bare), std::invalid_argument);
}

TEST(KeyFrameDatabase, DetachesFromTheMapWhenDestroyed) {
  REQUIRE_PLACE_DATA();
  map::Map map;
  std::shared_ptr<KeyFrame> kf;
  {
    KeyFrameDatabase db(map, place_data().vocabulary);
    std::lock_guard<std::mutex> lk(map.mutex());
    kf = make_keyframe(map, 0);
    make_keyframe(map, 1);
    db.add(*kf);
  }
  std::lock_guard<std::mutex> lk(map.mutex());
  map.erase_keyframe(map.keyframe(1));  // no observer left to call
  map.clear();
  SUCCEED();
}

TEST(KeyFrameDatabase, RefusesAMissingVocabulary) {
  map::Map map;
  EXPECT_THROW(KeyFrameDatabase(map, nullptr), std::invalid_argument);
  EXPECT_THROW(KeyFrameDatabase(map, std::make_shared<const vocab::Vocabulary>()), std::invalid_argument);
}

// ORB-SLAM's grouping on hand-made bags of words. Query: words 1-4 at 0.25.
// L1 score = sum of the smaller weights over shared words.
//   A: 0.6, B: 0.5, A and B covisible; C: 0.7 alone; D shares one word only.
// Groups: A+B = 1.1 (best A), C = 0.7 < 0.75 * 1.1: only A is a candidate
// although C scores best on its own; D shares too few words to be scored.
TEST(KeyFrameDatabase, GroupsAccumulateOverCovisiblesAndKeepTheirBest) {
  REQUIRE_PLACE_DATA();
  map::Map map;
  KeyFrameDatabase db(map, place_data().vocabulary);
  std::lock_guard<std::mutex> lk(map.mutex());
  auto make = [&](vocab::BowVector words) {
    auto kf = std::make_shared<KeyFrame>(map.new_keyframe_id(), 0, 0, place_data().frames[0],
                                         Eigen::Isometry3d::Identity());
    kf->set_bow(std::make_shared<const map::BagOfWords>(std::move(words), vocab::FeatureVector{}));
    map.add_keyframe(kf);
    db.add(*kf);
    return kf;
  };
  auto a = make({{1, .25}, {2, .25}, {3, .1}, {10, .4}});
  auto b = make({{1, .25}, {2, .2}, {3, .05}, {11, .5}});
  auto c = make({{1, .25}, {2, .25}, {3, .2}, {12, .3}});
  auto d = make({{1, .9}, {13, .1}});
  // A and B share 20 points: a covisibility edge.
  for (int i = 0; i < 20; ++i) {
    auto p = std::make_shared<map::MapPoint>(map.new_point_id(), Eigen::Vector3d(0, 0, 5), a.get(), a->id);
    map.add_point(p);
    map.add_observation(*a, i, p);
    map.add_observation(*b, i, p);
  }
  a->update_connections();
  b->update_connections();
  ASSERT_EQ(a->weight(b.get()), 20);

  const vocab::BowVector query{{1, .25}, {2, .25}, {3, .25}, {4, .25}};
  const auto cand = db.relocalization_candidates(query);
  ASSERT_EQ(cand.size(), 1u) << ::testing::PrintToString(ids(cand));
  EXPECT_EQ(cand[0].keyframe, a.get());
  EXPECT_NEAR(cand[0].score, 0.6, 1e-9);
  EXPECT_NEAR(cand[0].group_score, 1.1, 1e-9);

  // Without B, A's group is 0.6 and C (0.7) leads; A stays (0.6 > 0.525).
  map.erase_keyframe(b);
  const auto after = db.relocalization_candidates(query);
  ASSERT_EQ(after.size(), 2u);
  EXPECT_EQ(after[0].keyframe, c.get());
  EXPECT_EQ(after[1].keyframe, a.get());
  EXPECT_FALSE(contains(after, d.get()));
}

}  // namespace
}  // namespace dynaorb::place
