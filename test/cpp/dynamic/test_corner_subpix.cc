// refine_corners_subpix against cv::cornerSubPix: the same positions, bit for
// bit, on real images (EuRoC V1_01 cam0, KITTI 06, TUM fr3 walking_xyz) with
// the motion cues' Harris corners, at the image border (OpenCV's replicated
// patch), for several windows and stopping rules, with 2 lanes and (on an
// AVX2 CPU) 4; and the same refusals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "../test_util.h"
#include "dynaorb/dynamic/corner_subpix.h"

namespace dynaorb {
namespace {

using dynamic::refine_corners_subpix;
using dynamic::detail::refine_corners_subpix_lanes;
using dynamic::detail::subpix_lanes_available;
using test::shared_data;

cv::Mat first_image(const test::fs::path& dir, int skip) {
  std::vector<std::string> files;
  for (const auto& e : test::fs::directory_iterator(dir)) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  if (files.empty()) return cv::Mat();
  return cv::imread(files[std::min<size_t>(skip, files.size() - 1)], cv::IMREAD_GRAYSCALE);
}

std::vector<cv::Mat> real_images() {
  return {first_image(shared_data() / "euroc/V1_01_easy_micro/mav0/cam0/data", 10),
          first_image(shared_data() / "kitti/sequences/06/image_0", 20),
          first_image(shared_data() / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment/rgb", 0)};
}

bool same_bits(const cv::Point2f& a, const cv::Point2f& b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// Refines `corners` with OpenCV and with every lane count this CPU has, and counts the
// corners whose positions differ from OpenCV's in any bit (summed over the lane counts).
int differing(const cv::Mat& grey, const std::vector<cv::Point2f>& corners, int half, int iterations,
              double eps) {
  std::vector<cv::Point2f> theirs = corners;
  cv::cornerSubPix(grey, theirs, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, iterations, eps));
  int n = 0;
  for (int lanes = 2; lanes <= subpix_lanes_available(); lanes *= 2) {
    std::vector<cv::Point2f> ours = corners;
    refine_corners_subpix_lanes(grey, ours, half, iterations, eps, lanes);
    for (size_t i = 0; i < corners.size(); ++i) n += !same_bits(ours[i], theirs[i]);
  }
  return n;
}

TEST(CornerSubpix, SameBitsAsOpenCVOnRealImages) {
  DYNAORB_REQUIRE_SHARED();
  int images = 0;
  for (const cv::Mat& grey : real_images()) {
    if (grey.empty()) continue;
    ++images;
    // The motion cues' detection (DS-SLAM's Harris corners, 0.01 and a low quality level).
    for (double quality : {0.01, 0.001}) {
      std::vector<cv::Point2f> corners;
      cv::goodFeaturesToTrack(grey, corners, 1000, quality, 8, cv::noArray(), 3, true, 0.04);
      ASSERT_GT(corners.size(), 100u);
      for (int half : {10, 5, 3})
        EXPECT_EQ(differing(grey, corners, half, 20, 0.03), 0) << "half window " << half << ", quality " << quality;
      EXPECT_EQ(differing(grey, corners, 10, 1, 0.03), 0);
      EXPECT_EQ(differing(grey, corners, 10, 100, 0.0), 0);  // runs to OpenCV's cap of 100 steps
      EXPECT_EQ(differing(grey, corners, 10, 0, 0.03), 0);   // OpenCV makes that 1 step
    }
  }
  EXPECT_EQ(images, 3);
}

TEST(CornerSubpix, SameBitsAsOpenCVAtTheBorderAndOnFlatPatches) {
  DYNAORB_REQUIRE_SHARED();
  const cv::Mat grey = first_image(shared_data() / "euroc/V1_01_easy_micro/mav0/cam0/data", 10);
  ASSERT_FALSE(grey.empty());
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<cv::Point2f> corners;
  // Within 15 px of each edge (the patch leaves the image), and anywhere.
  for (int i = 0; i < 400; ++i) {
    const float x = u(rng) * (grey.cols - 1), y = u(rng) * (grey.rows - 1);
    const float edge = u(rng) * 15.f;
    switch (i % 5) {
      case 0: corners.emplace_back(edge, y); break;
      case 1: corners.emplace_back(grey.cols - 1 - edge, y); break;
      case 2: corners.emplace_back(x, edge); break;
      case 3: corners.emplace_back(x, grey.rows - 1 - edge); break;
      default: corners.emplace_back(x, y);
    }
  }
  corners.emplace_back(0.f, 0.f);
  for (int half : {10, 4}) EXPECT_EQ(differing(grey, corners, half, 20, 0.03), 0) << half;
  // A flat image: singular systems, every corner stays where it was.
  const cv::Mat flat(120, 160, CV_8UC1, cv::Scalar(90));
  std::vector<cv::Point2f> few = {{50.5f, 60.25f}, {3.f, 4.f}};
  EXPECT_EQ(differing(flat, few, 10, 20, 0.03), 0);
  refine_corners_subpix(flat, few, 10, 20, 0.03);
  EXPECT_TRUE(same_bits(few[0], cv::Point2f(50.5f, 60.25f)));
}

TEST(CornerSubpix, RefusesWhatCornerSubPixRefuses) {
  const cv::Mat grey(100, 100, CV_8UC1, cv::Scalar(0));
  std::vector<cv::Point2f> none;
  EXPECT_NO_THROW(refine_corners_subpix(grey, none, 10, 20, 0.03));
  std::vector<cv::Point2f> outside = {{10.f, 10.f}, {100.5f, 5.f}};
  EXPECT_THROW(refine_corners_subpix(grey, outside, 10, 20, 0.03), cv::Exception);
  std::vector<cv::Point2f> one = {{50.f, 50.f}};
  EXPECT_THROW(refine_corners_subpix(cv::Mat(100, 100, CV_32FC1, cv::Scalar(0)), one, 10, 20, 0.03), cv::Exception);
  EXPECT_THROW(refine_corners_subpix(cv::Mat(20, 20, CV_8UC1, cv::Scalar(0)), one, 10, 20, 0.03), cv::Exception);
  EXPECT_THROW(refine_corners_subpix(grey, one, 0, 20, 0.03), cv::Exception);
  EXPECT_THROW(refine_corners_subpix_lanes(grey, one, 10, 20, 0.03, 3), cv::Exception);
  EXPECT_TRUE(subpix_lanes_available() == 2 || subpix_lanes_available() == 4);
}

}  // namespace
}  // namespace dynaorb
