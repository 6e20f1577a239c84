// Boundary labelling (Li et al. eq. 9-11): a fronto-parallel box in front of
// a wall gives occlusion boundaries along its outline with the box in front,
// a wall split in two gives co-planar boundaries, a floor meeting a wall
// gives a hinge; rays from points on the box stop at its outline.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "dynaorb/dynamic/li_boundaries.h"
#include "dynaorb/dynamic/li_regions.h"

namespace dynaorb::dynamic {
namespace {

LiPlane plane(double a, double b, double c) {
  LiPlane p;
  p.a = a, p.b = b, p.c = c, p.valid = true;
  return p;
}

// Moments of a w x h block of pixels at (x0, y0), and of the column of
// boundary midpoints between x = xb and xb + 1 over those rows.
LiMoments block(int x0, int y0, int w, int h) {
  LiMoments m;
  for (int y = y0; y < y0 + h; ++y)
    for (int x = x0; x < x0 + w; ++x) m.add(x, y);
  return m;
}
LiMoments column(double xb, int y0, int h) {
  LiMoments m;
  for (int y = y0; y < y0 + h; ++y) m.add(xb + 0.5, y);
  return m;
}

TEST(LiBoundaries, EnergiesPickTheRightLabel) {
  LiOptions o;
  const LiMoments u = block(0, 0, 20, 20);
  {
    // Box (d = 30) left of a wall (d = 10): occlusion, the box in front.
    LiBoundary b;
    b.i = 0, b.j = 1, b.moments = column(9, 0, 20);
    li_label_boundary(b, plane(0, 0, 30), plane(0, 0, 10), u, o);
    EXPECT_EQ(b.type, LiBoundaryType::kLeftOcclusion);
    EXPECT_DOUBLE_EQ(b.energy[2], o.lambda_occ);                 // front in front: no penalty
    EXPECT_DOUBLE_EQ(b.energy[3], o.lambda_occ + o.lambda_pen);  // the wall "in front": penalised
    EXPECT_NEAR(b.energy[1], 400 + o.lambda_hinge, 1e-6);
    // Same pair, indices swapped: right occlusion.
    LiBoundary s;
    s.i = 0, s.j = 1, s.moments = b.moments;
    li_label_boundary(s, plane(0, 0, 10), plane(0, 0, 30), u, o);
    EXPECT_EQ(s.type, LiBoundaryType::kRightOcclusion);
  }
  {
    // Two halves of one slanted wall: co-planar, zero energy.
    LiBoundary b;
    b.moments = column(9, 0, 20);
    li_label_boundary(b, plane(0.1, 0.05, 8), plane(0.1, 0.05, 8.02), u, o);
    EXPECT_EQ(b.type, LiBoundaryType::kCoplanar);
    EXPECT_LT(b.energy[0], 1e-3);
  }
  {
    // Floor meeting a wall along x = 9.5: equal disparity on the boundary,
    // different slopes: hinge.
    LiBoundary b;
    b.moments = column(9, 0, 20);
    li_label_boundary(b, plane(0.8, 0, 10 - 0.8 * 9.5), plane(0, 0, 10), u, o);
    EXPECT_EQ(b.type, LiBoundaryType::kHinge);
    EXPECT_NEAR(b.energy[1], o.lambda_hinge, 1e-6);
  }
  {
    // A small step (1 px of disparity) is not worth an occlusion: co-planar or hinge.
    LiBoundary b;
    b.moments = column(9, 0, 20);
    li_label_boundary(b, plane(0, 0, 11), plane(0, 0, 10), u, o);
    EXPECT_FALSE(is_occlusion(b.type));
  }
  {
    LiBoundary b;
    b.moments = column(9, 0, 20);
    LiPlane none;
    li_label_boundary(b, none, plane(0, 0, 10), u, o);
    EXPECT_EQ(b.type, LiBoundaryType::kUnknown);
  }
}

// A wall (d = 10) cut into 10 x 10 superpixels with a fronto-parallel box
// (d = 25) covering superpixel columns 2-4 and rows 1-3.
struct BoxScene {
  cv::Mat labels;
  std::vector<LiPlane> planes;
  static constexpr int kCols = 8, kRows = 6, kS = 10;
  static bool box(int cx, int cy) { return cx >= 2 && cx <= 4 && cy >= 1 && cy <= 3; }
  BoxScene() {
    labels.create(kRows * kS, kCols * kS, CV_32SC1);
    for (int y = 0; y < labels.rows; ++y)
      for (int x = 0; x < labels.cols; ++x) labels.at<int>(y, x) = (y / kS) * kCols + x / kS;
    for (int cy = 0; cy < kRows; ++cy)
      for (int cx = 0; cx < kCols; ++cx) planes.push_back(plane(0, 0, box(cx, cy) ? 25 : 10));
  }
};

TEST(LiBoundaries, OcclusionAlongTheBoxOutlineOnly) {
  BoxScene s;
  const LiBoundaries b = li_label_boundaries(s.labels, s.planes, {cv::Rect(0, 0, s.labels.cols, s.labels.rows)},
                                             LiOptions());
  // 8 x 6 grid: 7*6 vertical + 8*5 horizontal adjacencies.
  EXPECT_EQ(b.list.size(), 7u * 6u + 8u * 5u);
  int occlusions = 0;
  for (const LiBoundary& e : b.list) {
    const int ax = e.i % BoxScene::kCols, ay = e.i / BoxScene::kCols;
    const int bx = e.j % BoxScene::kCols, by = e.j / BoxScene::kCols;
    const bool outline = BoxScene::box(ax, ay) != BoxScene::box(bx, by);
    EXPECT_EQ(is_occlusion(e.type), outline) << e.i << "-" << e.j;
    if (outline) {
      ++occlusions;
      // The box side is the front one.
      const bool i_front = BoxScene::box(ax, ay);
      EXPECT_EQ(e.type, i_front ? LiBoundaryType::kLeftOcclusion : LiBoundaryType::kRightOcclusion);
    } else {
      EXPECT_EQ(e.type, LiBoundaryType::kCoplanar);
    }
  }
  EXPECT_EQ(occlusions, 2 * 3 + 2 * 3);  // the box's perimeter in superpixel edges
}

TEST(LiRegions, RaysFromBoxPointsStopAtItsOutline) {
  BoxScene s;
  const cv::Rect all(0, 0, s.labels.cols, s.labels.rows);
  const LiBoundaries b = li_label_boundaries(s.labels, s.planes, {all}, LiOptions());
  // Dynamic points inside the box (pixels 20..49 x 10..39), one cluster.
  std::vector<cv::Point2f> pts{{25, 15}, {40, 20}, {33, 33}, {45, 36}, {22, 28}};
  LiCluster c;
  c.members = {0, 1, 2, 3, 4};
  c.roi = all;
  LiOptions o;
  const auto regions = li_dynamic_rectangles(pts, {c}, s.labels, b, o);
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_TRUE(regions[0].dynamic);
  EXPECT_EQ(regions[0].hit_directions, 4);
  EXPECT_EQ(regions[0].rect, cv::Rect(20, 10, 30, 30));  // exactly the box

  // Points on the wall above and below-right of the box: no ray meets an
  // occlusion boundary, so the cluster is a false alarm (Sec. IV-A).
  std::vector<cv::Point2f> wall{{70, 5}, {72, 8}, {75, 52}, {71, 55}, {78, 50}};
  const auto r2 = li_dynamic_rectangles(wall, {c}, s.labels, b, o);
  ASSERT_EQ(r2.size(), 1u);
  EXPECT_EQ(r2[0].hit_directions, 0);
  EXPECT_FALSE(r2[0].dynamic);
  EXPECT_TRUE(r2[0].rect.empty());
}

TEST(LiRegions, ForegroundOnlyLeavesTheFartherBackground) {
  // A 40 x 30 rectangle over an object at disparity 20 (its left half) in
  // front of a wall at disparity 5 (its right half); a hole without
  // disparity in the wall part; a floor strip at 19 (as near as the object).
  cv::Mat disparity(60, 80, CV_32FC1, cv::Scalar(5.f));
  disparity(cv::Rect(10, 10, 20, 30)).setTo(20.f);
  disparity(cv::Rect(35, 15, 5, 5)).setTo(0.f);
  disparity(cv::Rect(30, 35, 20, 5)).setTo(19.f);
  const cv::Rect rect(10, 10, 40, 30);
  LiOptions o;
  cv::Mat paper(disparity.size(), CV_8UC1, cv::Scalar(0));
  li_mark_region(paper, rect, disparity, 20.f, o);  // off: the whole rectangle, as the paper
  EXPECT_EQ(cv::countNonZero(paper), rect.area());

  o.foreground_only = true;  // foreground_margin_px 2: disparity >= 18 or none
  o.foreground_band_px = 0;
  cv::Mat fg(disparity.size(), CV_8UC1, cv::Scalar(0));
  li_mark_region(fg, rect, disparity, 20.f, o);
  EXPECT_EQ(cv::countNonZero(fg(cv::Rect(10, 10, 20, 30))), 20 * 30);  // the object
  EXPECT_EQ(cv::countNonZero(fg(cv::Rect(35, 15, 5, 5))), 25);         // no disparity: marked
  EXPECT_EQ(cv::countNonZero(fg(cv::Rect(30, 35, 20, 5))), 100);       // as near as the object
  EXPECT_EQ(cv::countNonZero(fg), 20 * 30 + 25 + 100);                 // not the wall
  EXPECT_EQ(cv::countNonZero(fg(cv::Rect(0, 0, 80, 10))), 0);          // nothing outside

  o.foreground_band_px = 3;  // and the wall within 3 px of those, inside the rectangle
  cv::Mat band(disparity.size(), CV_8UC1, cv::Scalar(0));
  li_mark_region(band, rect, disparity, 20.f, o);
  EXPECT_EQ(cv::countNonZero(band(cv::Rect(30, 10, 3, 25))), 3 * 25);  // beside the object
  EXPECT_EQ(band.at<unsigned char>(25, 35), 0);                         // 6 px from all: not
  EXPECT_EQ(band.at<unsigned char>(12, 44), 0);
  EXPECT_EQ(cv::countNonZero(band(cv::Rect(0, 0, 80, 10))), 0);        // still nothing outside
  EXPECT_GT(cv::countNonZero(band), cv::countNonZero(fg));
  o.foreground_band_px = 0;

  cv::Mat unknown(disparity.size(), CV_8UC1, cv::Scalar(0));  // no object disparity: the rectangle
  li_mark_region(unknown, rect, disparity, 0.f, o);
  EXPECT_EQ(cv::countNonZero(unknown), rect.area());
  cv::Mat clipped(disparity.size(), CV_8UC1, cv::Scalar(0));  // partly outside the image
  li_mark_region(clipped, cv::Rect(70, 50, 30, 30), disparity, 20.f, o);
  EXPECT_EQ(cv::countNonZero(clipped), 0);
}

}  // namespace
}  // namespace dynaorb::dynamic
