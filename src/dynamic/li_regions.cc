#include "dynaorb/dynamic/li_regions.h"

#include <algorithm>
#include <climits>

#include "dynaorb/dynamic/semantic_stage.h"

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

void li_mark_region(cv::Mat& mask, const cv::Rect& rect, const cv::Mat& disparity, float object_disparity,
                    const LiOptions& o) {
  const cv::Rect r = rect & cv::Rect(0, 0, mask.cols, mask.rows);
  if (r.area() == 0) return;
  if (!o.foreground_only || !(object_disparity > 0) || disparity.size() != mask.size() ||
      disparity.type() != CV_32FC1) {
    mask(r).setTo(255);
    return;
  }
  const float least = object_disparity - static_cast<float>(o.foreground_margin_px);
  cv::Mat near(r.size(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < r.height; ++y) {
    const float* d = disparity.ptr<float>(y + r.y) + r.x;
    unsigned char* n = near.ptr<unsigned char>(y);
    for (int x = 0; x < r.width; ++x)
      if (!(d[x] > 0.f) || d[x] >= least) n[x] = 255;
  }
  cv::Mat dst = mask(r);
  cv::bitwise_or(dst, widen_by_disc(near, o.foreground_band_px), dst);
}

}  // namespace dynaorb::dynamic
