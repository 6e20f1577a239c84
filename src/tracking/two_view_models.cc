// Two-view models of the monocular initialisation (ORB-SLAM Sec. IV-2): the
// normalised DLT homography, the normalised 8-point fundamental matrix, their
// symmetric-transfer-error scores and the RANSAC loop over prefixed samples.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "dynaorb/tracking/two_view_initializer.h"

namespace dynaorb::tracking::two_view {

namespace {

// Hartley's normalisation: centroid to the origin, mean distance sqrt(2). Returns T with
// out[i] = T * x[i].
Eigen::Matrix3d normalise(const std::vector<Eigen::Vector2d>& x, std::vector<Eigen::Vector2d>& out) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : x) mean += p;
  mean /= static_cast<double>(x.size());
  double dist = 0;
  for (const auto& p : x) dist += (p - mean).norm();
  dist /= static_cast<double>(x.size());
  const double s = dist > 1e-12 ? std::sqrt(2.0) / dist : 1.0;
  out.resize(x.size());
  for (size_t i = 0; i < x.size(); ++i) out[i] = s * (x[i] - mean);
  Eigen::Matrix3d T;
  T << s, 0, -s * mean.x(), 0, s, -s * mean.y(), 0, 0, 1;
  return T;
}

// The unit h minimising |A h| (right singular vector of the smallest singular value), as a
// row-major 3x3 matrix: the eigenvector of A^T A (9 x 9, whatever the number of rows) with
// the smallest eigenvalue. After Hartley's normalisation A^T A is well enough conditioned
// for this. A^T A is symmetric, so its eigenvectors come from Eigen's self-adjoint solver
// (tridiagonalisation and implicit QR) rather than a Jacobi SVD of it: the same vector to
// 1e-14, in 3.8 instead of 14.4 us (this machine, -O2), and RANSAC takes 400 of them per
// initialisation attempt (200 sample sets, H and F).
Eigen::Matrix3d null_vector(const Eigen::MatrixXd& A) {
  using Mat9 = Eigen::Matrix<double, 9, 9>;
  const Mat9 AtA = A.transpose() * A;
  const Eigen::SelfAdjointEigenSolver<Mat9> eigen(AtA);
  if (eigen.info() != Eigen::Success) return Eigen::Matrix3d::Zero();  // no model: scores nothing
  const Eigen::Matrix<double, 9, 1> h = eigen.eigenvectors().col(0);  // eigenvalues ascending
  Eigen::Matrix3d M;
  M << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  return M;
}

std::vector<Eigen::Vector2d> pick(const std::vector<Eigen::Vector2d>& x, const std::vector<int>& idx,
                                  int n) {
  std::vector<Eigen::Vector2d> out(n);
  for (int i = 0; i < n; ++i) out[i] = x[idx[i]];
  return out;
}

std::vector<int> inlier_indices(const ModelScore& s) {
  std::vector<int> idx;
  for (size_t i = 0; i < s.inliers.size(); ++i)
    if (s.inliers[i]) idx.push_back(static_cast<int>(i));
  return idx;
}

// rho(d^2) = gamma - d^2 when d^2 < chi2, else 0 (and the match is an outlier).
inline bool add_score(double d2, double chi2, double gamma, double& score) {
  if (!std::isfinite(d2) || d2 >= chi2) return false;
  score += gamma - d2;
  return true;
}

bool finite(const Eigen::Matrix3d& M) { return M.allFinite() && M.norm() > 0; }

// Whether a score of `score` after `done` of n correspondences can no longer exceed
// must_beat: each of the others adds at most 2 gamma (gamma - d^2 per image, d^2 >= 0).
// The margin (far above the sums' rounding) keeps every model that could still win.
inline bool cannot_win(double score, int done, int n, double gamma, double must_beat) {
  const double bound = score + 2.0 * gamma * static_cast<double>(n - done);
  return bound < must_beat - 1e-9 * std::max(1.0, std::abs(must_beat));
}

template <typename Fit, typename Score>
ModelScore ransac(const Correspondences& c, const std::vector<std::vector<int>>& samples,
                  int sample_size, Fit fit, Score score, Eigen::Matrix3d& model) {
  ModelScore best;
  best.inliers.assign(c.size(), false);
  model.setZero();
  for (const auto& s : samples) {
    const Eigen::Matrix3d M = fit(pick(c.x1, s, sample_size), pick(c.x2, s, sample_size));
    if (!finite(M)) continue;
    ModelScore cur = score(M, best.score);
    if (cur.score > best.score) {
      best = std::move(cur);
      model = M;
    }
  }
  return best;
}

// A few refits on the inliers (least-squares DLT / weighted 8-point), each kept only when it
// scores at least as well as the model it replaces.
template <typename Fit, typename Score>
ModelScore refine(const Correspondences& c, const ModelScore& start, int min_points, Fit fit,
                  Score score, Eigen::Matrix3d& model) {
  ModelScore best = start;
  for (int it = 0; it < 5 && best.n_inliers >= min_points; ++it) {
    const std::vector<int> idx = inlier_indices(best);
    const int n = static_cast<int>(idx.size());
    const Eigen::Matrix3d M = fit(pick(c.x1, idx, n), pick(c.x2, idx, n));
    if (!finite(M)) break;
    ModelScore cur = score(M);
    if (cur.score < best.score) break;
    const bool converged = cur.score - best.score <= 1e-9 * best.score;
    best = std::move(cur);
    model = M;
    if (converged) break;
  }
  return best;
}

// The normalised 8-point algorithm with an optional weight per equation (empty: all 1).
Eigen::Matrix3d fundamental_weighted(const std::vector<Eigen::Vector2d>& x1,
                                     const std::vector<Eigen::Vector2d>& x2,
                                     const std::vector<double>& weight) {
  const int n = static_cast<int>(x1.size());
  if (n < 8 || x2.size() != x1.size()) return Eigen::Matrix3d::Zero();
  std::vector<Eigen::Vector2d> p1, p2;
  const Eigen::Matrix3d T1 = normalise(x1, p1), T2 = normalise(x2, p2);
  Eigen::MatrixXd A(n, 9);
  for (int i = 0; i < n; ++i) {
    const double u1 = p1[i].x(), v1 = p1[i].y(), u2 = p2[i].x(), v2 = p2[i].y();
    A.row(i) << u2 * u1, u2 * v1, u2, v2 * u1, v2 * v1, v2, u1, v1, 1;
    if (!weight.empty()) A.row(i) *= weight[i];
  }
  const Eigen::Matrix3d Fn = null_vector(A);
  // Rank 2: the closest singular matrix in Frobenius norm.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(Fn, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  S(0, 0) = svd.singularValues()(0);
  S(1, 1) = svd.singularValues()(1);
  const Eigen::Matrix3d F2 = svd.matrixU() * S * svd.matrixV().transpose();
  Eigen::Matrix3d F = T2.transpose() * F2 * T1;
  const double norm = F.norm();
  return norm > 0 ? Eigen::Matrix3d(F / norm) : F;
}

// Sampson weights of F: the algebraic error x2^T F x1 divided by its first-order standard
// deviation, so that the weighted 8-point approximately minimises the Sampson error.
std::vector<double> sampson_weights(const Eigen::Matrix3d& F, const std::vector<Eigen::Vector2d>& x1,
                                    const std::vector<Eigen::Vector2d>& x2) {
  std::vector<double> w(x1.size());
  for (size_t i = 0; i < x1.size(); ++i) {
    const Eigen::Vector3d l2 = F * x1[i].homogeneous(), l1 = F.transpose() * x2[i].homogeneous();
    const double g = l2.head<2>().squaredNorm() + l1.head<2>().squaredNorm();
    w[i] = g > 0 ? 1 / std::sqrt(g) : 0;
  }
  return w;
}

}  // namespace

Eigen::Matrix3d homography_dlt(const std::vector<Eigen::Vector2d>& x1,
                               const std::vector<Eigen::Vector2d>& x2) {
  const int n = static_cast<int>(x1.size());
  if (n < 4 || x2.size() != x1.size()) return Eigen::Matrix3d::Zero();
  std::vector<Eigen::Vector2d> p1, p2;
  const Eigen::Matrix3d T1 = normalise(x1, p1), T2 = normalise(x2, p2);
  Eigen::MatrixXd A(2 * n, 9);
  for (int i = 0; i < n; ++i) {
    const double u1 = p1[i].x(), v1 = p1[i].y(), u2 = p2[i].x(), v2 = p2[i].y();
    // x2 x (H x1) = 0: two independent rows per correspondence.
    A.row(2 * i) << 0, 0, 0, -u1, -v1, -1, v2 * u1, v2 * v1, v2;
    A.row(2 * i + 1) << u1, v1, 1, 0, 0, 0, -u2 * u1, -u2 * v1, -u2;
  }
  const Eigen::Matrix3d Hn = null_vector(A);
  Eigen::Matrix3d H = T2.inverse() * Hn * T1;
  const double norm = H.norm();
  return norm > 0 ? Eigen::Matrix3d(H / norm) : H;
}

Eigen::Matrix3d fundamental_8point(const std::vector<Eigen::Vector2d>& x1,
                                   const std::vector<Eigen::Vector2d>& x2) {
  return fundamental_weighted(x1, x2, {});
}

ModelScore score_homography(const Eigen::Matrix3d& H21, const Correspondences& c, double chi2,
                            double gamma, double must_beat) {
  ModelScore out;
  out.inliers.assign(c.size(), false);
  const Eigen::Matrix3d H12 = H21.inverse();
  if (!H12.allFinite()) return out;
  for (int i = 0; i < c.size(); ++i) {
    if (cannot_win(out.score, i, c.size(), gamma, must_beat)) break;
    // Transfer error in the current image (x1 -> x2) and in the reference one (x2 -> x1).
    const Eigen::Vector3d p2 = H21 * c.x1[i].homogeneous();
    const Eigen::Vector3d p1 = H12 * c.x2[i].homogeneous();
    const double d2_cur = (c.x2[i] - p2.hnormalized()).squaredNorm() * c.w2[i];
    const double d2_ref = (c.x1[i] - p1.hnormalized()).squaredNorm() * c.w1[i];
    const bool in_cur = add_score(d2_cur, chi2, gamma, out.score);
    const bool in_ref = add_score(d2_ref, chi2, gamma, out.score);
    if (in_cur && in_ref) {
      out.inliers[i] = true;
      ++out.n_inliers;
    }
  }
  return out;
}

ModelScore score_fundamental(const Eigen::Matrix3d& F21, const Correspondences& c, double chi2,
                             double gamma, double must_beat) {
  ModelScore out;
  out.inliers.assign(c.size(), false);
  for (int i = 0; i < c.size(); ++i) {
    if (cannot_win(out.score, i, c.size(), gamma, must_beat)) break;
    const Eigen::Vector3d x1 = c.x1[i].homogeneous(), x2 = c.x2[i].homogeneous();
    // Distance of x2 to the epipolar line F x1, and of x1 to F^T x2.
    const Eigen::Vector3d l2 = F21 * x1, l1 = F21.transpose() * x2;
    const double e = x2.dot(l2);  // = x1.dot(l1)
    const double d2_cur = e * e / l2.head<2>().squaredNorm() * c.w2[i];
    const double d2_ref = e * e / l1.head<2>().squaredNorm() * c.w1[i];
    const bool in_cur = add_score(d2_cur, chi2, gamma, out.score);
    const bool in_ref = add_score(d2_ref, chi2, gamma, out.score);
    if (in_cur && in_ref) {
      out.inliers[i] = true;
      ++out.n_inliers;
    }
  }
  return out;
}

ModelScore ransac_homography(const Correspondences& c, const std::vector<std::vector<int>>& samples,
                             const TwoViewOptions& o, Eigen::Matrix3d& model) {
  const int k = std::min(std::max(o.homography_sample, 4), 8);
  return ransac(
      c, samples, k, homography_dlt,
      [&](const Eigen::Matrix3d& H, double must_beat) {
        return score_homography(H, c, o.chi2_h, o.score_gamma, must_beat);
      },
      model);
}

ModelScore ransac_fundamental(const Correspondences& c,
                              const std::vector<std::vector<int>>& samples,
                              const TwoViewOptions& o, Eigen::Matrix3d& model) {
  return ransac(
      c, samples, 8, fundamental_8point,
      [&](const Eigen::Matrix3d& F, double must_beat) {
        return score_fundamental(F, c, o.chi2_f, o.score_gamma, must_beat);
      },
      model);
}

ModelScore refine_homography(const Correspondences& c, const ModelScore& start,
                             const TwoViewOptions& o, Eigen::Matrix3d& model) {
  return refine(
      c, start, 8, homography_dlt,
      [&](const Eigen::Matrix3d& H) { return score_homography(H, c, o.chi2_h, o.score_gamma); },
      model);
}

ModelScore refine_fundamental(const Correspondences& c, const ModelScore& start,
                              const TwoViewOptions& o, Eigen::Matrix3d& model) {
  // Refits weighted by the Sampson weights of the model being replaced.
  auto fit = [&](const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2) {
    return fundamental_weighted(x1, x2, sampson_weights(model, x1, x2));
  };
  return refine(
      c, start, 12, fit,
      [&](const Eigen::Matrix3d& F) { return score_fundamental(F, c, o.chi2_f, o.score_gamma); },
      model);
}

}  // namespace dynaorb::tracking::two_view
