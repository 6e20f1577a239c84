#pragma once
// Li et al. 2021, eq. 9-11: the type of the boundary between two adjacent
// superpixels s_i, s_j (i < j) with disparity planes theta_i, theta_j:
//   co-planar: E = mean over U_ij (both superpixels' pixels) of (d_i - d_j)^2
//   hinge:     E = mean over B_ij (the boundary) of (d_i - d_j)^2 + lambda_hinge
//   lo (s_i in front): E = phi_occ(theta_i, theta_j) + lambda_occ
//   ro (s_j in front): E = phi_occ(theta_j, theta_i) + lambda_occ
// with phi_occ(front, back) = lambda_pen when sum over B_ij of (d_front -
// d_back) < 0 (the "front" one would be behind), else 0. With the planes
// fixed (RANSAC, eq. 8) the energy E = E_smo + E_prior is a sum of one term
// per boundary, so its minimum is each boundary's cheapest label.
//
// B_ij holds the midpoints between 4-adjacent pixels of s_i and s_j (as in
// Yamaguchi et al.'s SPS-Stereo, whose boundary energy this is). The sums of
// squares over B_ij and U_ij come from their first and second moments, so a
// boundary costs O(1) however many pixels it has.
#include <cstdint>
#include <opencv2/core.hpp>
#include <unordered_map>
#include <vector>

#include "dynaorb/dynamic/li_options.h"
#include "dynaorb/dynamic/li_planes.h"

namespace dynaorb::dynamic {

enum class LiBoundaryType : uint8_t { kUnknown, kCoplanar, kHinge, kLeftOcclusion, kRightOcclusion };

inline bool is_occlusion(LiBoundaryType t) {
  return t == LiBoundaryType::kLeftOcclusion || t == LiBoundaryType::kRightOcclusion;
}

// Sums of 1, x, y, x^2, y^2, xy over a set of points.
struct LiMoments {
  double n = 0, x = 0, y = 0, xx = 0, yy = 0, xy = 0;
  void add(double px, double py) { n += 1, x += px, y += py, xx += px * px, yy += py * py, xy += px * py; }
  LiMoments& operator+=(const LiMoments& m) {
    n += m.n, x += m.x, y += m.y, xx += m.xx, yy += m.yy, xy += m.xy;
    return *this;
  }
};

struct LiBoundary {
  int i = -1, j = -1;  // i < j
  LiMoments moments;   // of B_ij
  LiBoundaryType type = LiBoundaryType::kUnknown;  // kUnknown: a superpixel without a plane
  double energy[4] = {0, 0, 0, 0};                 // co, hinge, lo, ro
};

struct LiBoundaries {
  std::vector<LiBoundary> list;
  std::unordered_map<uint64_t, int> index;  // key(i, j) -> list position
  static uint64_t key(int a, int b) {
    const auto lo = static_cast<uint32_t>(std::min(a, b)), hi = static_cast<uint32_t>(std::max(a, b));
    return (static_cast<uint64_t>(lo) << 32) | hi;
  }
  LiBoundaryType between(int a, int b) const {
    const auto it = index.find(key(a, b));
    return it == index.end() ? LiBoundaryType::kUnknown : list[it->second].type;
  }
};

// Eq. 9-11 for one boundary: fills b.energy and b.type from the planes and
// the moments of B_ij (b.moments) and of U_ij (`u`).
void li_label_boundary(LiBoundary& b, const LiPlane& pi, const LiPlane& pj, const LiMoments& u,
                       const LiOptions& o);

// Finds every boundary between the superpixels 0 .. planes.size()-1 of
// `labels` (CV_32SC1, -1 = none) whose left/upper pixel lies in `areas`, and
// labels it.
LiBoundaries li_label_boundaries(const cv::Mat& labels, const std::vector<LiPlane>& planes,
                                 const std::vector<cv::Rect>& areas, const LiOptions& o);

}  // namespace dynaorb::dynamic
