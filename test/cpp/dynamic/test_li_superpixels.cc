// Li et al.'s improved SLIC (eq. 5-7): superpixels snap to an intensity edge
// that the initial grid does not follow, the edge stays put once found, only
// pixels near superpixel edges are revisited, and bad input gives nothing.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <set>

#include "dynaorb/dynamic/li_superpixels.h"

namespace dynaorb::dynamic {
namespace {

// Two grey levels split by a vertical edge at `edge_x` (not on the 16 px grid).
cv::Mat two_colour(int w, int h, int edge_x) {
  cv::Mat img(h, w, CV_8UC1, cv::Scalar(60));
  img(cv::Rect(edge_x, 0, w - edge_x, h)).setTo(200);
  return img;
}

// Superpixels holding pixels of both sides of the edge.
int straddling(const LiSuperpixels& sp, int edge_x) {
  std::vector<int> side(sp.count, 0);  // bit 1: left pixels, bit 2: right pixels
  for (int y = 0; y < sp.labels.rows; ++y)
    for (int x = 0; x < sp.labels.cols; ++x) side[sp.labels.at<int>(y, x)] |= x < edge_x ? 1 : 2;
  int n = 0;
  for (int s : side) n += s == 3 ? 1 : 0;
  return n;
}

TEST(LiSuperpixels, BoundariesSnapToATwoColourEdgeAndStay) {
  const int edge_x = 57;  // 57 / 16 = 3.56: the edge cuts the grid cells of column 3
  const cv::Mat img = two_colour(128, 96, edge_x);
  const LiSuperpixels sp = li_slic(img, 16.0, 20.0, 10);
  ASSERT_EQ(sp.labels.type(), CV_32SC1);
  ASSERT_EQ(sp.labels.size(), img.size());
  EXPECT_EQ(sp.count, 8 * 6);  // round(128/16) x round(96/16) centres (eq. 6)
  EXPECT_EQ(straddling(sp, edge_x), 0);

  // Stable: the edge splits every row after 10 passes, and still does when the
  // passes go on until nothing changes (the flat halves rebalance slowly:
  // k-means converges there in ~30 passes, the edge itself does not move).
  for (int y = 0; y < img.rows; ++y)
    EXPECT_NE(sp.labels.at<int>(y, edge_x - 1), sp.labels.at<int>(y, edge_x)) << "row " << y;
  const LiSuperpixels more = li_slic(img, 16.0, 20.0, 100);
  EXPECT_TRUE(more.converged);
  EXPECT_EQ(straddling(more, edge_x), 0);
  for (int y = 0; y < img.rows; ++y)
    EXPECT_NE(more.labels.at<int>(y, edge_x - 1), more.labels.at<int>(y, edge_x)) << "row " << y;

  // The labels stay in range and every superpixel is spatially compact (no
  // pixel further than 2 S from its superpixel's centroid).
  std::vector<double> sx(sp.count, 0), sy(sp.count, 0), n(sp.count, 0);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const int l = sp.labels.at<int>(y, x);
      ASSERT_GE(l, 0);
      ASSERT_LT(l, sp.count);
      sx[l] += x, sy[l] += y, n[l] += 1;
    }
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const int l = sp.labels.at<int>(y, x);
      EXPECT_LE(std::abs(x - sx[l] / n[l]), 32.0);
      EXPECT_LE(std::abs(y - sy[l] / n[l]), 32.0);
    }
}

TEST(LiSuperpixels, RevisitsOnlyUnstablePixels) {
  // A textured image: standard SLIC touches every pixel ~4 times per pass
  // (each lies in ~4 centres' 2S x 2S windows); the improved update
  // evaluates each unstable pixel once per pass, and far fewer than all.
  cv::Mat img(160, 160, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(9, 9), 3.0);
  const LiSuperpixels sp = li_slic(img, 16.0, 20.0, 10);
  ASSERT_GT(sp.iterations, 0);
  const double per_pass = static_cast<double>(sp.visits) / sp.iterations / img.total();
  EXPECT_LT(per_pass, 0.6);
  EXPECT_GT(sp.visits, 0);

  // A flat image: the grid is already optimal, the first pass changes nothing.
  const LiSuperpixels flat = li_slic(cv::Mat(96, 96, CV_8UC1, cv::Scalar(90)), 16.0, 20.0, 10);
  EXPECT_TRUE(flat.converged);
  EXPECT_EQ(flat.iterations, 1);
}

TEST(LiSuperpixels, FollowsAnObjectOutline) {
  // A bright disc on a dark background: no superpixel mixes disc and background.
  cv::Mat img(120, 160, CV_8UC1, cv::Scalar(40));
  cv::circle(img, {83, 61}, 30, cv::Scalar(210), cv::FILLED);
  const LiSuperpixels sp = li_slic(img, 12.0, 20.0, 10);
  std::vector<int> side(sp.count, 0);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) side[sp.labels.at<int>(y, x)] |= img.at<uchar>(y, x) > 128 ? 1 : 2;
  int mixed = 0;
  for (int s : side) mixed += s == 3 ? 1 : 0;
  EXPECT_EQ(mixed, 0);
}

TEST(LiSuperpixels, BadInputGivesNothing) {
  EXPECT_EQ(li_slic(cv::Mat(), 16.0, 20.0, 10).count, 0);
  EXPECT_EQ(li_slic(cv::Mat(32, 32, CV_32FC1, cv::Scalar(0)), 16.0, 20.0, 10).count, 0);
  EXPECT_EQ(li_slic(cv::Mat(32, 32, CV_8UC1, cv::Scalar(0)), 0.5, 20.0, 10).count, 0);
  // Smaller than one step: a single superpixel.
  const LiSuperpixels one = li_slic(cv::Mat(5, 7, CV_8UC1, cv::Scalar(9)), 16.0, 20.0, 10);
  EXPECT_EQ(one.count, 1);
  EXPECT_EQ(cv::countNonZero(one.labels), 0);
}

}  // namespace
}  // namespace dynaorb::dynamic
