#pragma once
// Linear (DLT) triangulation of one point seen by two cameras (Hartley &
// Zisserman, Sec. 12.2): the mapper's new points and the two-view initialiser.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>

namespace dynaorb {

namespace detail {

// The DLT system A h = 0 of the two views (h: the homogeneous point).
inline Eigen::Matrix4d dlt_system(const Eigen::Vector2d& x1, const Eigen::Matrix<double, 3, 4>& P1,
                                  const Eigen::Vector2d& x2, const Eigen::Matrix<double, 3, 4>& P2) {
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  return A;
}

// The point of a unit homogeneous solution h; false at infinity or not finite.
inline bool dehomogenised(const Eigen::Vector4d& h, Eigen::Vector3d& X) {
  if (!(std::abs(h(3)) > 1e-12)) return false;
  X = h.head<3>() / h(3);
  return X.allFinite();
}

}  // namespace detail

// x1, x2: normalised image coordinates (K^-1 [u v 1]); P1, P2: 3x4 projection
// matrices [R|t] of the two cameras. False when the point is at infinity or
// not finite.
inline bool triangulate_dlt(const Eigen::Vector2d& x1, const Eigen::Matrix<double, 3, 4>& P1,
                            const Eigen::Vector2d& x2, const Eigen::Matrix<double, 3, 4>& P2,
                            Eigen::Vector3d& X) {
  const Eigen::Matrix4d A = detail::dlt_system(x1, P1, x2, P2);
  // A NaN does not stop Jacobi's sweeps (its comparisons are false): the SVD
  // of such an A can come back finite, and a point from nothing.
  if (!A.allFinite()) return false;
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  return detail::dehomogenised(svd.matrixV().col(3), X);  // unit norm
}

// The same least-squares point from the eigenvector of A^T A with the
// smallest eigenvalue (a self-adjoint 4x4 solve) instead of A's SVD: about
// half the time, but A^T A squares A's condition. Only for cameras of the
// two-view initialiser's scale, the reference one at the origin and a unit
// baseline (on such points the two agree to 1e-8 of the point's distance
// down to parallaxes of 0.01 degree); the mapper's cameras, metres from the
// world origin, keep the SVD.
inline bool triangulate_dlt_unit_baseline(const Eigen::Vector2d& x1, const Eigen::Matrix<double, 3, 4>& P1,
                                          const Eigen::Vector2d& x2, const Eigen::Matrix<double, 3, 4>& P2,
                                          Eigen::Vector3d& X) {
  const Eigen::Matrix4d A = detail::dlt_system(x1, P1, x2, P2);
  const Eigen::Matrix4d M = A.transpose() * A;
  if (!M.allFinite()) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(M);
  if (es.info() != Eigen::Success) return false;
  return detail::dehomogenised(es.eigenvectors().col(0), X);  // unit norm, smallest eigenvalue first
}

}  // namespace dynaorb
