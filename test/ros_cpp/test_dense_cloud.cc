#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "support/dense_cloud.h"

namespace dynaorb::node {
namespace {

cv::Mat intrinsics() { return (cv::Mat_<double>(3, 3) << 100.0, 0, 31.5, 0, 100.0, 23.5, 0, 0, 1); }

TEST(DenseCloud, UnprojectsEveryValidPixel) {
  DenseCloudOptions o;
  o.stride = 1;
  o.max_depth = 5.0;
  DenseCloudBuilder b(o);
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(2.0f));
  cv::Mat colour(48, 64, CV_8UC3, cv::Scalar(10, 20, 30));  // B G R
  const DenseCloud c = b.build(depth, colour, false, cv::Mat(), intrinsics(), cv::Mat());
  ASSERT_TRUE(b.error().empty());
  ASSERT_EQ(c.xyz.size(), 64u * 48u);
  ASSERT_EQ(c.rgb.size(), c.xyz.size());
  // Pixel (0, 0): x = (0 - 31.5) / 100 * 2.
  EXPECT_NEAR(c.xyz[0].x(), -0.63f, 1e-5);
  EXPECT_NEAR(c.xyz[0].y(), -0.47f, 1e-5);
  EXPECT_NEAR(c.xyz[0].z(), 2.0f, 1e-6);
  EXPECT_EQ(c.rgb[0][0], 30);  // red first
  EXPECT_EQ(c.rgb[0][2], 10);
}

TEST(DenseCloud, DropsMaskedMissingAndFarPixels) {
  DenseCloudOptions o;
  o.stride = 1;
  o.max_depth = 3.0;
  DenseCloudBuilder b(o);
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(2.0f));
  depth(cv::Rect(0, 0, 10, 48)).setTo(0.0f);                                     // 480 without depth
  depth(cv::Rect(10, 0, 5, 48)).setTo(std::numeric_limits<float>::quiet_NaN());  // 240 NaN
  depth(cv::Rect(15, 0, 5, 48)).setTo(7.0f);                                     // 240 beyond max_depth
  cv::Mat mask = cv::Mat::zeros(48, 64, CV_8UC1);
  mask(cv::Rect(40, 0, 24, 48)).setTo(255);  // 1152 on a moving object
  const DenseCloud c = b.build(depth, cv::Mat(), true, mask, intrinsics(), cv::Mat());
  EXPECT_EQ(c.no_depth, 720);
  EXPECT_EQ(c.out_of_range, 240);
  EXPECT_EQ(c.masked, 1152);
  EXPECT_EQ(c.xyz.size(), static_cast<size_t>(64 * 48 - 720 - 240 - 1152));
  EXPECT_TRUE(c.rgb.empty());
  for (const auto& p : c.xyz) EXPECT_LT((p.x() / p.z()) * 100.0 + 31.5, 40.0);  // nothing from the masked columns
}

TEST(DenseCloud, StrideSubsamples) {
  DenseCloudOptions o;
  o.stride = 4;
  DenseCloudBuilder b(o);
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_EQ(b.build(depth, cv::Mat(), true, cv::Mat(), intrinsics(), cv::Mat()).xyz.size(), 16u * 12u);
}

TEST(DenseCloud, UndistortsRays) {
  DenseCloudOptions o;
  o.stride = 1;
  DenseCloudBuilder b(o);
  const cv::Mat K = intrinsics();
  const cv::Mat dist = (cv::Mat_<double>(1, 5) << 0.2, -0.1, 0.001, 0.002, 0.0);
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(1.5f));
  const DenseCloud c = b.build(depth, cv::Mat(), true, cv::Mat(), K, dist);
  // Projecting the points with the distortion gives back their pixels.
  std::vector<cv::Point3f> obj;
  for (const auto& p : c.xyz) obj.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2f> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, dist, img);
  double worst = 0.0;
  for (size_t i = 0; i < img.size(); ++i) {
    const double u = static_cast<double>(i % 64), v = static_cast<double>(i / 64);
    worst = std::max(worst, std::hypot(img[i].x - u, img[i].y - v));
  }
  EXPECT_LT(worst, 0.05);
}

TEST(DenseCloud, BadInputGivesAnEmptyCloudAndAReason) {
  DenseCloudBuilder b;
  cv::Mat depth16(48, 64, CV_16UC1, cv::Scalar(1000));
  EXPECT_TRUE(b.build(depth16, cv::Mat(), true, cv::Mat(), intrinsics(), cv::Mat()).xyz.empty());
  EXPECT_FALSE(b.error().empty());
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_TRUE(b.build(depth, cv::Mat(10, 10, CV_8UC3), true, cv::Mat(), intrinsics(), cv::Mat()).xyz.empty());
  EXPECT_TRUE(b.build(depth, cv::Mat(), true, cv::Mat(48, 64, CV_16UC1), intrinsics(), cv::Mat()).xyz.empty());
  EXPECT_TRUE(b.build(depth, cv::Mat(), true, cv::Mat(), cv::Mat::eye(2, 2, CV_64F), cv::Mat()).xyz.empty());
  EXPECT_TRUE(b.build(cv::Mat(), cv::Mat(), true, cv::Mat(), intrinsics(), cv::Mat()).xyz.empty());
}

TEST(MovableMask, MarksOnlyMovableIds) {
  cv::Mat labels = (cv::Mat_<std::uint8_t>(1, 5) << 0, 15, 7, 9, 15);
  const cv::Mat m = movable_mask(labels, {7, 15});
  ASSERT_EQ(m.type(), CV_8UC1);
  EXPECT_EQ(m.at<std::uint8_t>(0), 0);
  EXPECT_EQ(m.at<std::uint8_t>(1), 255);
  EXPECT_EQ(m.at<std::uint8_t>(2), 255);
  EXPECT_EQ(m.at<std::uint8_t>(3), 0);
  cv::Mat wide = (cv::Mat_<std::uint16_t>(1, 3) << 300, 15, 2);
  const cv::Mat w = movable_mask(wide, {300, 2});
  EXPECT_EQ(w.at<std::uint8_t>(0), 255);
  EXPECT_EQ(w.at<std::uint8_t>(1), 0);
  EXPECT_EQ(w.at<std::uint8_t>(2), 255);
  EXPECT_TRUE(movable_mask(cv::Mat(2, 2, CV_32FC1), {1}).empty());
  // Ids outside the label range are ignored.
  EXPECT_EQ(cv::countNonZero(movable_mask(labels, {-1, 999})), 0);
}

}  // namespace
}  // namespace dynaorb::node
