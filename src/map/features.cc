#include "dynaorb/map/features.h"

#include <algorithm>
#include <cmath>

namespace dynaorb::map {

void Features::build_grid() {
  cell_inv_w_ = kGridCols / (calib->max_x - calib->min_x);
  cell_inv_h_ = kGridRows / (calib->max_y - calib->min_y);
  // A counting sort of the keypoints by cell, stable: ascending index within a cell.
  const int n = size();
  std::vector<int> cell_of(n, -1);
  cell_start_.assign(kGridCols * kGridRows + 1, 0);
  for (int i = 0; i < n; ++i) {
    const int cx = static_cast<int>(std::floor((keys_un[i].pt.x - calib->min_x) * cell_inv_w_));
    const int cy = static_cast<int>(std::floor((keys_un[i].pt.y - calib->min_y) * cell_inv_h_));
    if (cx < 0 || cx >= kGridCols || cy < 0 || cy >= kGridRows) continue;  // undistorted out of bounds
    cell_of[i] = cy * kGridCols + cx;
    ++cell_start_[cell_of[i] + 1];
  }
  for (int k = 0; k < kGridCols * kGridRows; ++k) cell_start_[k + 1] += cell_start_[k];
  cell_items_.resize(cell_start_.back());
  std::vector<int> next(cell_start_.begin(), cell_start_.end() - 1);
  for (int i = 0; i < n; ++i) {
    if (cell_of[i] < 0) continue;
    const cv::KeyPoint& k = keys_un[i];
    cell_items_[next[cell_of[i]]++] = {k.pt.x, k.pt.y, k.octave, i};
  }
}

std::vector<int> Features::in_area(double x, double y, double radius, int min_level,
                                   int max_level) const {
  std::vector<int> out;
  in_area(x, y, radius, min_level, max_level, out);
  return out;
}

void Features::in_area(double x, double y, double radius, int min_level, int max_level,
                       std::vector<int>& out) const {
  out.clear();
  if (cell_start_.empty()) return;  // no grid built
  const int c0 = std::max(0, static_cast<int>(std::floor((x - calib->min_x - radius) * cell_inv_w_)));
  const int c1 = std::min(kGridCols - 1, static_cast<int>(std::floor((x - calib->min_x + radius) * cell_inv_w_)));
  const int r0 = std::max(0, static_cast<int>(std::floor((y - calib->min_y - radius) * cell_inv_h_)));
  const int r1 = std::min(kGridRows - 1, static_cast<int>(std::floor((y - calib->min_y + radius) * cell_inv_h_)));
  if (c0 > c1 || r0 > r1) return;
  for (int r = r0; r <= r1; ++r) {
    // The row's cells c0..c1 are contiguous in cell_items_.
    const GridItem* it = cell_items_.data() + cell_start_[r * kGridCols + c0];
    const GridItem* end = cell_items_.data() + cell_start_[r * kGridCols + c1 + 1];
    for (; it != end; ++it) {
      if (min_level >= 0 && it->octave < min_level) continue;
      if (max_level >= 0 && it->octave > max_level) continue;
      if (std::abs(it->x - x) < radius && std::abs(it->y - y) < radius) out.push_back(it->index);
    }
  }
}

}  // namespace dynaorb::map
