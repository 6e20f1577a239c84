#pragma once
// Private to src/optimize: the pose parameterisation and the reprojection residuals shared by the
// motion-only optimiser (pose_optimizer.cc) and local bundle adjustment (bundle_adjuster.cc).
//
// Pose parameterisation (bundle adjustment; the motion-only optimiser solves each round for the
// same left-perturbation delta on a plain 6-vector and applies it with PoseManifold::Plus). A
// pose T_cw is one 7-double parameter block [qx qy qz qw tx ty tz]
// (Eigen quaternion order) with the 6-DoF manifold PoseManifold below, whose update is a left
// perturbation
//     R <- Exp(w) * R,   t <- Exp(w) * t + v,   delta = [w, v]
// i.e. X_c <- Exp(w) * X_c + v for every point. Why this and not EigenQuaternionManifold +
// a separate translation block:
//  - the residual Jacobians w.r.t. [w, v] are closed-form and cheap (-[X_c]x and I composed with
//    the projection Jacobian), they only need the camera-frame point already computed for the
//    residual, and the left perturbation keeps them well conditioned whatever R is;
//  - with a quaternion block, Ceres needs the 2x4 Jacobian w.r.t. the quaternion coefficients
//    and multiplies it by the 4x3 PlusJacobian for every residual, every iteration: more flops
//    and a second parameter block per pose (larger Schur structure in BA).
// Any smooth retraction with exact Jacobians gives the same LM steps to first order, so the
// iteration counts are alike; what differs is the cost of an iteration, lowest with this one.
// The cost functions therefore write the tangent-space (6-column) Jacobian into the first six
// columns of the 7-column "ambient" Jacobian (last column zero) and PoseManifold reports
// PlusJacobian = [I6; 0]. Ceres only ever uses the product J_ambient * PlusJacobian, which is
// then exactly the tangent Jacobian. (The same "lifted Jacobian" convention is common in
// visual-inertial solvers; it is correct for Ceres' trust-region minimiser, but a numeric
// GradientChecker on the ambient Jacobian would not agree with it.)
// Bundle adjustment with stereo observations splits the pose into a rotation block
// (RotationManifold: the same left perturbation of R, lifted the same way) and a plain
// translation block, t <- t + v (BaSplitCost; bundle_adjuster.cc says why).
//
// Residuals (information = inv_sigma2 * I, as in ORB-SLAM2):
//   mono:   r = s * ([u v] - [fx x/z + cx, fy y/z + cy]),                 s = sqrt(inv_sigma2)
//   stereo: r = s * ([u v ur] - [.., .., fx x/z + cx - bf/z])
// so chi2 = |r|^2 = e^T * inv_sigma2 * e. A point at depth z < kMinDepth (behind or on the camera
// plane) is projected as if at kMinDepth: the residual is large but finite and continuous, and
// the optimisers classify z <= 0 as outlier separately.
#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "dynaorb/optimize/types.h"

namespace dynaorb::optimize::detail {

constexpr double kMinDepth = 1e-6;

// ---------------------------------------------------------------- pose block <-> Isometry3d
inline void pose_to_params(const Eigen::Isometry3d& T, double* p) {
  Eigen::Quaterniond q(T.rotation());
  q.normalize();
  p[0] = q.x();
  p[1] = q.y();
  p[2] = q.z();
  p[3] = q.w();
  p[4] = T.translation().x();
  p[5] = T.translation().y();
  p[6] = T.translation().z();
}

inline Eigen::Isometry3d params_to_pose(const double* p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(p[3], p[0], p[1], p[2]).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(p[4], p[5], p[6]);
  return T;
}

// Exp / Log on SO(3) via unit quaternions (small-angle safe).
inline Eigen::Quaterniond so3_exp(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  if (theta < 1e-10)
    return Eigen::Quaterniond(1, 0.5 * w.x(), 0.5 * w.y(), 0.5 * w.z()).normalized();
  const Eigen::Vector3d a = std::sin(0.5 * theta) / theta * w;
  return Eigen::Quaterniond(std::cos(0.5 * theta), a.x(), a.y(), a.z());
}

inline Eigen::Vector3d so3_log(Eigen::Quaterniond q) {
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // shortest rotation
  const double sn = q.vec().norm();
  if (sn < 1e-10) return 2.0 * q.vec() / q.w();
  return 2.0 * std::atan2(sn, q.w()) / sn * q.vec();
}

// ---------------------------------------------------------------- manifolds
// The lifted-Jacobian part shared by the manifolds below (see the file comment): the first
// kTangent ambient coordinates carry the tangent Jacobian, so PlusJacobian = [I; 0] (row-major
// kAmbient x kTangent) and MinusJacobian = [I 0].
template <int kAmbient, int kTangent>
class LiftedManifold : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kAmbient; }
  int TangentSize() const override { return kTangent; }

  bool PlusJacobian(const double* /*x*/, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, kAmbient, kTangent, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.template topRows<kTangent>().setIdentity();
    return true;
  }

  bool RightMultiplyByPlusJacobian(const double* /*x*/, const int num_rows, const double* ambient,
                                   double* tangent) const override {
    for (int r = 0; r < num_rows; ++r)
      for (int c = 0; c < kTangent; ++c) tangent[r * kTangent + c] = ambient[r * kAmbient + c];
    return true;
  }

  bool MinusJacobian(const double* /*x*/, double* jacobian) const override {
    Eigen::Map<Eigen::Matrix<double, kTangent, kAmbient, Eigen::RowMajor>> J(jacobian);
    J.setZero();
    J.template leftCols<kTangent>().setIdentity();
    return true;
  }
};

// The left rotation update both manifolds below use: q_out <- Exp(w) * q (renormalised). Returns
// Exp(w), for a caller that moves a translation with it.
inline Eigen::Quaterniond rotate_left(const double* q, const double* w, double* q_out) {
  using ConstQuat = Eigen::Map<const Eigen::Quaterniond>;
  const Eigen::Quaterniond dq = so3_exp(Eigen::Vector3d(w[0], w[1], w[2]));
  Eigen::Map<Eigen::Quaterniond> out(q_out);
  out = (dq * ConstQuat(q)).normalized();
  return dq;
}

// Its inverse: dq = qy * qx^-1 (renormalised), whose Log is the tangent w with qy = Exp(w) * qx.
inline Eigen::Quaterniond left_difference(const double* qy, const double* qx) {
  using ConstQuat = Eigen::Map<const Eigen::Quaterniond>;
  return (ConstQuat(qy) * ConstQuat(qx).conjugate()).normalized();
}

// The whole pose [q t], delta = [w, v]: R <- Exp(w) R, t <- Exp(w) t + v.
class PoseManifold final : public LiftedManifold<7, 6> {
 public:
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    const Eigen::Quaterniond dq = rotate_left(x, delta, x_plus_delta);
    Eigen::Map<const Eigen::Vector3d> t(x + 4), v(delta + 3);
    Eigen::Map<Eigen::Vector3d> t_out(x_plus_delta + 4);
    t_out = dq * t + v;
    return true;
  }

  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    const Eigen::Quaterniond dq = left_difference(y, x);
    Eigen::Map<const Eigen::Vector3d> ty(y + 4), tx(x + 4);
    const Eigen::Vector3d w = so3_log(dq);
    const Eigen::Vector3d v = ty - dq * tx;
    for (int i = 0; i < 3; ++i) {
      y_minus_x[i] = w[i];
      y_minus_x[3 + i] = v[i];
    }
    return true;
  }
};

// Rotation-only block [qx qy qz qw] with the same left perturbation q <- Exp(w) * q. Bundle
// adjustment with stereo observations gives each pose a rotation block and a plain 3-double
// translation block (see BaSplitCost).
class RotationManifold final : public LiftedManifold<4, 3> {
 public:
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    rotate_left(x, delta, x_plus_delta);
    return true;
  }

  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    Eigen::Map<Eigen::Vector3d> out(y_minus_x);
    out = so3_log(left_difference(y, x));
    return true;
  }
};

// ---------------------------------------------------------------- residuals
// Weighted residual r (N = 2 mono, 3 stereo) of one observation of the camera-frame point Xc and,
// if P is given, dr/dXc (N x 3).
// s = sqrt(obs.inv_sigma2), passed in so that cost functions compute it once.
template <int N>
inline void reprojection_residual(const Intrinsics& K, const Observation& obs, double s,
                                  const Eigen::Vector3d& Xc, double* r,
                                  Eigen::Matrix<double, N, 3>* dr_dXc) {
  const bool clamped = Xc.z() < kMinDepth;
  const double z = clamped ? kMinDepth : Xc.z();
  const double iz = 1.0 / z;
  const double u = K.fx * Xc.x() * iz + K.cx;
  const double v = K.fy * Xc.y() * iz + K.cy;
  r[0] = s * (obs.uv.x() - u);
  r[1] = s * (obs.uv.y() - v);
  if constexpr (N == 3) r[2] = s * (obs.u_right - (u - K.bf * iz));
  if (!dr_dXc) return;
  // d(pred)/dXc; in the clamped region z is a constant, so its column is zero.
  const double iz2 = clamped ? 0.0 : iz * iz;
  Eigen::Matrix<double, N, 3>& J = *dr_dXc;
  J(0, 0) = -s * K.fx * iz;
  J(0, 1) = 0;
  J(0, 2) = s * K.fx * Xc.x() * iz2;
  J(1, 0) = 0;
  J(1, 1) = -s * K.fy * iz;
  J(1, 2) = s * K.fy * Xc.y() * iz2;
  if constexpr (N == 3) {
    J(2, 0) = J(0, 0);
    J(2, 1) = 0;
    J(2, 2) = s * (K.fx * Xc.x() - K.bf) * iz2;
  }
}

// Ceres' rho for HuberLoss(a) with a^2 = delta2, applied to s = chi2.
inline double huber(double s, double delta2) {
  return s <= delta2 ? s : 2.0 * std::sqrt(delta2 * s) - delta2;
}

// chi2 = e^T * inv_sigma2 * e of one observation (mono or stereo by obs.stereo()).
inline double observation_chi2(const Intrinsics& K, const Observation& obs,
                               const Eigen::Vector3d& Xc) {
  double r[3];
  const double s = std::sqrt(obs.inv_sigma2);
  if (obs.stereo()) {
    reprojection_residual<3>(K, obs, s, Xc, r, nullptr);
    return r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
  }
  reprojection_residual<2>(K, obs, s, Xc, r, nullptr);
  return r[0] * r[0] + r[1] * r[1];
}

// Xc = R * Xw + t from a 7-double pose block.
inline Eigen::Vector3d transform_point(const double* pose, const Eigen::Vector3d& Xw) {
  Eigen::Map<const Eigen::Quaterniond> q(pose);
  return q * Xw + Eigen::Vector3d(pose[4], pose[5], pose[6]);
}

// Writes the rotation part of row i of a pose Jacobian: dr_dXc.row(i) * (-[X]x), where X is the
// rotated point (dX/dw = -[X]x for a left update Exp(w) R), into out[0..2].
// -[X]x = [[0, z, -y], [-z, 0, x], [y, -x, 0]].
template <int N>
inline void rotation_jacobian_row(const Eigen::Matrix<double, N, 3>& dr_dXc, int i,
                                  const Eigen::Vector3d& X, double* out) {
  const double a = dr_dXc(i, 0), b = dr_dXc(i, 1), c = dr_dXc(i, 2);
  out[0] = -b * X.z() + c * X.y();
  out[1] = a * X.z() - c * X.x();
  out[2] = -a * X.y() + b * X.x();
}

// Writes the pose Jacobian (tangent [w, v] in the first six columns, last column zero) of a
// residual whose camera-frame Jacobian is dr_dXc; row-major N x 7. Uses dXc/dw = -[Xc]x,
// dXc/dv = I.
template <int N>
inline void pose_jacobian(const Eigen::Matrix<double, N, 3>& dr_dXc, const Eigen::Vector3d& Xc,
                          double* out) {
  for (int i = 0; i < N; ++i) {
    double* row = out + 7 * i;
    rotation_jacobian_row<N>(dr_dXc, i, Xc, row);
    row[3] = dr_dXc(i, 0);
    row[4] = dr_dXc(i, 1);
    row[5] = dr_dXc(i, 2);
    row[6] = 0;
  }
}

// Bundle-adjustment cost of a problem with only monocular observations (N = 2): pose block (7)
// and point block (3). Problems with stereo observations use BaSplitCost.
template <int N>
class BaCost final : public ceres::SizedCostFunction<N, 7, 3> {
 public:
  BaCost(const Intrinsics& K, const Observation& obs)
      : K_(K), obs_(obs), s_(std::sqrt(obs.inv_sigma2)) {}

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const Eigen::Matrix3d R = Eigen::Map<const Eigen::Quaterniond>(params[0]).toRotationMatrix();
    const Eigen::Vector3d Xc = R * Eigen::Map<const Eigen::Vector3d>(params[1]) +
                               Eigen::Map<const Eigen::Vector3d>(params[0] + 4);
    if (!jacobians) {
      reprojection_residual<N>(K_, obs_, s_, Xc, residuals, nullptr);
      return true;
    }
    Eigen::Matrix<double, N, 3> dr_dXc;
    reprojection_residual<N>(K_, obs_, s_, Xc, residuals, &dr_dXc);
    if (jacobians[0]) pose_jacobian<N>(dr_dXc, Xc, jacobians[0]);
    if (jacobians[1]) {
      // dXc/dXw = R.
      Eigen::Map<Eigen::Matrix<double, N, 3, Eigen::RowMajor>> Jp(jacobians[1]);
      Jp.noalias() = dr_dXc * R;
    }
    return true;
  }

 private:
  Intrinsics K_;
  Observation obs_;
  double s_;  // sqrt(inv_sigma2)
};

// Bundle-adjustment cost on a split pose: rotation block (4, RotationManifold), translation block
// (3, plain) and point block (3), with R residual rows of which the observation fills N (N = 2
// mono, 3 stereo; rows N..R-1 are zero with zero Jacobians, so they change neither the cost nor
// the normal equations). Every residual block of a problem then has the same number of rows and
// every camera block 3 tangent dimensions, which lets Ceres' Schur eliminator use its
// fixed-size <2, 3, 3> or <3, 3, 3> kernels; a mix of 2- and 3-row residuals or 6-dimensional
// pose blocks alongside 3-row ones (no <3, 3, 6> kernel) falls back to its dynamic-size code,
// which took most of local BA's time.
// Xc = R * Xw + t; with R <- Exp(w) R and t <- t + v: dXc/dw = -[R * Xw]x, dXc/dv = I.
template <int R, int N>
class BaSplitCost final : public ceres::SizedCostFunction<R, 4, 3, 3> {
  static_assert(N <= R, "the observation has at most R rows");

 public:
  BaSplitCost(const Intrinsics& K, const Observation& obs)
      : K_(K), obs_(obs), s_(std::sqrt(obs.inv_sigma2)) {}

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const Eigen::Matrix3d Rm = Eigen::Map<const Eigen::Quaterniond>(params[0]).toRotationMatrix();
    const Eigen::Vector3d Xr = Rm * Eigen::Map<const Eigen::Vector3d>(params[2]);
    const Eigen::Vector3d Xc = Xr + Eigen::Map<const Eigen::Vector3d>(params[1]);
    for (int i = N; i < R; ++i) residuals[i] = 0;
    if (!jacobians) {
      reprojection_residual<N>(K_, obs_, s_, Xc, residuals, nullptr);
      return true;
    }
    Eigen::Matrix<double, N, 3> dr_dXc;
    reprojection_residual<N>(K_, obs_, s_, Xc, residuals, &dr_dXc);
    if (jacobians[0]) {
      Eigen::Map<Eigen::Matrix<double, R, 4, Eigen::RowMajor>> J(jacobians[0]);
      J.setZero();
      for (int i = 0; i < N; ++i) rotation_jacobian_row<N>(dr_dXc, i, Xr, jacobians[0] + 4 * i);
    }
    if (jacobians[1]) {
      Eigen::Map<Eigen::Matrix<double, R, 3, Eigen::RowMajor>> J(jacobians[1]);
      J.setZero();
      J.template topRows<N>() = dr_dXc;
    }
    if (jacobians[2]) {
      Eigen::Map<Eigen::Matrix<double, R, 3, Eigen::RowMajor>> J(jacobians[2]);
      J.setZero();
      J.template topRows<N>().noalias() = dr_dXc * Rm;
    }
    return true;
  }

 private:
  Intrinsics K_;
  Observation obs_;
  double s_;  // sqrt(inv_sigma2)
};

}  // namespace dynaorb::optimize::detail
