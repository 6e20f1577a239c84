#include "dynaorb/dynamic/li_planes.h"

#include <algorithm>
#include <cmath>

namespace dynaorb::dynamic {

namespace {

// Plane through three samples; false when they are (nearly) collinear.
bool plane_through(const cv::Point3f& p, const cv::Point3f& q, const cv::Point3f& r, LiPlane& out) {
  const cv::Matx33d A(p.x, p.y, 1, q.x, q.y, 1, r.x, r.y, 1);
  const double det = cv::determinant(A);
  if (std::abs(det) < 1e-6) return false;
  const cv::Vec3d s = A.inv() * cv::Vec3d(p.z, q.z, r.z);
  out.a = s[0], out.b = s[1], out.c = s[2];
  return true;
}

// Least squares on the points within `thr` of `pl` (normal equations, centred
// for conditioning). Leaves `pl` as is when the inliers are degenerate.
int refit(const std::vector<cv::Point3f>& pts, double thr, LiPlane& pl) {
  double mx = 0, my = 0, md = 0;
  int n = 0;
  for (const cv::Point3f& p : pts)
    if (std::abs(p.z - pl.at(p.x, p.y)) <= thr) mx += p.x, my += p.y, md += p.z, ++n;
  if (n < 3) return n;
  mx /= n, my /= n, md /= n;
  double sxx = 0, sxy = 0, syy = 0, sxd = 0, syd = 0;
  for (const cv::Point3f& p : pts) {
    if (std::abs(p.z - pl.at(p.x, p.y)) > thr) continue;
    const double x = p.x - mx, y = p.y - my, d = p.z - md;
    sxx += x * x, sxy += x * y, syy += y * y, sxd += x * d, syd += y * d;
  }
  const double det = sxx * syy - sxy * sxy;
  if (std::abs(det) < 1e-9 * std::max(1.0, sxx * syy)) return n;
  pl.a = (sxd * syy - syd * sxy) / det;
  pl.b = (syd * sxx - sxd * sxy) / det;
  pl.c = md - pl.a * mx - pl.b * my;
  int m = 0;
  for (const cv::Point3f& p : pts) m += std::abs(p.z - pl.at(p.x, p.y)) <= thr ? 1 : 0;
  return m;
}

}  // namespace

LiPlane li_fit_disparity_plane(const std::vector<cv::Point3f>& xyd, const LiOptions& o, cv::RNG& rng) {
  LiPlane best;
  const int n = static_cast<int>(xyd.size());
  best.support = n;
  if (n < std::max(3, o.plane_min_pixels)) return best;
  // An even subsample scores the hypotheses: a superpixel has a few hundred
  // pixels, and the plane is decided as well by 200 of them.
  std::vector<cv::Point3f> sub;
  const int m = std::min(n, o.plane_max_samples);
  sub.reserve(m);
  for (int i = 0; i < m; ++i) sub.push_back(xyd[static_cast<size_t>(i) * n / m]);
  const double thr = o.plane_inlier_px;
  int best_count = -1;
  double needed = o.plane_ransac_iterations;
  for (int it = 0; it < o.plane_ransac_iterations && it < needed; ++it) {
    const int i = rng.uniform(0, m), j = rng.uniform(0, m), k = rng.uniform(0, m);
    if (i == j || j == k || i == k) continue;
    LiPlane h;
    if (!plane_through(sub[i], sub[j], sub[k], h)) continue;
    int count = 0;
    for (const cv::Point3f& p : sub) count += std::abs(p.z - h.at(p.x, p.y)) <= thr ? 1 : 0;
    if (count > best_count) {
      best_count = count;
      best.a = h.a, best.b = h.b, best.c = h.c;
      // Adaptive stop at 99 % confidence of one all-inlier sample.
      const double w = static_cast<double>(count) / m;
      const double p_good = w * w * w;
      needed = p_good >= 1.0 ? 0 : std::log(0.01) / std::log(1.0 - std::max(p_good, 1e-9));
    }
  }
  if (best_count < 3) return best;
  best.inliers = refit(xyd, thr, best);
  best.valid = best.inliers >= 3;
  return best;
}

std::vector<LiPlane> li_fit_superpixel_planes(const cv::Mat& labels, int count, const cv::Mat& disparity,
                                              const std::vector<cv::Rect>& areas, const LiOptions& o) {
  std::vector<LiPlane> planes(std::max(count, 0));
  if (count <= 0 || labels.type() != CV_32SC1 || disparity.type() != CV_32FC1 ||
      labels.size() != disparity.size())
    return planes;
  // Bucket the pixels with disparity by superpixel (a counting sort).
  std::vector<int> start(count + 1, 0);
  const cv::Rect frame(0, 0, labels.cols, labels.rows);
  for (const cv::Rect& r0 : areas) {
    const cv::Rect r = r0 & frame;
    for (int y = r.y; y < r.y + r.height; ++y) {
      const int* l = labels.ptr<int>(y);
      const float* d = disparity.ptr<float>(y);
      for (int x = r.x; x < r.x + r.width; ++x)
        if (l[x] >= 0 && l[x] < count && d[x] > 0.f) ++start[l[x] + 1];
    }
  }
  for (int k = 0; k < count; ++k) start[k + 1] += start[k];
  std::vector<cv::Point3f> pts(start[count]);
  std::vector<int> cursor(start.begin(), start.end() - 1);
  for (const cv::Rect& r0 : areas) {
    const cv::Rect r = r0 & frame;
    for (int y = r.y; y < r.y + r.height; ++y) {
      const int* l = labels.ptr<int>(y);
      const float* d = disparity.ptr<float>(y);
      for (int x = r.x; x < r.x + r.width; ++x)
        if (l[x] >= 0 && l[x] < count && d[x] > 0.f)
          pts[cursor[l[x]]++] = cv::Point3f(static_cast<float>(x), static_cast<float>(y), d[x]);
    }
  }
  cv::RNG rng(0x4c69);  // fixed seed: the same frame gives the same planes
  std::vector<cv::Point3f> one;
  for (int k = 0; k < count; ++k) {
    one.assign(pts.begin() + start[k], pts.begin() + start[k + 1]);
    planes[k] = li_fit_disparity_plane(one, o, rng);
  }
  return planes;
}

}  // namespace dynaorb::dynamic
