// Dynamic ROIs (Li et al. eq. 4): dynamic points group when close in the
// image (T_s = alpha_s + beta_s d) and in disparity (T_disp); groups of more
// than four points are moving objects.
#include <gtest/gtest.h>

#include "dynaorb/dynamic/li_rois.h"

namespace dynaorb::dynamic {
namespace {

TEST(LiRois, ClustersByDistanceAndDisparity) {
  LiOptions o;  // T_s = 30 + d px, T_disp = 3 px
  std::vector<cv::Point2f> pts;
  std::vector<float> disp;
  auto add = [&](float x, float y, float d) { pts.emplace_back(x, y), disp.push_back(d); };
  // A near object (d = 40: T_s = 70 px): 6 points 50 px apart, one chain.
  for (int i = 0; i < 6; ++i) add(100.f + 50.f * i, 100.f, 40.f);
  // A far object (d = 5: T_s = 35 px): 5 points 30 px apart.
  for (int i = 0; i < 5; ++i) add(100.f + 30.f * i, 300.f, 5.f);
  // Same place as the far object, other depth: not the same object, and only 4 points.
  for (int i = 0; i < 4; ++i) add(105.f + 30.f * i, 305.f, 20.f);
  // Far-object-depth points 50 px apart: 50 > T_s = 35, each alone.
  for (int i = 0; i < 6; ++i) add(400.f + 50.f * i, 400.f, 5.f);

  const auto c = li_cluster_dynamic_points(pts, disp, cv::Size(640, 480), o);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].members.size(), 6u);  // largest first
  EXPECT_EQ(c[1].members.size(), 5u);
  EXPECT_DOUBLE_EQ(c[0].mean_disparity, 40.0);
  EXPECT_EQ(c[0].bounds, cv::Rect(100, 100, 251, 1));
  // ROI = bounds grown by T_s(mean d) = 70 px, clipped to the image.
  EXPECT_EQ(c[0].roi, cv::Rect(30, 30, 391, 141));
  EXPECT_EQ(c[1].roi, cv::Rect(100 - 35, 300 - 35, 121 + 70, 1 + 70));

  // "More than four": 4 points never make an object.
  LiOptions strict = o;
  strict.min_cluster_points = 7;
  EXPECT_TRUE(li_cluster_dynamic_points(pts, disp, cv::Size(640, 480), strict).empty());
  EXPECT_TRUE(li_cluster_dynamic_points({}, {}, cv::Size(640, 480), o).empty());
  EXPECT_TRUE(li_cluster_dynamic_points(pts, {1.f}, cv::Size(640, 480), o).empty());
}

TEST(LiRois, MergesOverlappingAreas) {
  const auto m = li_merge_overlapping({cv::Rect(0, 0, 10, 10), cv::Rect(50, 50, 5, 5), cv::Rect(5, 5, 10, 10),
                                       cv::Rect(14, 14, 40, 40), cv::Rect(0, 0, 0, 0)});
  // The third overlaps the first; the fourth overlaps their union (not the
  // first alone) and the second; the empty one is dropped.
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], cv::Rect(0, 0, 55, 55));
  const auto apart = li_merge_overlapping({cv::Rect(0, 0, 10, 10), cv::Rect(10, 0, 10, 10)});
  EXPECT_EQ(apart.size(), 2u);  // touching, not overlapping
}

}  // namespace
}  // namespace dynaorb::dynamic
