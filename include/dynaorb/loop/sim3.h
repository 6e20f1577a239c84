#pragma once
// Similarity transformations Sim(3) for loop closing: x' = s R x + t. A monocular map drifts in
// scale as well as in pose, so the loop correction (ORB-SLAM, Mur-Artal et al., T-RO 2015,
// Sec. VI-B / VI-D) and the essential graph (Strasdat et al., RSS 2010, "Scale drift-aware large
// scale monocular SLAM") work in Sim(3); stereo / RGB-D fix s = 1 (SE(3)).
//
// Lie algebra sim(3): xi = [rho(3), phi(3), sigma] (translation part, rotation vector, log
// scale), exp(xi) = matrix exponential of [[sigma I + [phi]x, rho], [0, 0]], i.e.
//   R = Exp(phi),  s = e^sigma,  t = W * rho,  W = integral_0^1 exp(u (sigma I + [phi]x)) du
// (Strasdat's thesis, App. A; closed form below). The templated kernels in `detail` work on
// 8-double arrays [qx qy qz qw tx ty tz s] and on Ceres Jets, so that the pose graph can
// differentiate the same code it evaluates (dynaorb/optimize/pose_graph.h).
//
// align_horn: closed-form absolute orientation, Horn (JOSA A, 1987) with unit quaternions, as
// ORB-SLAM's Sim3Solver: S12 minimising sum |p1 - (s R p2 + t)|^2 (scale: ORB-SLAM's
// asymmetric estimate s = sum r1.(R r2) / sum |r2|^2, not Horn's symmetric one).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <vector>

namespace dynaorb::loop {

using Vector7d = Eigen::Matrix<double, 7, 1>;

struct Sim3 {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double s = 1.0;

  Sim3() = default;
  Sim3(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation, double scale)
      : q(rotation.normalized()), t(translation), s(scale) {}

  static Sim3 identity() { return {}; }
  static Sim3 from_isometry(const Eigen::Isometry3d& T);  // s = 1
  Eigen::Isometry3d to_isometry() const;                   // [R | t], the scale is dropped
  Eigen::Matrix4d matrix() const;                          // [[sR, t], [0, 1]]
  Eigen::Matrix3d rotation() const { return q.toRotationMatrix(); }

  Sim3 inverse() const;
  Sim3 operator*(const Sim3& b) const;                         // (this * b)(x) = this(b(x))
  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const {  // s R x + t
    return s * (q * x) + t;
  }
};

Vector7d sim3_log(const Sim3& S);   // [rho, phi, sigma]
Sim3 sim3_exp(const Vector7d& xi);

// S12 with p1[i] ~ S12 * p2[i] (least squares in frame 1); fix_scale: s = 1 (SE(3), stereo /
// RGB-D). Needs >= 3 non-collinear pairs for a unique answer; throws std::invalid_argument on
// empty or unequal-size input. Degenerate spread of p2 (all equal) gives s = 1.
Sim3 align_horn(const std::vector<Eigen::Vector3d>& p1, const std::vector<Eigen::Vector3d>& p2,
                bool fix_scale);

namespace detail {

// W = C I + A [phi]x + B [phi]x^2 of the exp map; W^{-1} turns t into rho in the log. Branches
// keep values and first derivatives exact (Jets) at phi = 0 and sigma = 0.
template <typename T>
void sim3_w_coeffs(const T& sigma, const T& theta2, T* A, T* B, T* C) {
  using std::abs;
  using std::cos;
  using std::exp;
  using std::expm1;
  using std::sin;
  using std::sqrt;
  const bool small_sigma = abs(sigma) < T(1e-2);
  // C = (e^sigma - 1) / sigma = sum sigma^k / (k+1)!
  if (small_sigma) {
    T c(0), term(1);
    for (int k = 0; k <= 7; ++k) {
      c += term / T(k + 1);
      term = term * sigma / T(k + 1);
    }
    *C = c;
  } else {
    *C = expm1(sigma) / sigma;
  }
  if (theta2 < T(1e-8)) {  // phi ~ 0: integrals of e^{u sigma} u and e^{u sigma} u^2 / 2
    if (small_sigma) {     // A = sum sigma^k / (k! (k+2)),  B = sum sigma^k / (2 k! (k+3))
      T a(0), b(0), term(1);
      for (int k = 0; k <= 6; ++k) {
        a += term / T(k + 2);
        b += term / T(2 * (k + 3));
        term = term * sigma / T(k + 1);
      }
      *A = a;
      *B = b;
    } else {
      const T s = exp(sigma);
      *A = ((sigma - T(1)) * s + T(1)) / (sigma * sigma);
      *B = (s * (sigma * sigma - T(2) * sigma + T(2)) - T(2)) / (T(2) * sigma * sigma * sigma);
    }
    return;
  }
  const T theta = sqrt(theta2);
  const T s = exp(sigma);
  const T a = s * sin(theta), b = s * cos(theta), c = theta2 + sigma * sigma;
  *A = (a * sigma + (T(1) - b) * theta) / (theta * c);
  *B = (*C - ((b - T(1)) * sigma + a * theta) / c) / theta2;
}

template <typename T>
Eigen::Matrix<T, 3, 3> skew(const Eigen::Matrix<T, 3, 1>& v) {
  Eigen::Matrix<T, 3, 3> m;
  m << T(0), -v.z(), v.y(), v.z(), T(0), -v.x(), -v.y(), v.x(), T(0);
  return m;
}

// xi[7] -> S[8] = [qx qy qz qw tx ty tz s].
template <typename T>
void sim3_exp(const T* xi, T* S) {
  using std::cos;
  using std::exp;
  using std::sin;
  using std::sqrt;
  const Eigen::Matrix<T, 3, 1> rho(xi[0], xi[1], xi[2]), phi(xi[3], xi[4], xi[5]);
  const T sigma = xi[6];
  const T theta2 = phi.squaredNorm();
  Eigen::Quaternion<T> q;
  if (theta2 < T(1e-8)) {
    const T k = T(0.5) - theta2 / T(48);  // sin(theta/2)/theta
    q = Eigen::Quaternion<T>(T(1) - theta2 / T(8), k * phi.x(), k * phi.y(), k * phi.z());
  } else {
    const T theta = sqrt(theta2);
    const T k = sin(T(0.5) * theta) / theta;
    q = Eigen::Quaternion<T>(cos(T(0.5) * theta), k * phi.x(), k * phi.y(), k * phi.z());
  }
  q.normalize();
  T A, B, C;
  sim3_w_coeffs(sigma, theta2, &A, &B, &C);
  const Eigen::Matrix<T, 3, 3> P = skew(phi);
  const Eigen::Matrix<T, 3, 1> t = C * rho + A * (P * rho) + B * (P * (P * rho));
  S[0] = q.x();
  S[1] = q.y();
  S[2] = q.z();
  S[3] = q.w();
  S[4] = t.x();
  S[5] = t.y();
  S[6] = t.z();
  S[7] = exp(sigma);
}

// S[8] -> xi[7]; the rotation part is the shortest one (|phi| <= pi).
template <typename T>
void sim3_log(const T* S, T* xi) {
  using std::atan2;
  using std::log;
  using std::sqrt;
  Eigen::Quaternion<T> q(S[3], S[0], S[1], S[2]);
  if (q.w() < T(0)) q.coeffs() = -q.coeffs();
  const Eigen::Matrix<T, 3, 1> v = q.vec();
  const T n2 = v.squaredNorm();
  Eigen::Matrix<T, 3, 1> phi;
  if (n2 < T(1e-16)) {
    phi = (T(2) / q.w() * (T(1) - n2 / (T(3) * q.w() * q.w()))) * v;
  } else {
    const T n = sqrt(n2);
    phi = (T(2) * atan2(n, q.w()) / n) * v;
  }
  const T sigma = log(S[7]);
  T A, B, C;
  sim3_w_coeffs(sigma, phi.squaredNorm(), &A, &B, &C);
  const Eigen::Matrix<T, 3, 3> P = skew(phi);
  const Eigen::Matrix<T, 3, 3> W =
      C * Eigen::Matrix<T, 3, 3>::Identity() + A * P + B * (P * P);
  const Eigen::Matrix<T, 3, 1> rho = W.inverse() * Eigen::Matrix<T, 3, 1>(S[4], S[5], S[6]);
  for (int i = 0; i < 3; ++i) {
    xi[i] = rho[i];
    xi[3 + i] = phi[i];
  }
  xi[6] = sigma;
}

// ab = a * b.
template <typename T>
void sim3_compose(const T* a, const T* b, T* ab) {
  const Eigen::Quaternion<T> qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
  const Eigen::Quaternion<T> q = qa * qb;
  using Vec3 = Eigen::Matrix<T, 3, 1>;
  const Vec3 t = a[7] * (qa * Vec3(b[4], b[5], b[6])) + Vec3(a[4], a[5], a[6]);
  ab[0] = q.x();
  ab[1] = q.y();
  ab[2] = q.z();
  ab[3] = q.w();
  ab[4] = t.x();
  ab[5] = t.y();
  ab[6] = t.z();
  ab[7] = a[7] * b[7];
}

template <typename T>
void sim3_inverse(const T* a, T* ai) {
  const Eigen::Quaternion<T> qi = Eigen::Quaternion<T>(a[3], a[0], a[1], a[2]).conjugate();
  const T si = T(1) / a[7];
  const Eigen::Matrix<T, 3, 1> t = -si * (qi * Eigen::Matrix<T, 3, 1>(a[4], a[5], a[6]));
  ai[0] = qi.x();
  ai[1] = qi.y();
  ai[2] = qi.z();
  ai[3] = qi.w();
  ai[4] = t.x();
  ai[5] = t.y();
  ai[6] = t.z();
  ai[7] = si;
}

inline void to_array(const Sim3& S, double* a) {
  a[0] = S.q.x();
  a[1] = S.q.y();
  a[2] = S.q.z();
  a[3] = S.q.w();
  a[4] = S.t.x();
  a[5] = S.t.y();
  a[6] = S.t.z();
  a[7] = S.s;
}

inline Sim3 from_array(const double* a) {
  return Sim3(Eigen::Quaterniond(a[3], a[0], a[1], a[2]), Eigen::Vector3d(a[4], a[5], a[6]), a[7]);
}

}  // namespace detail

}  // namespace dynaorb::loop
