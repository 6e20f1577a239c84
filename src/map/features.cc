#include "dynaorb/map/features.h"

#include <algorithm>
#include <cmath>

namespace dynaorb::map {

void Features::build_grid() {
  cell_inv_w_ = kGridCols / (calib->max_x - calib->min_x);
  cell_inv_h_ = kGridRows / (calib->max_y - calib->min_y);
  grid_.assign(kGridCols * kGridRows, {});
  for (int i = 0; i < size(); ++i) {
    const int cx = static_cast<int>(std::floor((keys_un[i].pt.x - calib->min_x) * cell_inv_w_));
    const int cy = static_cast<int>(std::floor((keys_un[i].pt.y - calib->min_y) * cell_inv_h_));
    if (cx < 0 || cx >= kGridCols || cy < 0 || cy >= kGridRows) continue;  // undistorted out of bounds
    grid_[cy * kGridCols + cx].push_back(i);
  }
}

std::vector<int> Features::in_area(double x, double y, double radius, int min_level,
                                   int max_level) const {
  std::vector<int> out;
  const int c0 = std::max(0, static_cast<int>(std::floor((x - calib->min_x - radius) * cell_inv_w_)));
  const int c1 = std::min(kGridCols - 1, static_cast<int>(std::floor((x - calib->min_x + radius) * cell_inv_w_)));
  const int r0 = std::max(0, static_cast<int>(std::floor((y - calib->min_y - radius) * cell_inv_h_)));
  const int r1 = std::min(kGridRows - 1, static_cast<int>(std::floor((y - calib->min_y + radius) * cell_inv_h_)));
  if (c0 > c1 || r0 > r1) return out;
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      for (int i : grid_[r * kGridCols + c]) {
        const cv::KeyPoint& k = keys_un[i];
        if (min_level >= 0 && k.octave < min_level) continue;
        if (max_level >= 0 && k.octave > max_level) continue;
        if (std::abs(k.pt.x - x) < radius && std::abs(k.pt.y - y) < radius) out.push_back(i);
      }
    }
  }
  return out;
}

}  // namespace dynaorb::map
