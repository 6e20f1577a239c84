#include "dynaorb/dynamic/li_regions.h"

#include <algorithm>
#include <climits>

namespace dynaorb::dynamic {

std::vector<LiRegion> li_dynamic_rectangles(const std::vector<cv::Point2f>& points,
                                            const std::vector<LiCluster>& clusters,
                                            const cv::Mat& labels, const LiBoundaries& boundaries,
                                            const LiOptions& o) {
  std::vector<LiRegion> out;
  if (labels.empty() || labels.type() != CV_32SC1) return out;
  static constexpr int kDx[4] = {1, -1, 0, 0}, kDy[4] = {0, 0, 1, -1};
  for (const LiCluster& c : clusters) {
    LiRegion reg;
    int x0 = INT_MAX, y0 = INT_MAX, x1 = INT_MIN, y1 = INT_MIN;
    auto include = [&](int x, int y) {
      x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
    };
    bool found[4] = {false, false, false, false};
    for (int m : c.members) {
      if (m < 0 || m >= static_cast<int>(points.size())) continue;
      const int sx = cvRound(points[m].x), sy = cvRound(points[m].y);
      if (sx < 0 || sy < 0 || sx >= labels.cols || sy >= labels.rows) continue;
      include(sx, sy);
      const int start = labels.at<int>(sy, sx);
      if (start < 0) continue;
      for (int d = 0; d < 4; ++d) {
        int prev = start, x = sx, y = sy;
        while (true) {
          const int nx = x + kDx[d], ny = y + kDy[d];
          if (nx < 0 || ny < 0 || nx >= labels.cols || ny >= labels.rows) break;
          const int l = labels.at<int>(ny, nx);
          if (l < 0) break;  // left the segmented ROI
          if (l != prev && is_occlusion(boundaries.between(prev, l))) {
            include(x, y);
            ++reg.hits;
            found[d] = true;
            break;
          }
          prev = l, x = nx, y = ny;
        }
      }
    }
    for (bool f : found) reg.hit_directions += f ? 1 : 0;
    reg.dynamic = reg.hits > 0 && reg.hit_directions >= o.min_hit_directions;
    if (reg.dynamic && x1 >= x0 && y1 >= y0) reg.rect = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
    else reg.dynamic = false;
    out.push_back(reg);
  }
  return out;
}

}  // namespace dynaorb::dynamic
