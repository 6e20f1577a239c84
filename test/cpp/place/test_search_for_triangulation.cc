// Matcher::search_for_triangulation (ORB-SLAM's SearchForTriangulation) on
// real KITTI 06 stereo keyframes at their ground-truth poses, without map
// points (every keypoint unmatched, as local mapping sees the new ones):
// with bags of words only keypoints under the same vocabulary node are
// compared. The pairs lie on their epipolar lines, agree with the stereo
// depth of the first keyframe as often as the exhaustive search's do, and
// are found with a small share of its descriptor comparisons.
#include <gtest/gtest.h>

#include <chrono>
#include <map>

#include "dynaorb/match/matcher.h"
#include "place_test_util.h"

namespace dynaorb::place {
namespace {

using map::KeyFrame;
using test::place_data;

// A keyframe of frame i at its ground-truth pose, with or without a bag of words.
std::shared_ptr<KeyFrame> bare_keyframe(int i, bool bow) {
  const test::PlaceData& d = place_data();
  auto kf = std::make_shared<KeyFrame>(i, i, i, d.frames[i], d.ground_truth[i].pose.inverse());
  if (bow) kf->set_bow(map::BagOfWords::compute(*d.vocabulary, kf->f()));
  return kf;
}

struct Scored {
  int pairs = 0, with_depth = 0, agree = 0;
  double ms = 0;
};

// Pairs whose first keypoint has a close stereo depth: agree when that 3-D
// point projects within kAgreePx of the second keypoint. Right pairs land
// 1-8 px off (stereo depth over 2.4 m of motion, the ground-truth poses);
// wrong ones, anywhere along the epipolar band.
constexpr double kAgreePx = 10.0;

Scored score(const KeyFrame& kf1, const KeyFrame& kf2, bool bow) {
  const match::Matcher matcher;
  const auto t0 = std::chrono::steady_clock::now();
  const auto pairs = matcher.search_for_triangulation(kf1, kf2, match::Matcher::fundamental(kf1, kf2));
  Scored s;
  s.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  s.pairs = static_cast<int>(pairs.size());
  std::map<int, int> seen2;
  for (const auto& [i1, i2] : pairs) {
    EXPECT_EQ(seen2[i2]++, 0) << "keypoint " << i2 << " of the second keyframe matched twice";
    if (!kf1.f().is_close(i1)) continue;
    ++s.with_depth;
    const Eigen::Vector2d uv = kf2.calib().project(kf2.T_cw() * kf1.unproject(i1));
    const cv::KeyPoint& k2 = kf2.f().keys_un[i2];
    if ((uv - Eigen::Vector2d(k2.pt.x, k2.pt.y)).norm() <= kAgreePx) ++s.agree;
  }
  std::printf("[ measured ] %s: %d pairs in %.1f ms, %d with a close depth in the first keyframe, %d of them "
              "agree with it\n", bow ? "bag of words" : "exhaustive", s.pairs, s.ms, s.with_depth, s.agree);
  return s;
}

TEST(SearchForTriangulation, BagOfWordsPairsAreAsRightAsTheExhaustiveOnes) {
  REQUIRE_PLACE_DATA();
  // Frames 0 and 2: about 2.4 m apart along the road.
  const auto a1 = bare_keyframe(0, true), a2 = bare_keyframe(2, true);
  const auto b1 = bare_keyframe(0, false), b2 = bare_keyframe(2, false);
  const Scored bow = score(*a1, *a2, true);
  const Scored all = score(*b1, *b2, false);
  ASSERT_GT(bow.with_depth, 30);
  ASSERT_GT(all.with_depth, 30);
  const double bow_ratio = double(bow.agree) / bow.with_depth, all_ratio = double(all.agree) / all.with_depth;
  EXPECT_GE(bow_ratio, 0.9);
  EXPECT_GE(bow_ratio, all_ratio - 0.05);
  // A vocabulary node hides some pairs, not most.
  EXPECT_GE(bow.pairs, all.pairs / 3);
  EXPECT_LE(bow.pairs, all.pairs);
}

TEST(SearchForTriangulation, KeypointsWithMapPointsAreLeftOut) {
  REQUIRE_PLACE_DATA();
  map::Map map;
  std::lock_guard<std::mutex> lk(map.mutex());
  // make_keyframe gives every keypoint with stereo depth a map point.
  const auto kf1 = test::make_keyframe(map, 0);
  const auto kf2 = test::make_keyframe(map, 2);
  const match::Matcher matcher;
  const auto pairs = matcher.search_for_triangulation(*kf1, *kf2, match::Matcher::fundamental(*kf1, *kf2));
  for (const auto& [i1, i2] : pairs) {
    EXPECT_FALSE(kf1->point(i1)) << i1;
    EXPECT_FALSE(kf2->point(i2)) << i2;
  }
}

}  // namespace
}  // namespace dynaorb::place
