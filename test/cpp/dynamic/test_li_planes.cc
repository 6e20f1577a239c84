// Disparity planes (Li et al. eq. 8): RANSAC recovers a slanted plane from
// SGBM-like disparities with gross outliers, per-superpixel fits on a label
// map, and the SPS-style filling of the half-occluded band.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "dynaorb/dynamic/li_disparity.h"
#include "dynaorb/dynamic/li_planes.h"

namespace dynaorb::dynamic {
namespace {

TEST(LiPlanes, RecoversAPlaneDespiteOutliers) {
  const double a = 0.05, b = -0.02, c = 20.0;
  cv::RNG rng(11);
  std::vector<cv::Point3f> pts;
  for (int i = 0; i < 400; ++i) {
    const float x = rng.uniform(100.f, 140.f), y = rng.uniform(200.f, 240.f);
    float d = static_cast<float>(a * x + b * y + c + rng.gaussian(0.1));
    if (i % 10 < 3) d = rng.uniform(1.f, 60.f);  // 30 % mismatches
    pts.emplace_back(x, y, d);
  }
  LiOptions o;
  cv::RNG fit_rng(1);
  const LiPlane p = li_fit_disparity_plane(pts, o, fit_rng);
  ASSERT_TRUE(p.valid);
  EXPECT_NEAR(p.a, a, 0.005);
  EXPECT_NEAR(p.b, b, 0.005);
  EXPECT_NEAR(p.at(120, 220), a * 120 + b * 220 + c, 0.05);
  EXPECT_GE(p.inliers, 270);  // the 280 true points, less a few noise tails
  EXPECT_LE(p.inliers, 300);
  EXPECT_EQ(p.support, 400);

  // A least-squares fit on all points would be pulled far off: the test can tell.
  double sum = 0;
  for (const auto& q : pts) sum += q.z;
  EXPECT_GT(std::abs(sum / pts.size() - (a * 120 + b * 220 + c)), 1.0);
}

TEST(LiPlanes, TooFewOrDegeneratePointsGiveNoPlane) {
  LiOptions o;
  cv::RNG rng(1);
  std::vector<cv::Point3f> few{{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  EXPECT_FALSE(li_fit_disparity_plane(few, o, rng).valid);
  std::vector<cv::Point3f> line;  // all on one image row: x, d known, slope in y unknowable
  for (int i = 0; i < 50; ++i) line.emplace_back(static_cast<float>(i), 10.f, 5.f);
  EXPECT_FALSE(li_fit_disparity_plane(line, o, rng).valid);
}

TEST(LiPlanes, OnePlanePerSuperpixel) {
  // Left half superpixel 0 on a fronto-parallel plane d = 30, right half
  // superpixel 1 on a slanted one d = 10 + 0.1 x; a hole without disparity.
  cv::Mat labels(40, 80, CV_32SC1), disp(40, 80, CV_32FC1);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 80; ++x) {
      labels.at<int>(y, x) = x < 40 ? 0 : 1;
      disp.at<float>(y, x) = x < 40 ? 30.f : static_cast<float>(10 + 0.1 * x);
    }
  disp(cv::Rect(0, 0, 10, 10)).setTo(0);
  const auto planes = li_fit_superpixel_planes(labels, 2, disp, {cv::Rect(0, 0, 80, 40)}, LiOptions());
  ASSERT_EQ(planes.size(), 2u);
  ASSERT_TRUE(planes[0].valid && planes[1].valid);
  EXPECT_NEAR(planes[0].at(20, 20), 30.0, 1e-3);
  EXPECT_NEAR(planes[0].a, 0.0, 1e-4);
  EXPECT_NEAR(planes[1].a, 0.1, 1e-4);
  EXPECT_NEAR(planes[1].at(60, 5), 16.0, 1e-3);
  EXPECT_EQ(planes[0].support, 40 * 40 - 100);
  // Only the given areas are read.
  const auto none = li_fit_superpixel_planes(labels, 2, disp, {}, LiOptions());
  EXPECT_FALSE(none[0].valid);
}

TEST(LiPlanes, FillsHalfOccludedRunsWithTheBackground) {
  cv::Mat d = (cv::Mat_<float>(1, 10) << 0, 0, 12, 12, 0, 0, 0, 30, 30, 0);
  const cv::Mat f = li_fill_occlusions(d);
  const float expected[10] = {12, 12, 12, 12, 12, 12, 12, 30, 30, 30};
  for (int x = 0; x < 10; ++x) EXPECT_FLOAT_EQ(f.at<float>(0, x), expected[x]) << x;
  EXPECT_EQ(cv::countNonZero(li_fill_occlusions(cv::Mat(2, 5, CV_32FC1, cv::Scalar(0)))), 0);
  EXPECT_TRUE(li_fill_occlusions(cv::Mat(2, 5, CV_8UC1)).empty());
}

TEST(LiDisparity, DepthIsBaselineTimesFocalOverDisparity) {
  cv::Mat d = (cv::Mat_<float>(1, 3) << 0, 10, 40);
  const cv::Mat z = li_depth_from_disparity(d, 50.0);
  EXPECT_FLOAT_EQ(z.at<float>(0, 0), 0.f);
  EXPECT_FLOAT_EQ(z.at<float>(0, 1), 5.f);
  EXPECT_FLOAT_EQ(z.at<float>(0, 2), 1.25f);
  EXPECT_TRUE(li_depth_from_disparity(d, 0.0).empty());
  EXPECT_TRUE(li_disparity(cv::Mat(), cv::Mat(), LiOptions()).empty());
  EXPECT_TRUE(li_disparity(cv::Mat(10, 10, CV_8UC1), cv::Mat(10, 12, CV_8UC1), LiOptions()).empty());
}

}  // namespace
}  // namespace dynaorb::dynamic
