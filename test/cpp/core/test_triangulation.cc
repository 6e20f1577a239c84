// Linear triangulation (core/triangulation.h): the SVD solve and the
// initialiser's normal-equation solve give the same point on two-view
// geometry of the initialiser's scale (reference camera at the origin, unit
// baseline), down to a parallax of about 0.01 degree, and both refuse
// non-finite input and points at infinity.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "dynaorb/core/triangulation.h"

namespace {

using P34 = Eigen::Matrix<double, 3, 4>;

P34 camera(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  P34 P;
  P.leftCols<3>() = R;
  P.col(3) = t;
  return P;
}

TEST(Triangulation, NormalEquationsAgreeWithTheSvdAtUnitBaseline) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  std::normal_distribution<double> noise(0, 1e-3);  // about 0.5 px at fx 500
  const P34 P1 = camera(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  int compared = 0;
  double worst = 0;
  for (int i = 0; i < 5000; ++i) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.1 * U(rng), Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized()).toRotationMatrix();
    const Eigen::Vector3d t = Eigen::Vector3d(U(rng), 0.3 * U(rng), 0.3 * U(rng)).normalized();
    // Depths 2-200 baselines: parallax from about 30 down to 0.3 degrees and below.
    const Eigen::Vector3d X(U(rng), U(rng), 1);
    const Eigen::Vector3d Xw = X * std::pow(10.0, 0.3 + 2 * (U(rng) + 1) / 2);
    const P34 P2 = camera(R, t);
    const Eigen::Vector2d x1 = (P1 * Xw.homogeneous()).hnormalized() + Eigen::Vector2d(noise(rng), noise(rng));
    const Eigen::Vector2d x2 = (P2 * Xw.homogeneous()).hnormalized() + Eigen::Vector2d(noise(rng), noise(rng));
    Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
    const bool ok_a = dynaorb::triangulate_dlt(x1, P1, x2, P2, a);
    const bool ok_b = dynaorb::triangulate_dlt_unit_baseline(x1, P1, x2, P2, b);
    ASSERT_EQ(ok_a, ok_b) << i;
    if (!ok_a) continue;
    ++compared;
    worst = std::max(worst, (a - b).norm() / a.norm());
  }
  EXPECT_GT(compared, 4900);
  EXPECT_LT(worst, 1e-8);
}

TEST(Triangulation, NonFiniteInputAndPointsAtInfinityAreRefused) {
  const P34 P1 = camera(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  const P34 P2 = camera(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-1, 0, 0));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d X;
  for (auto* f : {&dynaorb::triangulate_dlt, &dynaorb::triangulate_dlt_unit_baseline}) {
    EXPECT_FALSE(f(Eigen::Vector2d(nan, 0), P1, Eigen::Vector2d(0.1, 0), P2, X));
    // The same ray from both cameras after a pure translation: no parallax, at infinity.
    EXPECT_FALSE(f(Eigen::Vector2d(0.2, 0.1), P1, Eigen::Vector2d(0.2, 0.1), P2, X));
    // A point 5 baselines ahead comes back.
    ASSERT_TRUE(f(Eigen::Vector2d(0.2, 0.1), P1, Eigen::Vector2d(0.0, 0.1), P2, X));
    EXPECT_NEAR(X.z(), 5.0, 1e-9);
  }
}

}  // namespace
