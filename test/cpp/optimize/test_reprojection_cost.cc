// The analytic Jacobians of bundle adjustment's split-pose cost (src/optimize/reprojection_cost.h)
// against central differences of the residual along the manifolds' tangent directions: what
// Ceres uses is J_ambient * PlusJacobian, so that product is what is checked, for a stereo
// observation (3 rows) and a monocular one padded to 3 rows (the third row and its Jacobians
// must be exactly zero). The residuals must agree with the single-block monocular BaCost.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "../../../src/optimize/reprojection_cost.h"

namespace {

using dynaorb::optimize::Intrinsics;
using dynaorb::optimize::Observation;
using namespace dynaorb::optimize::detail;  // NOLINT: the costs and manifolds under test

using Pose = std::array<double, 7>;  // [qx qy qz qw tx ty tz]

struct CostCase {
  Intrinsics K{500, 510, 320, 240, 40};
  Pose pose{};
  Eigen::Vector3d X{0.4, -0.3, 3.5};
  Observation obs;
};

CostCase make_setup(bool stereo) {
  CostCase s;
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, -1, 0.4).normalized()));
  s.pose = {q.x(), q.y(), q.z(), q.w(), 0.1, -0.2, 0.3};
  s.obs.uv = {350.5, 180.25};
  s.obs.inv_sigma2 = 1 / (1.2 * 1.2);
  if (stereo) s.obs.u_right = 341.0;
  return s;
}

// Residual at the pose moved by (w, v) on the split layout and the point moved by dX.
template <int N>
Eigen::Vector3d residual_at(const CostCase& s, const Eigen::Vector3d& w, const Eigen::Vector3d& v,
                            const Eigen::Vector3d& dX) {
  const BaSplitCost<3, N> cost(s.K, s.obs);
  Pose moved = s.pose;
  RotationManifold().Plus(s.pose.data(), w.data(), moved.data());
  for (int i = 0; i < 3; ++i) moved[4 + i] += v[i];
  const Eigen::Vector3d X = s.X + dX;
  const double* params[] = {moved.data(), moved.data() + 4, X.data()};
  Eigen::Vector3d r;
  EXPECT_TRUE(cost.Evaluate(params, r.data(), nullptr));
  return r;
}

template <int N>
void check_jacobians(const CostCase& s) {
  const BaSplitCost<3, N> cost(s.K, s.obs);
  Eigen::Matrix<double, 3, 4, Eigen::RowMajor> J_rot;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> J_t, J_X;
  double* jacobians[] = {J_rot.data(), J_t.data(), J_X.data()};
  const double* params[] = {s.pose.data(), s.pose.data() + 4, s.X.data()};
  Eigen::Vector3d r;
  ASSERT_TRUE(cost.Evaluate(params, r.data(), jacobians));
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  EXPECT_LT((r - residual_at<N>(s, zero, zero, zero)).norm(), 1e-9);  // Plus(0) renormalises q

  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus;
  ASSERT_TRUE(RotationManifold().PlusJacobian(s.pose.data(), plus.data()));
  const Eigen::Matrix3d J_w = J_rot * plus;  // what Ceres uses: the tangent Jacobian

  const double h = 1e-6;
  for (int c = 0; c < 3; ++c) {
    SCOPED_TRACE(c);
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(c) * h;
    const Eigen::Vector3d d_w = (residual_at<N>(s, e, zero, zero) - residual_at<N>(s, -e, zero, zero)) / (2 * h);
    const Eigen::Vector3d d_v = (residual_at<N>(s, zero, e, zero) - residual_at<N>(s, zero, -e, zero)) / (2 * h);
    const Eigen::Vector3d d_X = (residual_at<N>(s, zero, zero, e) - residual_at<N>(s, zero, zero, -e)) / (2 * h);
    // Entries are O(100) (fx / z with z = 3.5 m, times the pixel weight): 1e-5 relative.
    EXPECT_LT((J_w.col(c) - d_w).norm(), 1e-3) << J_w.col(c).transpose() << " vs " << d_w.transpose();
    EXPECT_LT((J_t.col(c) - d_v).norm(), 1e-3) << J_t.col(c).transpose() << " vs " << d_v.transpose();
    EXPECT_LT((J_X.col(c) - d_X).norm(), 1e-3) << J_X.col(c).transpose() << " vs " << d_X.transpose();
    EXPECT_GT(J_X.col(c).norm() + J_t.col(c).norm(), 1.0);  // not a trivially zero Jacobian
  }
  EXPECT_EQ(J_rot.col(3).norm(), 0.0);  // the lifted convention: the 4th column is unused
  if (N == 2) {
    EXPECT_EQ(r[2], 0.0);
    EXPECT_EQ(J_rot.row(2).norm() + J_t.row(2).norm() + J_X.row(2).norm(), 0.0);
  } else {
    EXPECT_NE(r[2], 0.0);
  }
}

TEST(BaSplitCost, StereoJacobiansMatchCentralDifferences) { check_jacobians<3>(make_setup(true)); }

TEST(BaSplitCost, PaddedMonocularJacobiansMatchCentralDifferences) {
  check_jacobians<2>(make_setup(false));
}

TEST(BaSplitCost, PaddedMonocularResidualEqualsTheSingleBlockCost) {
  const CostCase s = make_setup(false);
  const BaSplitCost<3, 2> split(s.K, s.obs);
  const BaCost<2> whole(s.K, s.obs);
  double r_split[3], r_whole[2];
  const double* p_split[] = {s.pose.data(), s.pose.data() + 4, s.X.data()};
  const double* p_whole[] = {s.pose.data(), s.X.data()};
  ASSERT_TRUE(split.Evaluate(p_split, r_split, nullptr));
  ASSERT_TRUE(whole.Evaluate(p_whole, r_whole, nullptr));
  EXPECT_NEAR(r_split[0], r_whole[0], 1e-9);
  EXPECT_NEAR(r_split[1], r_whole[1], 1e-9);
  EXPECT_GT(std::abs(r_whole[0]) + std::abs(r_whole[1]), 1.0);
}

TEST(RotationManifold, PlusThenMinusIsTheStep) {
  const CostCase s = make_setup(true);
  const Eigen::Vector3d w(0.01, -0.02, 0.015);
  std::array<double, 4> moved{};
  RotationManifold m;
  ASSERT_TRUE(m.Plus(s.pose.data(), w.data(), moved.data()));
  Eigen::Vector3d back;
  ASSERT_TRUE(m.Minus(moved.data(), s.pose.data(), back.data()));
  EXPECT_LT((back - w).norm(), 1e-12);
  EXPECT_NEAR(Eigen::Map<const Eigen::Quaterniond>(moved.data()).norm(), 1.0, 1e-12);
}

}  // namespace
