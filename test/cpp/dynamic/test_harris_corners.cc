// harris_corners against cv::goodFeaturesToTrack (Harris): the same corners
// in the same order on rendered rooms and on real frames of ../shared/data,
// over the options the motion cues use and others (block sizes, distances,
// masks, corner caps); OpenCV itself where the rules do not cover the input;
// OpenCV's refusals.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "dynaorb/dynamic/harris_corners.h"
#include "synthetic_scene.h"
#include "../test_util.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

struct Options {
  int max_corners = 1000;
  double quality = 0.01;
  double min_distance = 8;
  int block = 3;
  double k = 0.04;
};

std::vector<cv::Point2f> opencv_corners(const cv::Mat& grey, const cv::Mat& mask, const Options& o) {
  std::vector<cv::Point2f> out;
  cv::goodFeaturesToTrack(grey, out, o.max_corners, o.quality, o.min_distance, mask, o.block, true, o.k);
  return out;
}

struct Compared {
  int corners = 0;  // OpenCV's
  int swaps = 0;
};

// The same corners in the same order, but where OpenCV's own (float)
// responses of two neighbours in its list agree to 1e-6 and ours ordered
// them the other way: such a pair may be swapped.
Compared expect_same_corners(const cv::Mat& grey, const cv::Mat& mask, const Options& o, const std::string& what) {
  const std::vector<cv::Point2f> theirs = opencv_corners(grey, mask, o);
  const std::vector<cv::Point2f> ours = harris_corners(grey, o.max_corners, o.quality, o.min_distance, mask, o.block, o.k);
  Compared c;
  c.corners = static_cast<int>(theirs.size());
  EXPECT_EQ(ours.size(), theirs.size()) << what;
  if (ours.size() != theirs.size()) return c;
  cv::Mat response;
  cv::cornerHarris(grey, response, o.block, 3, o.k);
  const auto at = [&](const cv::Point2f& p) { return response.at<float>(cvRound(p.y), cvRound(p.x)); };
  for (size_t i = 0; i < ours.size(); ++i) {
    if (ours[i] == theirs[i]) continue;
    const bool swapped = i + 1 < ours.size() && ours[i] == theirs[i + 1] && ours[i + 1] == theirs[i] &&
                         std::abs(at(theirs[i]) - at(theirs[i + 1])) <= 1e-6 * std::abs(at(theirs[i]));
    EXPECT_TRUE(swapped) << what << ": corner " << i << " is (" << ours[i].x << ", " << ours[i].y
                         << "), OpenCV's (" << theirs[i].x << ", " << theirs[i].y << ")";
    if (!swapped) return c;
    ++c.swaps;
    ++i;
  }
  return c;
}

cv::Mat border_mask(const cv::Size& size, int border) {
  cv::Mat m(size, CV_8UC1, cv::Scalar(0));
  m(cv::Rect(border, border, size.width - 2 * border, size.height - 2 * border)).setTo(255);
  return m;
}

// A mask of random discs (values 1-255: any non-zero byte counts).
cv::Mat blob_mask(const cv::Size& size, unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat m(size, CV_8UC1, cv::Scalar(0));
  for (int i = 0; i < 12; ++i)
    cv::circle(m, cv::Point(rng() % size.width, rng() % size.height), 10 + static_cast<int>(rng() % 60),
               cv::Scalar(1 + static_cast<int>(rng() % 255)), cv::FILLED);
  return m;
}

std::vector<cv::Mat> rendered_frames() {
  auto calib = make_calibration(Sensor::kMono);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 3; ++i)
    frames.push_back(render(room(1 + i), make_motion(1.5 * i, -2.0 * i, 0.5 * i, {0.05 * i, 0.0, 0.1 * i}), *calib).grey);
  return frames;
}

TEST(HarrisCorners, SameAsGoodFeaturesToTrackOnRenderedRooms) {
  int swaps = 0, corners = 0;
  const std::vector<cv::Mat> frames = rendered_frames();
  for (size_t f = 0; f < frames.size(); ++f) {
    const cv::Mat& grey = frames[f];
    const std::vector<std::pair<std::string, cv::Mat>> masks = {
        {"no mask", cv::Mat()}, {"border", border_mask(grey.size(), 10)}, {"blobs", blob_mask(grey.size(), f)}};
    for (const auto& [mask_name, mask] : masks)
      for (const Options& o : {Options{}, Options{0, 0.01, 8, 3, 0.04}, Options{50, 0.1, 0, 3, 0.04},
                               Options{300, 0.001, 3.5, 5, 0.06}, Options{1000, 0.01, 8, 2, 0.04},
                               Options{1000, 0.01, 8, 4, 0.04}, Options{200, 0.05, 12, 7, 0.04}}) {
        const std::string what = "frame " + std::to_string(f) + ", " + mask_name + ", block " +
                                 std::to_string(o.block) + ", distance " + std::to_string(o.min_distance);
        const Compared c = expect_same_corners(grey, mask, o, what);
        swaps += c.swaps;
        corners += c.corners;
      }
  }
  EXPECT_GT(corners, 10000);
  // OpenCV's float rounding (its dispatched Sobel and box filter) decides the
  // near-ties' order: none here, so at most one in a thousand elsewhere.
  EXPECT_LE(swaps * 1000, corners) << swaps << " swaps of near-equal neighbours";
}

// Real frames: EuRoC MH_05 (752x480) and KITTI 06 (1226x370), the motion
// cues' options. Measured over all 250 / 51 frames: the same lists but on one
// MH_05 frame, where two corners 250 px apart swap places (OpenCV's responses
// 0.00868821796 and 0.0086882161).
TEST(HarrisCorners, SameAsGoodFeaturesToTrackOnRealFrames) {
  DYNAORB_REQUIRE_SHARED();
  const auto root = test::shared_data();
  std::vector<std::filesystem::path> dirs = {root / "euroc/MH_05_difficult_head/mav0/cam0/data",
                                             root / "kitti/sequences/06/image_0"};
  int frames = 0, swaps = 0, corners = 0;
  for (const auto& dir : dirs) {
    if (!std::filesystem::is_directory(dir)) continue;
    std::vector<std::filesystem::path> files;
    for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (size_t i = 0; i < files.size(); i += 10) {
      const cv::Mat grey = cv::imread(files[i].string(), cv::IMREAD_GRAYSCALE);
      ASSERT_FALSE(grey.empty()) << files[i];
      const Compared c = expect_same_corners(grey, border_mask(grey.size(), 10), Options{}, files[i].string());
      swaps += c.swaps;
      corners += c.corners;
      ++frames;
    }
  }
  if (frames == 0) GTEST_SKIP() << "no MH_05 or KITTI 06 frames under " << root;
  EXPECT_LE(swaps * 1000, corners) << swaps << " swaps of near-equal neighbours";
}

// Where the rules do not cover the input, OpenCV answers: a submatrix (its
// filters read the parent image past the edge), a block too large for exact
// int32 sums or for the image, images under 3x3.
TEST(HarrisCorners, OpenCvAnswersWhatTheRulesDoNotCover) {
  const cv::Mat grey = rendered_frames()[0];
  const cv::Mat roi = grey(cv::Rect(100, 80, 300, 200));
  ASSERT_TRUE(roi.isSubmatrix());
  Options o;
  EXPECT_EQ(harris_corners(roi, o.max_corners, o.quality, o.min_distance, cv::Mat(), o.block, o.k),
            opencv_corners(roi, cv::Mat(), o));
  o.block = 47;
  EXPECT_EQ(harris_corners(grey, o.max_corners, o.quality, o.min_distance, cv::Mat(), o.block, o.k),
            opencv_corners(grey, cv::Mat(), o));
  const cv::Mat tiny = grey(cv::Rect(0, 0, 2, 9)).clone();
  EXPECT_EQ(harris_corners(tiny, 10, 0.01, 1, cv::Mat(), 3, 0.04), opencv_corners(tiny, cv::Mat(), {10, 0.01, 1, 3, 0.04}));
  const cv::Mat flat(40, 40, CV_8UC1, cv::Scalar(90));
  EXPECT_TRUE(harris_corners(flat, 10, 0.01, 1, cv::Mat(), 3, 0.04).empty());
  EXPECT_TRUE(opencv_corners(flat, cv::Mat(), {10, 0.01, 1, 3, 0.04}).empty());
  EXPECT_TRUE(harris_corners(grey, 10, 0.01, 1, cv::Mat::zeros(grey.size(), CV_8UC1), 3, 0.04).empty());
}

TEST(HarrisCorners, RefusesWhatGoodFeaturesToTrackRefuses) {
  const cv::Mat grey = rendered_frames()[0];
  EXPECT_THROW(harris_corners(grey, 10, 0.0, 8, cv::Mat(), 3, 0.04), cv::Exception);
  EXPECT_THROW(harris_corners(grey, 10, 0.01, -1, cv::Mat(), 3, 0.04), cv::Exception);
  EXPECT_THROW(harris_corners(grey, -1, 0.01, 8, cv::Mat(), 3, 0.04), cv::Exception);
  EXPECT_THROW(harris_corners(grey, 10, 0.01, 8, cv::Mat(10, 10, CV_8UC1, cv::Scalar(1)), 3, 0.04), cv::Exception);
  cv::Mat colour;
  cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
  EXPECT_THROW(harris_corners(colour, 10, 0.01, 8, cv::Mat(), 3, 0.04), cv::Exception);
}

}  // namespace
}  // namespace dynaorb::dynamic
