#include "dynaorb/place/pnp_ransac.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <random>

namespace dynaorb::place {

namespace {

constexpr int kMinimalSet = 4;  // EPnP's minimum

// EPnP on the matches at `idx`; false when OpenCV finds no finite pose.
bool solve_epnp(const std::vector<PnpMatch>& m, const std::vector<int>& idx, const cv::Matx33d& K,
                Eigen::Isometry3d& T_cw) {
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  obj.reserve(idx.size());
  img.reserve(idx.size());
  for (int i : idx) {
    obj.emplace_back(m[i].point_world.x(), m[i].point_world.y(), m[i].point_world.z());
    img.emplace_back(m[i].pixel.x(), m[i].pixel.y());
  }
  cv::Mat rvec, tvec;
  try {
    if (!cv::solvePnP(obj, img, K, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_EPNP)) return false;
  } catch (const cv::Exception&) {
    return false;  // degenerate set
  }
  if (!cv::checkRange(rvec) || !cv::checkRange(tvec)) return false;
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  T_cw.setIdentity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T_cw.linear()(r, c) = R(r, c);
    T_cw.translation()(r) = tvec.at<double>(r);
  }
  return true;
}

int classify(const std::vector<PnpMatch>& m, const Eigen::Isometry3d& T_cw, const PinholeK& K, double chi2,
             std::vector<bool>& inlier) {
  inlier.assign(m.size(), false);
  int n = 0;
  for (size_t i = 0; i < m.size(); ++i) {
    const Eigen::Vector3d pc = T_cw * m[i].point_world;
    if (pc.z() <= 0) continue;
    const double u = K.fx * pc.x() / pc.z() + K.cx, v = K.fy * pc.y() / pc.z() + K.cy;
    const double du = u - m[i].pixel.x(), dv = v - m[i].pixel.y();
    if (du * du + dv * dv < chi2 * m[i].sigma2) {
      inlier[i] = true;
      ++n;
    }
  }
  return n;
}

}  // namespace

PnpRansacResult pnp_ransac(const std::vector<PnpMatch>& matches, const PinholeK& K,
                           const PnpRansacOptions& o) {
  PnpRansacResult best;
  const int n = static_cast<int>(matches.size());
  if (n < std::max(kMinimalSet, o.min_inliers)) return best;
  const cv::Matx33d Kcv(K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1);
  std::mt19937 rng(o.seed);
  std::vector<int> all(n), sample(kMinimalSet);
  for (int i = 0; i < n; ++i) all[i] = i;
  std::vector<bool> inlier;
  int needed = o.max_iterations;
  for (int it = 0; it < std::min(needed, o.max_iterations); ++it) {
    ++best.iterations;
    // A random minimal set: a partial Fisher-Yates shuffle.
    for (int k = 0; k < kMinimalSet; ++k) {
      std::uniform_int_distribution<int> pick(k, n - 1);
      std::swap(all[k], all[pick(rng)]);
      sample[k] = all[k];
    }
    Eigen::Isometry3d T;
    if (!solve_epnp(matches, sample, Kcv, T)) continue;
    const int count = classify(matches, T, K, o.chi2, inlier);
    if (count <= best.inliers) continue;
    best.inliers = count;
    best.T_cw = T;
    best.inlier = inlier;
    // Iterations for an all-inlier minimal set with the given probability.
    const double w = static_cast<double>(count) / n;
    const double p_fail = 1.0 - std::pow(w, kMinimalSet);
    if (p_fail <= 0.0) break;
    const double its = std::log(1.0 - o.probability) / std::log(p_fail);  // +inf when p_fail rounds to 1
    needed = its < o.max_iterations ? static_cast<int>(std::ceil(its)) : o.max_iterations;
  }
  if (best.inliers < o.min_inliers) return best;
  // EPnP on every inlier; kept when it explains at least as many matches.
  std::vector<int> in_idx;
  for (int i = 0; i < n; ++i)
    if (best.inlier[i]) in_idx.push_back(i);
  Eigen::Isometry3d refined;
  if (solve_epnp(matches, in_idx, Kcv, refined)) {
    const int count = classify(matches, refined, K, o.chi2, inlier);
    if (count >= best.inliers) {
      best.T_cw = refined;
      best.inlier = inlier;
      best.inliers = count;
    }
  }
  best.ok = best.inliers >= o.min_inliers;
  return best;
}

}  // namespace dynaorb::place
