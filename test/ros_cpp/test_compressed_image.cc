#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "support/compressed_image.h"

namespace dynaorb::node {
namespace {

std::vector<std::uint8_t> encode(const cv::Mat& image, const std::string& ext) {
  std::vector<std::uint8_t> out;
  EXPECT_TRUE(cv::imencode(ext, image, out));
  return out;
}

// compressed_depth_image_transport's message data: header + 16-bit PNG.
std::vector<std::uint8_t> depth_data(const cv::Mat& q, float a, float b) {
  std::vector<std::uint8_t> out(12, 0);
  std::memcpy(out.data() + 4, &a, sizeof(float));
  std::memcpy(out.data() + 8, &b, sizeof(float));
  const std::vector<std::uint8_t> png = encode(q, ".png");
  out.insert(out.end(), png.begin(), png.end());
  return out;
}

TEST(CompressedImage, GreyAndColourPngComeBackExactly) {
  cv::Mat grey(48, 64, CV_8UC1), colour(48, 64, CV_8UC3), grey16(48, 64, CV_16UC1);
  cv::randu(grey, 0, 255);
  cv::randu(colour, 0, 255);
  cv::randu(grey16, 0, 65535);
  const DecodedImage g = decode_compressed("mono8; png compressed mono8", encode(grey, ".png"));
  EXPECT_EQ(g.encoding, "mono8");
  EXPECT_EQ(cv::norm(g.image, grey, cv::NORM_INF), 0.0);
  const DecodedImage c = decode_compressed("rgb8; png compressed bgr8", encode(colour, ".png"));
  EXPECT_EQ(c.encoding, "bgr8");  // the transport compresses colour as bgr8
  EXPECT_EQ(cv::norm(c.image, colour, cv::NORM_INF), 0.0);
  const DecodedImage w = decode_compressed("png", encode(grey16, ".png"));
  EXPECT_EQ(w.encoding, "mono16");
  EXPECT_EQ(cv::norm(w.image, grey16, cv::NORM_INF), 0.0);
}

TEST(CompressedImage, JpegColourDecodesCloseToTheImage) {
  cv::Mat colour(48, 64, CV_8UC3);
  cv::randu(colour, 0, 255);
  cv::GaussianBlur(colour, colour, cv::Size(9, 9), 3);
  const DecodedImage c = decode_compressed("bgr8; jpeg compressed bgr8", encode(colour, ".jpg"));
  ASSERT_EQ(c.encoding, "bgr8");
  cv::Mat diff;
  cv::absdiff(c.image, colour, diff);
  EXPECT_LT(cv::mean(diff)[0], 3.0);
}

TEST(CompressedImage, DepthIn16BitsComesBackExactly) {
  cv::Mat mm(48, 64, CV_16UC1);
  cv::randu(mm, 0, 10000);
  const DecodedImage d = decode_compressed("16UC1; compressedDepth png", depth_data(mm, 0.f, 0.f));
  EXPECT_EQ(d.encoding, "16UC1");
  EXPECT_EQ(cv::norm(d.image, mm, cv::NORM_INF), 0.0);
}

TEST(CompressedImage, DepthInMetresFromItsQuantisedInverse) {
  // The transport's defaults: depth_quantization 100, depth_max 10 m.
  const float z0 = 100.f, a = z0 * (z0 + 1.f), b = 1.f - a / 10.f;
  cv::Mat depth(48, 64, CV_32FC1), q(48, 64, CV_16UC1);
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c) {
      const float d = 0.3f + 8.7f * static_cast<float>(r * depth.cols + c) / static_cast<float>(depth.total());
      depth.at<float>(r, c) = d;
      q.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(a / d + b);
    }
  q.at<std::uint16_t>(0, 0) = 0;  // no depth
  const DecodedImage out = decode_compressed("32FC1; compressedDepth", depth_data(q, a, b));
  ASSERT_EQ(out.encoding, "32FC1");
  EXPECT_TRUE(std::isnan(out.image.at<float>(0, 0)));
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c) {
      if (r == 0 && c == 0) continue;
      const float d = depth.at<float>(r, c);
      // One step of the quantised inverse depth, about d^2 / A.
      ASSERT_LT(std::abs(out.image.at<float>(r, c) - d), 1.01f * d * d / a) << r << "," << c;
    }
}

TEST(CompressedImage, WhatDoesNotDecodeIsNamed) {
  const std::vector<std::uint8_t> junk(40, 7);
  EXPECT_THROW(decode_compressed("jpeg", junk), std::invalid_argument);
  EXPECT_THROW(decode_compressed("jpeg", {}), std::invalid_argument);
  EXPECT_THROW(decode_compressed("16UC1; compressedDepth png", junk), std::invalid_argument);
  EXPECT_THROW(decode_compressed("32FC1; compressedDepth", std::vector<std::uint8_t>(12, 0)), std::invalid_argument);
  try {
    decode_compressed("16UC1; compressedDepth rvl", junk);
    FAIL() << "rvl accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rvl"), std::string::npos) << e.what();
  }
  cv::Mat grey8(8, 8, CV_8UC1, cv::Scalar(3));
  try {
    decode_compressed("8UC1; compressedDepth png", depth_data(grey8, 0.f, 0.f));
    FAIL() << "an 8-bit depth image accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("16-bit"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dynaorb::node
