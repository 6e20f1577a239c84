// EpipolarBand (src/match/epipolar_band.h) returns exactly the points that testing every point
// with the triangulation search's epipolar test would: random points with per-point limits,
// random lines of every slope (through the image and outside it), degenerate and non-finite
// lines, a non-finite point, duplicates and a single column of points.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "../../../src/match/epipolar_band.h"

namespace {

using dynaorb::match::EpipolarBand;

std::vector<int> brute_force(const std::vector<EpipolarBand::Point>& pts, const Eigen::Vector3d& l) {
  const double norm2 = l.x() * l.x() + l.y() * l.y();
  std::vector<int> ids;
  for (const auto& p : pts) {
    const double num = l.x() * p.x + l.y() * p.y + l.z();
    if (!(num * num / norm2 >= p.limit2)) ids.push_back(p.id);
  }
  return ids;
}

std::vector<EpipolarBand::Point> random_points(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> x(-20, 1260), y(-10, 390);
  std::uniform_int_distribution<int> octave(0, 7);
  std::vector<EpipolarBand::Point> pts;
  for (int i = 0; i < n; ++i)
    pts.push_back({x(rng), y(rng), 3.84 * std::pow(1.44, octave(rng)), 3 * i + 1});  // ids ascending
  return pts;
}

TEST(EpipolarBand, SamePointsAsTestingEveryOne) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> angle(0, M_PI), px(-100, 1350), py(-50, 420);
  const auto pts = random_points(rng, 2000);
  const EpipolarBand band(pts);
  std::vector<int> got;
  int non_empty = 0, total = 0;
  for (int t = 0; t < 2000; ++t) {
    // A line through a random point at a random angle, scaled as an F row would be.
    const double th = angle(rng), x0 = px(rng), y0 = py(rng), scale = std::pow(10.0, -4 + 3 * (t % 3));
    const Eigen::Vector3d l = scale * Eigen::Vector3d(std::sin(th), -std::cos(th), std::cos(th) * y0 - std::sin(th) * x0);
    band.near(l, &got);
    const std::vector<int> want = brute_force(pts, l);
    ASSERT_EQ(got, want) << "line " << l.transpose();
    non_empty += !want.empty();
    total += static_cast<int>(want.size());
  }
  EXPECT_GT(non_empty, 1500);
  EXPECT_LT(total, 2000 * 200);  // a band, not the image: the test is not trivially "all"
  // Axis-parallel lines.
  for (const Eigen::Vector3d& l : {Eigen::Vector3d(0, 1, -200), Eigen::Vector3d(1, 0, -600),
                                   Eigen::Vector3d(0, -2, 5), Eigen::Vector3d(3, 0, 7000)}) {
    band.near(l, &got);
    EXPECT_EQ(got, brute_force(pts, l)) << l.transpose();
  }
}

TEST(EpipolarBand, DegenerateLinesAndPointsTestEveryPoint) {
  std::mt19937 rng(5);
  auto pts = random_points(rng, 300);
  pts[17].x = std::numeric_limits<double>::quiet_NaN();
  pts[40] = pts[41];  // a duplicate position
  pts[41].id = 124;   // ids stay ascending
  const EpipolarBand band(pts);
  std::vector<int> got;
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& l : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(nan, 1, 2),
                                   Eigen::Vector3d(1, inf, 2), Eigen::Vector3d(0.3, 0.9, -150)}) {
    band.near(l, &got);
    EXPECT_EQ(got, brute_force(pts, l)) << l.transpose();
  }
  // The NaN point passes every test (NaN >= limit is false), as it would in the full scan.
  band.near(Eigen::Vector3d(0.3, 0.9, -150), &got);
  EXPECT_NE(std::find(got.begin(), got.end(), pts[17].id), got.end());
}

TEST(EpipolarBand, OneColumnAndNoPoints) {
  std::vector<EpipolarBand::Point> column;
  for (int i = 0; i < 50; ++i) column.push_back({100.0, 5.0 * i, 4.0, i});
  const EpipolarBand band(column);
  std::vector<int> got;
  for (const Eigen::Vector3d& l : {Eigen::Vector3d(1, 0, -100), Eigen::Vector3d(0, 1, -41), Eigen::Vector3d(1, 1, -200)}) {
    band.near(l, &got);
    EXPECT_EQ(got, brute_force(column, l)) << l.transpose();
    EXPECT_FALSE(got.empty());
  }
  const EpipolarBand empty({});
  empty.near(Eigen::Vector3d(1, 1, 1), &got);
  EXPECT_TRUE(got.empty());
}

}  // namespace
