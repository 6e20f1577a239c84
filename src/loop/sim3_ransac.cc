// Sim3 RANSAC between two keyframes (see sim3_ransac.h).
#include "dynaorb/loop/sim3_ransac.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>

namespace dynaorb::loop {

namespace {

// Squared pixel error of the camera-frame point X against uv; infinite behind the camera.
double reprojection_error2(const Eigen::Matrix3d& K, const Eigen::Vector3d& X,
                           const Eigen::Vector2d& uv) {
  if (X.z() <= 0) return std::numeric_limits<double>::infinity();
  const double iz = 1.0 / X.z();
  const double u = K(0, 0) * X.x() * iz + K(0, 2);
  const double v = K(1, 1) * X.y() * iz + K(1, 2);
  return (uv - Eigen::Vector2d(u, v)).squaredNorm();
}

// RANSAC iterations for confidence p with inlier ratio w and minimal sets of 3.
int needed_iterations(double p, double w, int max_iterations) {
  if (w >= 1.0) return 1;
  if (w <= 0.0) return max_iterations;
  const double denom = std::log(1.0 - w * w * w);
  if (denom >= 0.0) return max_iterations;  // w^3 underflows
  const double n = std::ceil(std::log(1.0 - p) / denom);
  return static_cast<int>(std::min<double>(std::max(n, 1.0), max_iterations));
}

Sim3 fit(const std::vector<Sim3Match>& matches, const std::vector<int>& idx, bool fix_scale) {
  std::vector<Eigen::Vector3d> p1, p2;
  p1.reserve(idx.size());
  p2.reserve(idx.size());
  for (int i : idx) {
    p1.push_back(matches[i].X1);
    p2.push_back(matches[i].X2);
  }
  return align_horn(p1, p2, fix_scale);
}

}  // namespace

int sim3_inliers(const std::vector<Sim3Match>& matches, const Eigen::Matrix3d& K1,
                 const Eigen::Matrix3d& K2, const Sim3& S12, double chi2,
                 std::vector<bool>* inlier) {
  const Sim3 S21 = S12.inverse();
  inlier->assign(matches.size(), false);
  int count = 0;
  for (size_t i = 0; i < matches.size(); ++i) {
    const Sim3Match& m = matches[i];
    const double e1 = reprojection_error2(K1, S12 * m.X2, m.uv1);
    const double e2 = reprojection_error2(K2, S21 * m.X1, m.uv2);
    if (e1 < chi2 * m.sigma2_1 && e2 < chi2 * m.sigma2_2) {
      (*inlier)[i] = true;
      ++count;
    }
  }
  return count;
}

Sim3RansacResult sim3_ransac(const std::vector<Sim3Match>& matches, const Eigen::Matrix3d& K1,
                             const Eigen::Matrix3d& K2, const Sim3RansacOptions& options) {
  Sim3RansacResult result;
  const int n = static_cast<int>(matches.size());
  result.inlier.assign(matches.size(), false);
  if (n < 3 || n < options.min_inliers) return result;

  // mt19937's output sequence is fixed by the standard; the modulo draw keeps the samples
  // identical across standard libraries (uniform_int_distribution is implementation-defined).
  std::mt19937 rng(options.seed);
  std::vector<int> all(n);
  std::iota(all.begin(), all.end(), 0);
  std::vector<bool> flags;
  int best = -1;
  int budget = needed_iterations(options.probability,
                                 static_cast<double>(options.min_inliers) / n,
                                 options.max_iterations);
  for (int it = 0; it < budget; ++it) {
    for (int k = 0; k < 3; ++k) {  // 3 distinct indices: partial Fisher-Yates shuffle
      const int j = k + static_cast<int>(rng() % static_cast<unsigned>(n - k));
      std::swap(all[k], all[j]);
    }
    const Sim3 S = fit(matches, {all[0], all[1], all[2]}, options.fix_scale);
    ++result.iterations;
    const int count = sim3_inliers(matches, K1, K2, S, options.chi2, &flags);
    if (count > best) {
      best = count;
      result.S12 = S;
      result.inlier = flags;
      budget = std::min(budget, needed_iterations(options.probability,
                                                  std::max<double>(best, options.min_inliers) / n,
                                                  options.max_iterations));
    }
  }

  // Refinement on the inliers: re-fit and re-score while the inlier count does not drop.
  for (int round = 0; round < 3 && best >= 3; ++round) {
    std::vector<int> idx;
    for (int i = 0; i < n; ++i)
      if (result.inlier[i]) idx.push_back(i);
    const Sim3 S = fit(matches, idx, options.fix_scale);
    const int count = sim3_inliers(matches, K1, K2, S, options.chi2, &flags);
    if (count < best) break;
    const bool same = flags == result.inlier;
    best = count;
    result.S12 = S;
    result.inlier = flags;
    if (same) break;
  }
  result.inliers = std::max(best, 0);
  result.ok = result.inliers >= options.min_inliers;
  return result;
}

}  // namespace dynaorb::loop
