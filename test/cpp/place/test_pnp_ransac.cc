// PnP RANSAC on synthetic matches: the pose under pixel noise and outliers,
// per-level thresholds, too few matches, and repeatability.
#include <gtest/gtest.h>

#include <random>

#include "dynaorb/place/pnp_ransac.h"

namespace dynaorb::place {
namespace {

const PinholeK kK{500, 500, 320, 240};

struct Scene {
  std::vector<PnpMatch> matches;
  std::vector<bool> outlier;
  Eigen::Isometry3d T_cw = Eigen::Isometry3d::Identity();
};

// n points 2-10 m in front of a camera at T_cw; a share of the matches get a
// random pixel; keypoint levels 0..7 (sigma 1.2^level), noise at that sigma.
Scene scene(int n, double outlier_share, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> g(0, 1);
  Scene s;
  s.T_cw.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  s.T_cw.translation() = Eigen::Vector3d(0.5, -0.2, 1.0);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d pc(u(rng) * 3, u(rng) * 2, 6 + 4 * u(rng));
    const int level = i % 8;
    const double sigma = std::pow(1.2, level);
    Eigen::Vector2d px(kK.fx * pc.x() / pc.z() + kK.cx + 0.5 * sigma * g(rng),
                       kK.fy * pc.y() / pc.z() + kK.cy + 0.5 * sigma * g(rng));
    const bool bad = (u(rng) + 1) / 2 < outlier_share;
    if (bad) px = Eigen::Vector2d(320 + 300 * u(rng), 240 + 220 * u(rng));
    s.matches.push_back({s.T_cw.inverse() * pc, px, sigma * sigma});
    s.outlier.push_back(bad);
  }
  return s;
}

TEST(PnpRansac, FindsThePoseAmongHalfOutliers) {
  const Scene s = scene(200, 0.5, 1);
  const PnpRansacResult r = pnp_ransac(s.matches, kK);
  ASSERT_TRUE(r.ok);
  const Eigen::Isometry3d d = r.T_cw * s.T_cw.inverse();
  EXPECT_LT(d.translation().norm(), 0.05);
  EXPECT_LT(Eigen::AngleAxisd(d.linear()).angle(), 0.005);
  int agree = 0, true_inliers = 0;
  for (size_t i = 0; i < s.matches.size(); ++i) {
    true_inliers += !s.outlier[i];
    agree += r.inlier[i] == !s.outlier[i];
  }
  EXPECT_GE(agree, 0.95 * s.matches.size());
  EXPECT_GE(r.inliers, 0.9 * true_inliers);
  EXPECT_LE(r.iterations, PnpRansacOptions{}.max_iterations);
}

TEST(PnpRansac, StopsEarlyWhenMostMatchesAreInliers) {
  const PnpRansacResult r = pnp_ransac(scene(100, 0.0, 2).matches, kK);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(r.iterations, 20);
}

TEST(PnpRansac, RefusesTooFewMatchesOrInliers) {
  EXPECT_FALSE(pnp_ransac(scene(9, 0.0, 3).matches, kK).ok);  // < min_inliers
  PnpRansacOptions o;
  o.min_inliers = 150;
  EXPECT_FALSE(pnp_ransac(scene(200, 0.5, 4).matches, kK, o).ok);
  EXPECT_FALSE(pnp_ransac({}, kK).ok);
}

TEST(PnpRansac, IsRepeatableForASeed) {
  const Scene s = scene(150, 0.6, 5);
  const PnpRansacResult a = pnp_ransac(s.matches, kK), b = pnp_ransac(s.matches, kK);
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_TRUE(a.T_cw.isApprox(b.T_cw));
}

}  // namespace
}  // namespace dynaorb::place
