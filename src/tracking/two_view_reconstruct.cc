// Motion and structure of the monocular initialisation (ORB-SLAM Sec. IV-4):
// the 8 homography hypotheses (Faugeras & Lustman's SVD decomposition), the
// 4 essential-matrix hypotheses, linear triangulation and the choice of the
// hypothesis that clearly wins with enough parallax.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "dynaorb/tracking/two_view_initializer.h"
#include "dynaorb/core/triangulation.h"

namespace dynaorb::tracking::two_view {

namespace {

// cos(0.36 deg): below this parallax the depth sign of a triangulated point is not reliable,
// so it is not checked (the point still counts as good, as a point at infinity would), and
// the point is not triangulated (ORB-SLAM2 uses the same bound).
constexpr double kTinyParallaxCos = 0.99998;
constexpr double kRad2Deg = 57.295779513082321;  // 180 / pi

std::string format(const char* fmt, double a = 0, double b = 0, double c = 0, double d = 0) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), fmt, a, b, c, d);
  return buf;
}

Eigen::Vector2d project(const Eigen::Matrix3d& K, const Eigen::Vector3d& X) {
  return (K * X).hnormalized();
}

}  // namespace

std::vector<Motion> decompose_homography(const Eigen::Matrix3d& H21, const Eigen::Matrix3d& K) {
  // In normalised coordinates A = K^-1 H K ~ d R + t n^T (plane n^T X1 = d). With
  // A = U diag(d1, d2, d3) V^T, s = det U det V: A' = diag(d1, d2, d3) = d' R' + t' n'^T and
  // R = s U R' V^T, t = U t', n = V n' (Faugeras & Lustman 1988, the case d1 > d2 > d3).
  std::vector<Motion> out;
  const Eigen::Matrix3d A = K.inverse() * H21 * K;
  if (!A.allFinite()) return out;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  const Eigen::Vector3d w = svd.singularValues();
  const double s = U.determinant() * V.determinant();
  const double d1 = w(0), d2 = w(1), d3 = w(2);
  // Equal singular values: pure rotation (all equal) or a degenerate configuration.
  if (!(d3 > 0) || d1 / d2 < 1.00001 || d2 / d3 < 1.00001) return out;

  const double a1 = std::sqrt((d1 * d1 - d2 * d2) / (d1 * d1 - d3 * d3));
  const double a3 = std::sqrt((d2 * d2 - d3 * d3) / (d1 * d1 - d3 * d3));
  const double e1s[4] = {1, 1, -1, -1}, e3s[4] = {1, -1, 1, -1};
  auto add = [&](const Eigen::Matrix3d& Rp, const Eigen::Vector3d& tp, const Eigen::Vector3d& np) {
    Motion m;
    m.R = s * U * Rp * V.transpose();
    m.t = (U * tp).normalized();
    m.n = V * np;  // A ~ (s d') R + t n^T up to the scale of t
    out.push_back(m);
  };
  // d' = +d2: R' is a rotation about the y axis by theta.
  for (int k = 0; k < 4; ++k) {
    const double x1 = e1s[k] * a1, x3 = e3s[k] * a3;
    const double st = (d1 - d3) * x1 * x3 / d2;
    const double ct = (d2 * d2 + d1 * d3) / ((d1 + d3) * d2);
    Eigen::Matrix3d Rp;
    Rp << ct, 0, -st, 0, 1, 0, st, 0, ct;
    add(Rp, (d1 - d3) * Eigen::Vector3d(x1, 0, -x3), Eigen::Vector3d(x1, 0, x3));
  }
  // d' = -d2: R' is a reflection-composed rotation (det +1) by phi.
  for (int k = 0; k < 4; ++k) {
    const double x1 = e1s[k] * a1, x3 = e3s[k] * a3;
    const double sp = (d1 + d3) * x1 * x3 / d2;
    const double cp = (d1 * d3 - d2 * d2) / ((d1 - d3) * d2);
    Eigen::Matrix3d Rp;
    Rp << cp, 0, sp, 0, -1, 0, sp, 0, -cp;
    add(Rp, (d1 + d3) * Eigen::Vector3d(x1, 0, x3), Eigen::Vector3d(x1, 0, x3));
  }
  return out;
}

std::vector<Motion> decompose_essential(const Eigen::Matrix3d& E21) {
  std::vector<Motion> out;
  if (!E21.allFinite()) return out;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(E21, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  // E is defined up to sign: make both factors proper rotations.
  if (U.determinant() < 0) U = -U;
  if (V.determinant() < 0) V = -V;
  Eigen::Matrix3d W;
  W << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const Eigen::Matrix3d R1 = U * W * V.transpose(), R2 = U * W.transpose() * V.transpose();
  const Eigen::Vector3d t = U.col(2).normalized();
  for (const Eigen::Matrix3d* R : {&R1, &R2})
    for (double sign : {1.0, -1.0}) {
      Motion m;
      m.R = *R;
      m.t = sign * t;
      out.push_back(m);
    }
  return out;
}

bool triangulate(const Eigen::Vector2d& xn1, const Eigen::Vector2d& xn2, const Eigen::Matrix3d& R,
                 const Eigen::Vector3d& t, Eigen::Vector3d& X) {
  Eigen::Matrix<double, 3, 4> P1 = Eigen::Matrix<double, 3, 4>::Zero(), P2;
  P1.leftCols<3>().setIdentity();
  P2.leftCols<3>() = R;
  P2.col(3) = t;
  return triangulate_dlt_unit_baseline(xn1, P1, xn2, P2, X);  // |t| = 1 (decompose_*)
}

MotionCheck check_motion(const Motion& m, const Eigen::Matrix3d& K, const Correspondences& c,
                         const std::vector<bool>& inliers, double reproj_chi2, int give_up_at) {
  MotionCheck out;
  out.points.assign(c.size(), Eigen::Vector3d::Zero());
  out.triangulated.assign(c.size(), false);
  const Eigen::Matrix3d Kinv = K.inverse();
  const Eigen::Vector3d O2 = -m.R.transpose() * m.t;  // current camera centre, reference frame
  int left = 0;  // inliers not yet checked
  for (int i = 0; i < c.size(); ++i) left += inliers[i] ? 1 : 0;
  for (int i = 0; i < c.size(); ++i) {
    if (!inliers[i]) continue;
    if (out.n_good + left <= give_up_at) {
      out.abandoned = true;
      break;
    }
    --left;
    const Eigen::Vector2d xn1 = (Kinv * c.x1[i].homogeneous()).hnormalized();
    const Eigen::Vector2d xn2 = (Kinv * c.x2[i].homogeneous()).hnormalized();
    Eigen::Vector3d X1;
    if (!triangulate(xn1, xn2, m.R, m.t, X1)) continue;
    const Eigen::Vector3d X2 = m.R * X1 + m.t;
    const Eigen::Vector3d ray1 = X1, ray2 = X1 - O2;
    const double cos_par = ray1.dot(ray2) / (ray1.norm() * ray2.norm());
    const bool parallax = cos_par < kTinyParallaxCos;
    if (parallax && (X1.z() <= 0 || X2.z() <= 0)) continue;  // behind a camera
    const double e1 = (project(K, X1) - c.x1[i]).squaredNorm() * c.w1[i];
    const double e2 = (project(K, X2) - c.x2[i]).squaredNorm() * c.w2[i];
    if (!(e1 < reproj_chi2) || !(e2 < reproj_chi2)) continue;
    ++out.n_good;
    out.parallax_deg.push_back(std::acos(std::clamp(cos_par, -1.0, 1.0)) * kRad2Deg);
    if (parallax) {
      out.points[i] = X1;
      out.triangulated[i] = true;
    }
  }
  return out;
}

void select_motion(const std::vector<Motion>& hypotheses, const Eigen::Matrix3d& K,
                   const Correspondences& c, const ModelScore& model, const TwoViewOptions& o,
                   TwoViewResult& out) {
  out.ok = false;
  if (hypotheses.empty()) {
    out.reason = "no motion hypothesis";
    return;
  }
  // A hypothesis is the winner only with more good points than every one
  // before it, and counts against the winner only with more than
  // clear_winner_ratio of its good points: one that can no longer have more
  // than the smaller of the two bounds of the best so far is left unfinished
  // (most wrong hypotheses put points behind a camera early). The outcome is
  // the same as checking every hypothesis to the end.
  std::vector<MotionCheck> checks;
  int best = 0;
  for (const Motion& m : hypotheses) {
    int give_up_at = -1;
    if (!checks.empty()) {
      const double b = checks[best].n_good;
      give_up_at = static_cast<int>(std::floor(std::min(b, o.clear_winner_ratio * b)));
    }
    checks.push_back(check_motion(m, K, c, model.inliers, o.reproj_chi2, give_up_at));
    if (checks.back().n_good > checks[best].n_good) best = static_cast<int>(checks.size()) - 1;
  }
  MotionCheck& win = checks[best];
  const int n_good = win.n_good;
  int n_similar = 0;
  for (const MotionCheck& mc : checks)
    if (mc.n_good > o.clear_winner_ratio * n_good) ++n_similar;

  // Parallax: the (rank+1)-th largest parallax of the good points must reach the minimum.
  std::vector<double> par = win.parallax_deg;
  std::sort(par.begin(), par.end(), std::greater<double>());
  const double ranked =
      par.empty() ? 0 : par[std::min<size_t>(std::max(o.parallax_rank, 0), par.size() - 1)];
  out.n_good = n_good;
  if (!par.empty()) {
    std::nth_element(par.begin(), par.begin() + par.size() / 2, par.end());
    out.median_parallax_deg = par[par.size() / 2];
  }

  std::string why;
  auto fail = [&](const std::string& r) { why += (why.empty() ? "" : "; ") + r; };
  if (ranked < o.min_parallax_deg)
    fail(format("not enough parallax (rank-%.0f largest parallax %.3f deg < %.2f deg)",
                std::min<double>(o.parallax_rank, par.empty() ? 0 : par.size() - 1) + 1, ranked,
                o.min_parallax_deg));
  if (n_good < o.min_triangulated)
    fail(format("too few good points (%.0f < %.0f)", n_good, o.min_triangulated));
  if (n_good < o.min_good_fraction * model.n_inliers)
    fail(format("good points are %.0f of %.0f model inliers (< %.0f %%)", n_good,
                model.n_inliers, 100 * o.min_good_fraction));
  if (n_similar > 1)
    fail(format("no clear winner (%.0f of %.0f hypotheses above %.2f of the best's %.0f points)",
                n_similar, static_cast<double>(hypotheses.size()), o.clear_winner_ratio, n_good));
  if (!why.empty()) {
    out.reason = why;
    return;
  }
  out.ok = true;
  out.reason.clear();
  out.R_cr = hypotheses[best].R;
  out.t_cr = hypotheses[best].t;
  out.points = std::move(win.points);
  out.triangulated = std::move(win.triangulated);
}

}  // namespace dynaorb::tracking::two_view
