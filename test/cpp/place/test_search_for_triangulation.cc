// Matcher::search_for_triangulation (ORB-SLAM's SearchForTriangulation) on
// real KITTI 06 stereo keyframes at their ground-truth poses, without map
// points (every keypoint unmatched, as local mapping sees the new ones):
// with bags of words only keypoints under the same vocabulary node are
// compared. The pairs lie on their epipolar lines, agree with the stereo
// depth of the first keyframe as often as the exhaustive search's do, and
// are found with a small share of its descriptor comparisons. The exhaustive
// search, which narrows the pairs to the epipolar band before comparing
// descriptors, still returns each keypoint's best candidate in that band.
#include <gtest/gtest.h>

#include <chrono>
#include <map>

#include "dynaorb/match/hamming.h"
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

// Each exhaustive pair (i1, i2) is i1's best candidate: no kf2 keypoint that
// passes the same tests (unmatched, within the epipolar distance of its
// octave, not a monocular pair near the epipole) is closer in descriptor
// space. A narrowing that dropped candidates would break this.
TEST(SearchForTriangulation, ExhaustivePairsAreTheBestInTheirEpipolarBand) {
  REQUIRE_PLACE_DATA();
  const auto kf1 = bare_keyframe(0, false), kf2 = bare_keyframe(2, false);
  const match::Matcher matcher;
  const Eigen::Matrix3d F12 = match::Matcher::fundamental(*kf1, *kf2);
  const auto pairs = matcher.search_for_triangulation(*kf1, *kf2, F12, false);
  ASSERT_GT(pairs.size(), 200u);
  const map::Features& f1 = kf1->f();
  const map::Features& f2 = kf2->f();
  const map::ScalePyramid& sp = kf1->calib().scale;
  const Eigen::Vector3d c1_in_2 = kf2->T_cw() * kf1->center();
  const Eigen::Vector2d ep = kf2->calib().project(c1_in_2);
  auto candidate = [&](int i1, int j) {
    const cv::KeyPoint& k1 = f1.keys_un[i1];
    const cv::KeyPoint& k2 = f2.keys_un[j];
    const Eigen::Vector3d line = Eigen::Vector3d(k1.pt.x, k1.pt.y, 1.0).transpose() * F12;
    const double num = line.x() * k2.pt.x + line.y() * k2.pt.y + line.z();
    if (num * num / (line.x() * line.x() + line.y() * line.y()) >= 3.84 * sp.sigma2[k2.octave]) return false;
    if (f1.u_right[i1] < 0 && f2.u_right[j] < 0 && c1_in_2.z() > 0 &&
        (ep - Eigen::Vector2d(k2.pt.x, k2.pt.y)).squaredNorm() < 100 * sp.scale[k2.octave])
      return false;
    return true;
  };
  int checked = 0;
  for (const auto& [i1, i2] : pairs) {
    ASSERT_TRUE(candidate(i1, i2)) << i1 << " -> " << i2;
    const int d = match::hamming(f1.descriptor(i1), f2.descriptor(i2));
    EXPECT_LE(d, match::MatcherOptions{}.th_low);
    for (int j = 0; j < f2.size(); ++j) {
      if (j == i2 || !candidate(i1, j)) continue;
      EXPECT_GE(match::hamming(f1.descriptor(i1), f2.descriptor(j)), d) << i1 << ": " << j << " beats " << i2;
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);  // the band holds other candidates to beat
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
