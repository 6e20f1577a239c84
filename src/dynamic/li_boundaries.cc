#include "dynaorb/dynamic/li_boundaries.h"

#include <algorithm>

namespace dynaorb::dynamic {

namespace {

// Sum over the set of (d_p - d_q)^2 and of (d_p - d_q), d_p - d_q = da x + db y + dc.
double sum_squared(const LiMoments& m, double da, double db, double dc) {
  return da * da * m.xx + db * db * m.yy + dc * dc * m.n + 2 * da * db * m.xy + 2 * da * dc * m.x +
         2 * db * dc * m.y;
}
double sum_difference(const LiMoments& m, double da, double db, double dc) {
  return da * m.x + db * m.y + dc * m.n;
}

}  // namespace

void li_label_boundary(LiBoundary& b, const LiPlane& pi, const LiPlane& pj, const LiMoments& u,
                       const LiOptions& o) {
  if (!pi.valid || !pj.valid || b.moments.n <= 0 || u.n <= 0) {
    b.type = LiBoundaryType::kUnknown;
    return;
  }
  const double da = pi.a - pj.a, db = pi.b - pj.b, dc = pi.c - pj.c;  // theta_i - theta_j
  const double front_i = sum_difference(b.moments, da, db, dc);      // sum over B of d_i - d_j
  b.energy[0] = sum_squared(u, da, db, dc) / u.n;                             // co
  b.energy[1] = sum_squared(b.moments, da, db, dc) / b.moments.n + o.lambda_hinge;  // hi
  b.energy[2] = (front_i < 0 ? o.lambda_pen : 0.0) + o.lambda_occ;           // lo: s_i in front
  b.energy[3] = (-front_i < 0 ? o.lambda_pen : 0.0) + o.lambda_occ;          // ro: s_j in front
  static constexpr LiBoundaryType kTypes[4] = {LiBoundaryType::kCoplanar, LiBoundaryType::kHinge,
                                               LiBoundaryType::kLeftOcclusion,
                                               LiBoundaryType::kRightOcclusion};
  int best = 0;
  for (int k = 1; k < 4; ++k)
    if (b.energy[k] < b.energy[best]) best = k;
  b.type = kTypes[best];
}

LiBoundaries li_label_boundaries(const cv::Mat& labels, const std::vector<LiPlane>& planes,
                                 const std::vector<cv::Rect>& areas, const LiOptions& o) {
  LiBoundaries out;
  const int count = static_cast<int>(planes.size());
  if (labels.empty() || labels.type() != CV_32SC1 || count == 0) return out;
  std::vector<LiMoments> region(count);
  auto boundary = [&](int a, int b) -> LiBoundary& {
    const uint64_t k = LiBoundaries::key(a, b);
    auto it = out.index.find(k);
    if (it == out.index.end()) {
      it = out.index.emplace(k, static_cast<int>(out.list.size())).first;
      LiBoundary nb;
      nb.i = std::min(a, b), nb.j = std::max(a, b);
      out.list.push_back(nb);
    }
    return out.list[it->second];
  };
  const cv::Rect frame(0, 0, labels.cols, labels.rows);
  for (const cv::Rect& r0 : areas) {
    const cv::Rect r = r0 & frame;
    for (int y = r.y; y < r.y + r.height; ++y) {
      const int* l = labels.ptr<int>(y);
      const int* below = y + 1 < labels.rows ? labels.ptr<int>(y + 1) : nullptr;
      for (int x = r.x; x < r.x + r.width; ++x) {
        const int a = l[x];
        if (a < 0 || a >= count) continue;
        region[a].add(x, y);
        // Right and lower neighbours, which may lie in an adjacent area.
        if (x + 1 < labels.cols && l[x + 1] >= 0 && l[x + 1] < count && l[x + 1] != a)
          boundary(a, l[x + 1]).moments.add(x + 0.5, y);
        if (below && below[x] >= 0 && below[x] < count && below[x] != a)
          boundary(a, below[x]).moments.add(x, y + 0.5);
      }
    }
  }
  for (LiBoundary& b : out.list) {
    LiMoments u = region[b.i];
    u += region[b.j];
    li_label_boundary(b, planes[b.i], planes[b.j], u, o);
  }
  return out;
}

}  // namespace dynaorb::dynamic
