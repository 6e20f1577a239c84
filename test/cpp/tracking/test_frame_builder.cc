// FrameBuilder::stereo with an exclusion mask on KITTI 06 (frame 0): the
// right image's budget follows the mask (TrackerOptions::
// stereo_right_budget_max_factor), so the share of left keypoints with a
// right match stays near the unmasked frame's; without a mask nothing changes.
// A mask computed beside the detection gives the same features.
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <opencv2/core.hpp>

#include "../test_util.h"
#include "dynaorb/io/dataset.h"
#include "dynaorb/map/calibration.h"
#include "dynaorb/tracking/frame_builder.h"

namespace dynaorb {
namespace {

struct Built {
  int keypoints = 0, with_depth = 0;
};

Built build(const Settings& settings, const dynaorb::Frame& f, const cv::Mat& exclude, double max_factor) {
  tracking::FrameBuilder builder(
      settings, map::Calibration::make(settings, Sensor::kStereo, f.image.cols, f.image.rows), 2, max_factor);
  tracking::StageTimes t;
  const auto features = builder.stereo(f.image, f.right, exclude, t);
  Built b;
  b.keypoints = features->size();
  for (int i = 0; i < features->size(); ++i) b.with_depth += features->has_depth(i);
  return b;
}

// KITTI 06 frame 0, its settings, and a mask over columns 300-759.
struct Kitti06 {
  Settings settings;
  dynaorb::Frame frame;
  cv::Mat exclude;
  Kitti06() {
    auto provider = open_dataset("kitti", (test::shared_data() / "kitti/sequences/06").string());
    settings = provider->default_settings();
    frame = provider->load(0);
    exclude = cv::Mat::zeros(frame.image.size(), CV_8UC1);
    exclude(cv::Rect(300, 0, 460, frame.image.rows)).setTo(255);
  }
};

double share(const Built& b) { return static_cast<double>(b.with_depth) / b.keypoints; }

// Measured (2000 features; mask over columns 300-759, 37.5 % of the image):
// no mask, 811 of 2008 left keypoints matched (0.40); masked, right budget
// fixed at 2000, 685 of 2004 (0.34); masked, right budget 2000 / (1 - m) =
// 3200, 916 of 2004 (0.46).
TEST(FrameBuilder, RightBudgetFollowsTheExclusionMask) {
  DYNAORB_REQUIRE_SHARED();
  const Kitti06 k;
  const Settings& settings = k.settings;
  const dynaorb::Frame& f = k.frame;
  const cv::Mat& exclude = k.exclude;

  const Built plain = build(settings, f, cv::Mat(), 2.0), plain_fixed = build(settings, f, cv::Mat(), 1.0);
  const Built fixed = build(settings, f, exclude, 1.0), follows = build(settings, f, exclude, 2.0);
  std::printf("no mask %d / %d; mask, fixed right budget %d / %d; following %d / %d\n", plain.with_depth,
              plain.keypoints, fixed.with_depth, fixed.keypoints, follows.with_depth, follows.keypoints);
  // Without a mask the budget is nFeatures whatever the factor.
  EXPECT_EQ(plain.with_depth, plain_fixed.with_depth);
  EXPECT_EQ(plain.keypoints, plain_fixed.keypoints);
  // The left image is extracted the same way in both masked runs.
  EXPECT_EQ(fixed.keypoints, follows.keypoints);
  EXPECT_GT(share(follows), share(fixed) + 0.03);
  EXPECT_GT(share(follows), share(plain) - 0.05);
}

// The exclusion mask computed beside the detection (ExclusionSource, as the
// System does with the dynamic filter) gives the features of the same mask
// given up front, for stereo and mono; the source runs on the calling thread.
TEST(FrameBuilder, AMaskComputedBesideTheDetectionGivesTheSameFeatures) {
  DYNAORB_REQUIRE_SHARED();
  const Kitti06 k;
  const Settings& settings = k.settings;
  const dynaorb::Frame& f = k.frame;
  const cv::Mat& exclude = k.exclude;
  const auto calib = map::Calibration::make(settings, Sensor::kStereo, f.image.cols, f.image.rows);
  tracking::FrameBuilder up_front(settings, calib, 2, 2.0), beside(settings, calib, 2, 2.0);
  const auto caller = std::this_thread::get_id();
  std::thread::id source_thread;
  features::ExcludedCount c1, c2;
  c1.region = exclude;
  const tracking::ExclusionSource source = [&] {
    source_thread = std::this_thread::get_id();
    c2.region = exclude;
    return exclude;
  };
  const auto same = [](const map::Features& a, const map::Features& b) {
    ASSERT_EQ(a.size(), b.size());
    for (int i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a.keys[i].pt, b.keys[i].pt);
      EXPECT_EQ(a.keys_un[i].pt, b.keys_un[i].pt);
      EXPECT_EQ(a.u_right[i], b.u_right[i]);
      EXPECT_EQ(a.depth[i], b.depth[i]);
    }
    EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_HAMMING), 0.0);
  };
  tracking::StageTimes t1, t2;
  const auto s1 = up_front.stereo(f.image, f.right, exclude, t1, &c1);
  const auto s2 = beside.stereo(f.image, f.right, source, t2, &c2);
  EXPECT_EQ(source_thread, caller);
  same(*s1, *s2);
  int with_depth = 0;
  for (int i = 0; i < s2->size(); ++i) with_depth += s2->has_depth(i);
  EXPECT_GT(with_depth, 500);
  EXPECT_GT(c1.keypoints, 100);
  EXPECT_EQ(c1.keypoints, c2.keypoints);
  EXPECT_GT(t2.at("extract_overlapped"), 0.0);
  EXPECT_EQ(t2.count("stereo_matching"), 1u);

  source_thread = std::thread::id();
  const auto m1 = up_front.mono(f.image, exclude, t1, false, &c1);
  const auto m2 = beside.mono(f.image, source, t2, false, &c2);
  EXPECT_EQ(source_thread, caller);
  same(*m1, *m2);
  EXPECT_EQ(c1.keypoints, c2.keypoints);
}

// A mask of the wrong type or size is refused with the extractor's message,
// not an OpenCV assertion from the budget.
TEST(FrameBuilder, RefusesABadExclusionMask) {
  DYNAORB_REQUIRE_SHARED();
  auto provider = open_dataset("kitti", (test::shared_data() / "kitti/sequences/06").string());
  const Settings settings = provider->default_settings();
  const dynaorb::Frame f = provider->load(0);
  tracking::FrameBuilder builder(
      settings, map::Calibration::make(settings, Sensor::kStereo, f.image.cols, f.image.rows), 2, 2.0);
  tracking::StageTimes t;
  for (const cv::Mat& bad : {cv::Mat(f.image.size(), CV_8UC3, cv::Scalar::all(255)),
                             cv::Mat(f.image.rows / 2, f.image.cols, CV_8UC1, cv::Scalar(255))}) {
    try {
      builder.stereo(f.image, f.right, bad, t);
      ADD_FAILURE() << "accepted a " << bad.cols << "x" << bad.rows << " mask of type " << bad.type();
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("exclude mask"), std::string::npos) << e.what();
    }
    // The same when the mask comes while both images' levels are detected
    // (the levels shared with the helper thread).
    try {
      builder.stereo(f.image, f.right, tracking::ExclusionSource([&] { return bad; }), t);
      ADD_FAILURE() << "accepted a " << bad.cols << "x" << bad.rows << " mask beside the detection";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("exclude mask"), std::string::npos) << e.what();
    }
  }
  // An image the extractor refuses: its pyramid's error, not a hang of the
  // levels that wait for that pyramid.
  const cv::Mat empty;
  EXPECT_THROW(builder.stereo(f.image, empty, cv::Mat(), t), std::invalid_argument);
  EXPECT_THROW(builder.stereo(f.image, empty, tracking::ExclusionSource([] { return cv::Mat(); }), t),
               std::invalid_argument);
  EXPECT_THROW(builder.stereo(empty, f.right, tracking::ExclusionSource([] { return cv::Mat(); }), t),
               std::invalid_argument);
}

}  // namespace
}  // namespace dynaorb
