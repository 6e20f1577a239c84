#include "dynaorb/dynamic/li_rois.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace dynaorb::dynamic {

namespace {

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

}  // namespace

std::vector<LiCluster> li_cluster_dynamic_points(const std::vector<cv::Point2f>& points,
                                                 const std::vector<float>& disparities,
                                                 const cv::Size& image, const LiOptions& o) {
  std::vector<LiCluster> out;
  const int n = static_cast<int>(points.size());
  if (n == 0 || disparities.size() != points.size()) return out;
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const double dd = std::abs(disparities[i] - disparities[j]);
      if (dd > o.t_disp) continue;
      // Eq. 4 with d the pair's mean disparity: the relation stays symmetric,
      // and the two disparities differ by at most T_disp anyway.
      const double ts = o.alpha_s + o.beta_s * 0.5 * (disparities[i] + disparities[j]);
      if (cv::norm(points[i] - points[j]) > ts) continue;
      parent[find_root(parent, i)] = find_root(parent, j);
    }
  }
  std::vector<std::vector<int>> groups(n);
  for (int i = 0; i < n; ++i) groups[find_root(parent, i)].push_back(i);
  const cv::Rect frame(0, 0, image.width, image.height);
  for (auto& g : groups) {
    if (static_cast<int>(g.size()) < o.min_cluster_points) continue;
    LiCluster c;
    c.members = std::move(g);
    float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
    c.min_disparity = disparities[c.members.front()];
    for (int i : c.members) {
      c.mean_disparity += disparities[i];
      c.min_disparity = std::min(c.min_disparity, disparities[i]);
      x0 = std::min(x0, points[i].x);
      y0 = std::min(y0, points[i].y);
      x1 = std::max(x1, points[i].x);
      y1 = std::max(y1, points[i].y);
    }
    c.mean_disparity /= static_cast<double>(c.members.size());
    const int bx0 = static_cast<int>(std::floor(x0)), by0 = static_cast<int>(std::floor(y0));
    c.bounds = cv::Rect(bx0, by0, static_cast<int>(std::ceil(x1)) - bx0 + 1,
                        static_cast<int>(std::ceil(y1)) - by0 + 1) & frame;
    const int m = static_cast<int>(
        std::lround(o.roi_margin_factor * (o.alpha_s + o.beta_s * c.mean_disparity)));
    c.roi = cv::Rect(c.bounds.x - m, c.bounds.y - m, c.bounds.width + 2 * m, c.bounds.height + 2 * m) & frame;
    if (c.roi.area() > 0) out.push_back(std::move(c));
  }
  std::sort(out.begin(), out.end(),
            [](const LiCluster& a, const LiCluster& b) { return a.members.size() > b.members.size(); });
  return out;
}

std::vector<cv::Rect> li_merge_overlapping(std::vector<cv::Rect> rects) {
  rects.erase(std::remove_if(rects.begin(), rects.end(), [](const cv::Rect& r) { return r.area() <= 0; }),
              rects.end());
  bool merged = true;
  while (merged) {
    merged = false;
    for (size_t i = 0; i < rects.size() && !merged; ++i) {
      for (size_t j = i + 1; j < rects.size(); ++j) {
        if ((rects[i] & rects[j]).area() > 0) {
          rects[i] |= rects[j];
          rects.erase(rects.begin() + static_cast<long>(j));
          merged = true;
          break;
        }
      }
    }
  }
  return rects;
}

}  // namespace dynaorb::dynamic
