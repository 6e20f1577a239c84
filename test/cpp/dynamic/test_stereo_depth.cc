// Dense stereo depth (semi-global block matching) and what the System builds
// on it: stereo dense frames with DDL-SLAM's background inpainting, and the
// unchecked movable regions of a frame without a previous one.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/dynamic/stereo_depth.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/system.h"
#include "../test_util.h"

namespace dynaorb::dynamic {
namespace {

cv::Mat grey_texture(int seed, cv::Size size) {
  cv::Mat t(size, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(t, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(t, t, cv::Size(3, 3), 0.8);
  return t;
}

float median_valid(const cv::Mat& depth, const cv::Rect& roi) {
  std::vector<float> v;
  for (int y = roi.y; y < roi.y + roi.height; ++y)
    for (int x = roi.x; x < roi.x + roi.width; ++x)
      if (depth.at<float>(y, x) > 0) v.push_back(depth.at<float>(y, x));
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

TEST(StereoDepth, RecoversAKnownDisparity) {
  // A textured plane seen with a constant disparity of 20 px: depth = bf / 20.
  const cv::Mat right = grey_texture(3, cv::Size(240, 120));
  cv::Mat left = cv::Mat::zeros(right.size(), CV_8UC1);
  right(cv::Rect(0, 0, 220, 120)).copyTo(left(cv::Rect(20, 0, 220, 120)));  // x_left = x_right + 20
  StereoDepthOptions o;
  o.num_disparities = 64;
  const double bf = 40.0;
  const cv::Mat depth = stereo_depth(left, right, bf, o);
  ASSERT_EQ(depth.type(), CV_32FC1);
  const cv::Rect roi(90, 10, 140, 100);
  EXPECT_GT(cv::countNonZero(depth(roi) > 0), roi.area() * 8 / 10);
  EXPECT_NEAR(median_valid(depth, roi), bf / 20.0, 0.02);
}

TEST(StereoDepth, BadPairsGiveNothingAndBadOptionsAreNamed) {
  EXPECT_TRUE(stereo_depth(cv::Mat(), cv::Mat(), 40.0).empty());
  EXPECT_TRUE(stereo_depth(cv::Mat(10, 10, CV_8UC1), cv::Mat(10, 12, CV_8UC1), 40.0).empty());
  EXPECT_TRUE(stereo_depth(cv::Mat(10, 10, CV_32FC1), cv::Mat(10, 10, CV_32FC1), 40.0).empty());
  EXPECT_TRUE(stereo_depth(cv::Mat(10, 10, CV_8UC1), cv::Mat(10, 10, CV_8UC1), 0.0).empty());
  StereoDepthOptions o;
  o.num_disparities = 100;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  EXPECT_THROW(DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.inpainting: {stereo_block_size: 4}\n",
                                           "bad.yaml"),
               InputError);
  const DynamicFilterOptions ok = DynamicFilterOptions::parse(
      "Dynamic.stages: [semantic]\nDynamic.inpainting: {stereo_num_disparities: 64, stereo_three_way: false}\n", "ok");
  EXPECT_EQ(ok.inpainting.stereo.num_disparities, 64);
  EXPECT_FALSE(ok.inpainting.stereo.three_way);
}

// A stereo pair of a textured wall 2 m away (disparity 20 px at bf 40),
// optionally with a textured box 1 m away (disparity 40 px) in front of it.
struct StereoScene {
  cv::Mat wall = grey_texture(5, cv::Size(640 + 64, 480));
  cv::Mat box = grey_texture(9, cv::Size(640 + 64, 480)) / 2;  // darker: told apart from the wall
  cv::Rect box_left{250, 150, 120, 160};                       // where the box is in the left image

  std::pair<cv::Mat, cv::Mat> pair(bool with_box) const {
    cv::Mat left = wall(cv::Rect(0, 0, 640, 480)).clone();
    cv::Mat right = wall(cv::Rect(20, 0, 640, 480)).clone();  // right(x) = left(x + 20)
    if (with_box) {
      box(box_left).copyTo(left(box_left));
      const cv::Rect in_right(box_left.x - 40, box_left.y, box_left.width, box_left.height);
      box(box_left).copyTo(right(in_right));  // right(x) = left(x + 40) on the box
    }
    return {left, right};
  }
};

Settings stereo_settings() {
  Settings s = test::rgbd_settings();  // fx 500, bf 40
  s.camera.depth_map_factor.reset();
  return s;
}

SystemOptions drop_preset() {
  SystemOptions o;
  o.synchronous_mapping = true;
  o.dynamic = DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n",
                                          "drop.yaml");
  return o;
}

TEST(SystemStereoDense, DepthByBlockMatchingAndInpaintingFromKeyframes) {
  System sys(stereo_settings(), Sensor::kStereo, drop_preset());
  const StereoScene scene;
  auto [left, right] = scene.pair(false);
  ASSERT_EQ(sys.track_stereo(left, right, 1.0).state, TrackingState::kOk);  // the first keyframe
  ASSERT_EQ(sys.track_stereo(left, right, 2.0).state, TrackingState::kOk);
  auto [left_box, right_box] = scene.pair(true);
  cv::Mat labels = cv::Mat::zeros(480, 640, CV_8UC1);
  labels(scene.box_left).setTo(15);
  ASSERT_EQ(sys.track_stereo(left_box, right_box, 3.0, cv::Mat(), labels).state, TrackingState::kOk);
  const cv::Rect inner(scene.box_left.x + 20, scene.box_left.y + 20, 80, 120);
  const DenseFrame raw = sys.dense_frame(false);
  ASSERT_EQ(raw.depth.type(), CV_32FC1);
  EXPECT_FALSE(raw.inpainted);
  EXPECT_NEAR(median_valid(raw.depth, inner), 1.0f, 0.05f);  // the box, by block matching
  EXPECT_NEAR(median_valid(raw.depth, cv::Rect(420, 100, 100, 100)), 2.0f, 0.1f);
  const DenseFrame d = sys.dense_frame(true);
  ASSERT_TRUE(d.inpainted);
  EXPECT_GT(d.inpainted_pixels, scene.box_left.area() * 8 / 10);
  EXPECT_NEAR(median_valid(d.depth, inner), 2.0f, 0.1f);  // the wall the keyframe saw behind it
  cv::Mat grey, diff;
  cv::cvtColor(d.colour, grey, cv::COLOR_BGR2GRAY);
  cv::absdiff(grey(inner), left(inner), diff);
  EXPECT_LT(cv::mean(diff)[0], 12.0);
}

TEST(SystemStereoDense, MovableRegionsOfAFirstFrameAreUnchecked) {
  System sys(stereo_settings(), Sensor::kStereo, drop_preset());
  const StereoScene scene;
  auto [left, right] = scene.pair(true);
  cv::Mat labels = cv::Mat::zeros(480, 640, CV_8UC1);
  labels(scene.box_left).setTo(15);
  sys.track_stereo(left, right, 1.0, cv::Mat(), labels);
  const DenseFrame first = sys.dense_frame(false);
  EXPECT_FALSE(first.motion_checked);
  ASSERT_FALSE(first.candidates.empty());
  EXPECT_EQ(cv::countNonZero(first.candidates), scene.box_left.area());
  sys.track_stereo(left, right, 2.0, cv::Mat(), labels);
  EXPECT_TRUE(sys.dense_frame(false).motion_checked);
  sys.reset();
  sys.track_stereo(left, right, 3.0);
  const DenseFrame after_reset = sys.dense_frame(false);
  EXPECT_FALSE(after_reset.motion_checked);
  EXPECT_TRUE(after_reset.candidates.empty());  // no labels: nothing movable to check
}

}  // namespace
}  // namespace dynaorb::dynamic
