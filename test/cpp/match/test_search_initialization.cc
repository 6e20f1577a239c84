// Matcher::search_for_initialization (ORB-SLAM2's SearchForInitialization) on
// real consecutive images (EuRoC MH_05 cam0, EuRoC_mono.yaml settings, twice
// the features as during monocular initialisation): enough one-to-one,
// level-0 matches within the window and the descriptor threshold, consistent
// with the epipolar geometry, and the window positions follow the matches.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <string>
#include <vector>

#include "../test_util.h"
#include "dynaorb/match/hamming.h"
#include "dynaorb/match/matcher.h"
#include "dynaorb/tracking/frame_builder.h"

namespace dynaorb {
namespace {

using test::shared_data;

struct Sequence {
  std::vector<std::shared_ptr<const map::Features>> frames;
};

// Features of the first n images of MH_05_difficult_head (empty when the data is missing).
Sequence load(int n) {
  Sequence s;
  const auto dir = shared_data() / "euroc/MH_05_difficult_head/mav0/cam0/data";
  if (!test::fs::is_directory(dir)) return s;
  std::vector<std::string> files;
  for (const auto& e : test::fs::directory_iterator(dir)) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  const Settings settings = Settings::load(std::string(DYNAORB_SOURCE_DIR) + "/config/EuRoC_mono.yaml");
  const auto calib = map::Calibration::make(settings, Sensor::kMono, 752, 480);
  tracking::FrameBuilder builder(settings, calib);
  for (int i = 0; i < n && i < static_cast<int>(files.size()); ++i) {
    const cv::Mat img = cv::imread(files[i], cv::IMREAD_GRAYSCALE);
    tracking::StageTimes t;
    s.frames.push_back(builder.mono(img, cv::Mat(), t, /*initializing=*/true));
  }
  return s;
}

const Sequence& sequence() {
  static const Sequence s = load(6);
  return s;
}

TEST(SearchForInitialization, ConsecutiveImagesGiveConsistentLevelZeroMatches) {
  DYNAORB_REQUIRE_SHARED();
  const Sequence& s = sequence();
  ASSERT_GE(s.frames.size(), 2u);
  const map::Features& f1 = *s.frames[0];
  const map::Features& f2 = *s.frames[1];
  const match::Matcher matcher;
  std::vector<Eigen::Vector2d> prev;
  std::vector<int> m12;
  const int n = matcher.search_for_initialization(f1, f2, prev, m12, 100.0, 0.9);
  ASSERT_EQ(static_cast<int>(m12.size()), f1.size());
  ASSERT_EQ(static_cast<int>(prev.size()), f1.size());
  EXPECT_GE(n, 100) << "ORB-SLAM2 needs 100 matches to attempt an initialisation";
  std::set<int> used;
  std::vector<cv::Point2f> p1, p2;
  for (int i = 0; i < f1.size(); ++i) {
    const int j = m12[i];
    if (j < 0) {
      // Unmatched keypoints keep their own position as the window centre.
      EXPECT_NEAR(prev[i].x(), f1.keys_un[i].pt.x, 1e-4);
      continue;
    }
    EXPECT_TRUE(used.insert(j).second) << "keypoint " << j << " matched twice";
    EXPECT_EQ(f1.keys_un[i].octave, 0);
    EXPECT_EQ(f2.keys_un[j].octave, 0);
    EXPECT_LE(match::hamming(f1.descriptor(i), f2.descriptor(j)), 50);
    EXPECT_LT(std::abs(f1.keys_un[i].pt.x - f2.keys_un[j].pt.x), 100.0f);
    EXPECT_LT(std::abs(f1.keys_un[i].pt.y - f2.keys_un[j].pt.y), 100.0f);
    EXPECT_NEAR(prev[i].x(), f2.keys_un[j].pt.x, 1e-4);
    EXPECT_NEAR(prev[i].y(), f2.keys_un[j].pt.y, 1e-4);
    p1.push_back(f1.keys_un[i].pt);
    p2.push_back(f2.keys_un[j].pt);
  }
  EXPECT_EQ(static_cast<int>(used.size()), n);
  // Consecutive frames at 20 Hz: the matches agree with one epipolar geometry.
  std::vector<uchar> inliers;
  cv::findFundamentalMat(p1, p2, cv::FM_RANSAC, 1.0, 0.999, inliers);
  const int n_in = cv::countNonZero(inliers);
  EXPECT_GE(n_in, 0.8 * n) << n_in << " of " << n << " matches fit a fundamental matrix";
}

TEST(SearchForInitialization, WindowFollowsTheMatchesOverFrames) {
  DYNAORB_REQUIRE_SHARED();
  const Sequence& s = sequence();
  ASSERT_GE(s.frames.size(), 6u);
  const match::Matcher matcher;
  std::vector<Eigen::Vector2d> prev;
  std::vector<int> m12;
  int n = 0;
  // As during initialisation: the same reference against each later frame.
  for (size_t k = 1; k < s.frames.size(); ++k)
    n = matcher.search_for_initialization(*s.frames[0], *s.frames[k], prev, m12, 100.0, 0.9);
  // Measured: 171 matches to the fifth frame (206 to the first).
  EXPECT_GE(n, 130) << "reference still matched after 5 frames";
  // A frame against itself: every level-0 keypoint finds itself (or an identical twin).
  std::vector<Eigen::Vector2d> self_prev;
  const map::Features& f = *s.frames[0];
  const int self = matcher.search_for_initialization(f, f, self_prev, m12, 100.0, 0.9);
  int level0 = 0, identity = 0;
  for (int i = 0; i < f.size(); ++i) {
    if (f.keys_un[i].octave != 0) continue;
    ++level0;
    if (m12[i] == i) ++identity;
  }
  EXPECT_GE(identity, 0.95 * level0);
  EXPECT_LE(self, level0);
}

}  // namespace
}  // namespace dynaorb
