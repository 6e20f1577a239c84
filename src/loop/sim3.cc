// Sim(3) operations and Horn's closed-form absolute orientation (see sim3.h).
//
// Horn (1987): with centred points r1 = p1 - c1, r2 = p2 - c2 and M = sum r2 r1^T (entries
// S_ab = sum r2_a r1_b), the unit quaternion of the rotation R12 maximising sum r1 . (R r2) is
// the eigenvector of the largest eigenvalue of the symmetric 4x4 matrix N(M). Then
//   s = sum r1 . (R r2) / sum |r2|^2   (1 if fix_scale),   t = c1 - s R c2.
#include "dynaorb/loop/sim3.h"

#include <Eigen/Eigenvalues>
#include <stdexcept>

namespace dynaorb::loop {

Sim3 Sim3::from_isometry(const Eigen::Isometry3d& T) {
  return Sim3(Eigen::Quaterniond(T.rotation()), T.translation(), 1.0);
}

Eigen::Isometry3d Sim3::to_isometry() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotation();
  T.translation() = t;
  return T;
}

Eigen::Matrix4d Sim3::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = s * rotation();
  m.topRightCorner<3, 1>() = t;
  return m;
}

Sim3 Sim3::inverse() const {
  const Eigen::Quaterniond qi = q.conjugate();
  return Sim3(qi, -(qi * t) / s, 1.0 / s);
}

Sim3 Sim3::operator*(const Sim3& b) const {
  return Sim3(q * b.q, s * (q * b.t) + t, s * b.s);
}

Vector7d sim3_log(const Sim3& S) {
  double a[8];
  detail::to_array(S, a);
  Vector7d xi;
  detail::sim3_log(a, xi.data());
  return xi;
}

Sim3 sim3_exp(const Vector7d& xi) {
  double a[8];
  detail::sim3_exp(xi.data(), a);
  return detail::from_array(a);
}

Sim3 align_horn(const std::vector<Eigen::Vector3d>& p1, const std::vector<Eigen::Vector3d>& p2,
                bool fix_scale) {
  if (p1.empty() || p1.size() != p2.size())
    throw std::invalid_argument("align_horn: need two non-empty point sets of equal size");
  const double n = static_cast<double>(p1.size());
  Eigen::Vector3d c1 = Eigen::Vector3d::Zero(), c2 = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < p1.size(); ++i) {
    c1 += p1[i];
    c2 += p2[i];
  }
  c1 /= n;
  c2 /= n;
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < p1.size(); ++i) M += (p2[i] - c2) * (p1[i] - c1).transpose();

  const double Sxx = M(0, 0), Sxy = M(0, 1), Sxz = M(0, 2);
  const double Syx = M(1, 0), Syy = M(1, 1), Syz = M(1, 2);
  const double Szx = M(2, 0), Szy = M(2, 1), Szz = M(2, 2);
  Eigen::Matrix4d N;
  N << Sxx + Syy + Szz, Syz - Szy, Szx - Sxz, Sxy - Syx,  //
      Syz - Szy, Sxx - Syy - Szz, Sxy + Syx, Szx + Sxz,    //
      Szx - Sxz, Sxy + Syx, -Sxx + Syy - Szz, Syz + Szy,   //
      Sxy - Syx, Szx + Sxz, Syz + Szy, -Sxx - Syy + Szz;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(N);
  const Eigen::Vector4d e = eig.eigenvectors().col(3);  // eigenvalues are sorted increasingly
  const Eigen::Quaterniond q(e[0], e[1], e[2], e[3]);   // [q0 qx qy qz] in Horn's order

  double s = 1.0;
  if (!fix_scale) {
    double nom = 0, den = 0;
    for (size_t i = 0; i < p1.size(); ++i) {
      const Eigen::Vector3d r2 = p2[i] - c2;
      nom += (p1[i] - c1).dot(q * r2);
      den += r2.squaredNorm();
    }
    if (den > 1e-300 && nom > 0) s = nom / den;
  }
  return Sim3(q, c1 - s * (q * c2), s);
}

}  // namespace dynaorb::loop
