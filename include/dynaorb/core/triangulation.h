#pragma once
// Linear (DLT) triangulation of one point seen by two cameras (Hartley &
// Zisserman, Sec. 12.2): the mapper's new points and the two-view initialiser.
#include <Eigen/Core>
#include <Eigen/SVD>
#include <cmath>

namespace dynaorb {

// x1, x2: normalised image coordinates (K^-1 [u v 1]); P1, P2: 3x4 projection
// matrices [R|t] of the two cameras. False when the point is at infinity or
// not finite.
inline bool triangulate_dlt(const Eigen::Vector2d& x1, const Eigen::Matrix<double, 3, 4>& P1,
                            const Eigen::Vector2d& x2, const Eigen::Matrix<double, 3, 4>& P2,
                            Eigen::Vector3d& X) {
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);  // unit norm
  if (!(std::abs(h(3)) > 1e-12)) return false;
  X = h.head<3>() / h(3);
  return X.allFinite();
}

}  // namespace dynaorb
