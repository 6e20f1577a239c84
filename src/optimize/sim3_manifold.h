#pragma once
// Private to src/optimize: the Sim(3) parameter block, its manifold and the relative-pose
// residual of the essential graph (pose_graph.cc).
//
// A node is one 8-double block [qx qy qz qw tx ty tz s] (Eigen quaternion order, then the
// scale) holding S_iw. Its manifold updates on the left, S <- exp(delta) * S, delta in sim(3)
// ([rho, phi, sigma], tangent size 7), or with sigma = 0 (tangent size 6) for the SE(3) graph
// of stereo / RGB-D, which therefore keeps every node's scale exactly.
//
// Differentiation: automatic (Ceres Jets) through the templated exp / log / compose kernels of
// dynaorb/loop/sim3.h, both for the residual and for the manifold's PlusJacobian. The analytic
// Jacobian of the sim(3) log (the inverse of the left Jacobian of Sim(3), Strasdat's thesis
// App. A) is long and error-prone; the graph has only 2 blocks per residual and a few thousand
// nodes at most, so Jets cost little, and their derivatives are exact (no numeric
// differentiation as in g2o's EdgeSim3). The kernels keep value AND first derivative exact at
// phi = 0 / sigma = 0 (series branches), which matters here: every edge measured from the
// uncorrected poses starts exactly at the identity.
#include <ceres/autodiff_cost_function.h>
#include <ceres/autodiff_manifold.h>

#include <Eigen/Core>

#include "dynaorb/loop/sim3.h"

namespace dynaorb::optimize::detail {

// Functor for ceres::AutoDiffManifold: Plus(x, delta) = exp(delta) * x, Minus(y, x) =
// log(y * x^{-1}) (its first 6 components when the scale is fixed).
template <bool kFixScale>
struct Sim3PlusFunctor {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    T xi[7];
    for (int k = 0; k < 6; ++k) xi[k] = delta[k];
    xi[6] = kFixScale ? T(0) : delta[6];
    T E[8];
    loop::detail::sim3_exp(xi, E);
    loop::detail::sim3_compose(E, x, x_plus_delta);
    using std::sqrt;
    const T n = sqrt(x_plus_delta[0] * x_plus_delta[0] + x_plus_delta[1] * x_plus_delta[1] +
                     x_plus_delta[2] * x_plus_delta[2] + x_plus_delta[3] * x_plus_delta[3]);
    for (int k = 0; k < 4; ++k) x_plus_delta[k] /= n;
    if (kFixScale) x_plus_delta[7] = x[7];  // exactly, not e^0 * s
    return true;
  }

  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    T xi_inv[8], d[8], xi[7];
    loop::detail::sim3_inverse(x, xi_inv);
    loop::detail::sim3_compose(y, xi_inv, d);
    loop::detail::sim3_log(d, xi);
    for (int k = 0; k < (kFixScale ? 6 : 7); ++k) y_minus_x[k] = xi[k];
    return true;
  }
};

using Sim3Manifold = ceres::AutoDiffManifold<Sim3PlusFunctor<false>, 8, 7>;
using Se3ScaleFixedManifold = ceres::AutoDiffManifold<Sim3PlusFunctor<true>, 8, 6>;

// r = sqrt_info * log(S_ij * S_jw * S_iw^{-1}), blocks (S_iw, S_jw); sqrt_info^T sqrt_info =
// information.
struct Sim3EdgeCost {
  Sim3EdgeCost(const loop::Sim3& S_ij, const Eigen::Matrix<double, 7, 7>& sqrt_info)
      : sqrt_info_(sqrt_info) {
    loop::detail::to_array(S_ij, S_ij_);
  }

  template <typename T>
  bool operator()(const T* S_iw, const T* S_jw, T* residual) const {
    T Z[8], S_wi[8], ZS[8], E[8], xi[7];
    for (int k = 0; k < 8; ++k) Z[k] = T(S_ij_[k]);
    loop::detail::sim3_inverse(S_iw, S_wi);
    loop::detail::sim3_compose(Z, S_jw, ZS);
    loop::detail::sim3_compose(ZS, S_wi, E);
    loop::detail::sim3_log(E, xi);
    for (int r = 0; r < 7; ++r) {
      T acc(0);
      for (int c = 0; c < 7; ++c) acc += T(sqrt_info_(r, c)) * xi[c];
      residual[r] = acc;
    }
    return true;
  }

  static ceres::CostFunction* create(const loop::Sim3& S_ij,
                                     const Eigen::Matrix<double, 7, 7>& sqrt_info) {
    return new ceres::AutoDiffCostFunction<Sim3EdgeCost, 7, 8, 8>(
        new Sim3EdgeCost(S_ij, sqrt_info));
  }

 private:
  double S_ij_[8];
  Eigen::Matrix<double, 7, 7> sqrt_info_;
};

}  // namespace dynaorb::optimize::detail
