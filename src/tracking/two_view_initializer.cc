// Monocular two-view initialisation (ORB-SLAM Sec. IV): input checks, the
// prefixed RANSAC sample sets, H and F in parallel, model selection by R_H and
// the reconstruction from the selected model.
#include "dynaorb/tracking/two_view_initializer.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <future>
#include <numeric>
#include <random>

namespace dynaorb::tracking {

namespace {

// ransac_iterations sets of 8 distinct indices in [0, n): a partial Fisher-Yates shuffle per
// set (mt19937 output is fully specified, and the modulo keeps it independent of the
// standard library's distributions, so the sets are the same everywhere).
std::vector<std::vector<int>> sample_sets(int n, int iterations, std::uint32_t seed) {
  if (n < 8) return {};
  std::mt19937 rng(seed);
  std::vector<int> idx(n);
  std::iota(idx.begin(), idx.end(), 0);
  std::vector<std::vector<int>> sets(std::max(iterations, 0), std::vector<int>(8));
  for (auto& s : sets)
    for (int j = 0; j < 8; ++j) {
      const int k = j + static_cast<int>(rng() % static_cast<std::uint32_t>(n - j));
      std::swap(idx[j], idx[k]);
      s[j] = idx[j];
    }
  return sets;
}

TwoViewResult fail(TwoViewResult r, const std::string& reason) {
  r.ok = false;
  r.reason = reason;
  return r;
}

// r with the motion and points of one model (H when `homography`, else F, with its
// RANSAC score): refined on its inliers (refine_with_inliers), decomposed, the
// hypothesis with a clear lead taken; r.ok false with the reason otherwise.
void solve_with(TwoViewResult& r, bool homography, two_view::ModelScore model, Eigen::Matrix3d& H,
                Eigen::Matrix3d& F, const Eigen::Matrix3d& K, const two_view::Correspondences& c,
                const TwoViewOptions& o) {
  r.ok = false;
  r.reason.clear();
  r.used_homography = homography;
  if (o.refine_with_inliers)
    model = homography ? two_view::refine_homography(c, model, o, H) : two_view::refine_fundamental(c, model, o, F);
  r.n_inliers = model.n_inliers;
  std::vector<two_view::Motion> hypotheses;
  if (homography) {
    hypotheses = two_view::decompose_homography(H, K);
    if (hypotheses.empty()) {
      r = fail(r, "homography: singular values nearly equal, no translation (not enough parallax)");
      return;
    }
  } else {
    hypotheses = two_view::decompose_essential(K.transpose() * F * K);
  }
  two_view::select_motion(hypotheses, K, c, model, o, r);
  if (!r.ok) r.reason = (homography ? "homography: " : "fundamental: ") + r.reason;
}

}  // namespace

TwoViewResult TwoViewInitializer::initialize(const Eigen::Matrix3d& K,
                                             const std::vector<Eigen::Vector2d>& kps_ref,
                                             const std::vector<Eigen::Vector2d>& kps_cur,
                                             const std::vector<TwoViewMatch>& matches,
                                             const std::vector<double>& level_sigma2_ref,
                                             const std::vector<double>& level_sigma2_cur) const {
  const TwoViewOptions& o = options_;
  const int n = static_cast<int>(matches.size());
  TwoViewResult r;
  r.points.assign(n, Eigen::Vector3d::Zero());
  r.triangulated.assign(n, false);

  // ---- input checks
  if (!K.allFinite() || !(K(0, 0) > 0) || !(K(1, 1) > 0) || std::abs(K.determinant()) < 1e-12)
    return fail(r, "invalid camera matrix K");
  if (!level_sigma2_ref.empty() && level_sigma2_ref.size() != kps_ref.size())
    return fail(r, "level_sigma2_ref does not match the reference keypoints");
  if (!level_sigma2_cur.empty() && level_sigma2_cur.size() != kps_cur.size())
    return fail(r, "level_sigma2_cur does not match the current keypoints");
  if (!(o.sigma > 0)) return fail(r, "sigma must be positive");
  const int min_matches = std::max(8, o.min_triangulated);
  if (n < min_matches)
    return fail(r, "too few matches (" + std::to_string(n) + " < " +
                       std::to_string(min_matches) + ")");
  if (o.ransac_iterations < 1) return fail(r, "ransac_iterations must be positive");

  two_view::Correspondences c;
  c.x1.reserve(n), c.x2.reserve(n), c.w1.reserve(n), c.w2.reserve(n);
  const double inv_s2 = 1.0 / (o.sigma * o.sigma);
  for (const auto& [i1, i2] : matches) {
    if (i1 < 0 || i1 >= static_cast<int>(kps_ref.size()) || i2 < 0 ||
        i2 >= static_cast<int>(kps_cur.size()))
      return fail(r, "match index out of range");
    if (!kps_ref[i1].allFinite() || !kps_cur[i2].allFinite())
      return fail(r, "non-finite keypoint");
    const double l1 = level_sigma2_ref.empty() ? 1.0 : level_sigma2_ref[i1];
    const double l2 = level_sigma2_cur.empty() ? 1.0 : level_sigma2_cur[i2];
    if (!(l1 > 0) || !(l2 > 0)) return fail(r, "level sigma2 must be positive");
    c.x1.push_back(kps_ref[i1]);
    c.x2.push_back(kps_cur[i2]);
    c.w1.push_back(inv_s2 / l1);
    c.w2.push_back(inv_s2 / l2);
  }

  // ---- H and F on the same prefixed sample sets, in parallel
  const auto samples = sample_sets(n, o.ransac_iterations, o.seed);
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero(), F = Eigen::Matrix3d::Zero();
  two_view::ModelScore sh, sf;
  if (o.parallel) {
    auto fh = std::async(std::launch::async,
                         [&] { return two_view::ransac_homography(c, samples, o, H); });
    sf = two_view::ransac_fundamental(c, samples, o, F);
    sh = fh.get();
  } else {
    sh = two_view::ransac_homography(c, samples, o, H);
    sf = two_view::ransac_fundamental(c, samples, o, F);
  }
  r.score_h = sh.score;
  r.score_f = sf.score;
  if (!(sh.score + sf.score > 0)) return fail(r, "neither a homography nor a fundamental matrix fits");
  r.ratio_h = sh.score / (sh.score + sf.score);

  // ---- model selection and reconstruction
  const bool pick_h = r.ratio_h > o.ratio_h;
  solve_with(r, pick_h, pick_h ? sh : sf, H, F, K, c, o);
  if (r.ok || !o.try_other_model) return r;
  // Ours: the model R_H did not pick, when the picked one cannot reconstruct.
  TwoViewResult other = r;
  solve_with(other, !pick_h, pick_h ? sf : sh, H, F, K, c, o);
  if (other.ok) {
    other.other_model_used = true;
    return other;
  }
  r.reason += "; then " + other.reason;
  return r;
}

double median_depth(const TwoViewResult& result, double quantile) {
  std::vector<double> z;
  for (size_t i = 0; i < result.points.size() && i < result.triangulated.size(); ++i)
    if (result.triangulated[i]) z.push_back(result.points[i].z());
  if (z.empty()) return 0;
  const double q = std::clamp(quantile, 0.0, 1.0);
  const size_t k = std::min(z.size() - 1, static_cast<size_t>(q * (z.size() - 1) + 0.5));
  std::nth_element(z.begin(), z.begin() + k, z.end());
  return z[k];
}

}  // namespace dynaorb::tracking
