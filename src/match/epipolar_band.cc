#include "epipolar_band.h"

#include <algorithm>
#include <cmath>

namespace dynaorb::match {

namespace {
// A point with finite coordinates and limit goes into the strips; any other is tested always.
bool bucketable(const EpipolarBand::Point& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.limit2);
}
}  // namespace

EpipolarBand::EpipolarBand(std::vector<Point> points, int strips) : points_(std::move(points)) {
  double max_limit2 = 0;
  for (size_t i = 0; i < points_.size(); ++i) {
    const Point& p = points_[i];
    if (bucketable(p))
      max_limit2 = std::max(max_limit2, p.limit2);
    else
      unbucketed_.push_back(static_cast<int>(i));  // tested by every query
  }
  max_distance_ = std::sqrt(max_limit2);
  by_x_ = bucket(true, std::max(strips, 1));
  by_y_ = bucket(false, std::max(strips, 1));
}

EpipolarBand::Strips EpipolarBand::bucket(bool across_x, int n) const {
  Strips st;
  st.strip.assign(n, {});
  auto u_of = [&](const Point& p) { return across_x ? p.x : p.y; };
  double lo = INFINITY, hi = -INFINITY;
  for (const Point& p : points_) {
    if (!bucketable(p)) continue;
    lo = std::min(lo, u_of(p));
    hi = std::max(hi, u_of(p));
  }
  if (!(lo <= hi)) return st;  // no bucketed point
  st.lo = lo;
  st.width = hi > lo ? (hi - lo) / n : 1.0;
  for (size_t i = 0; i < points_.size(); ++i) {
    const Point& p = points_[i];
    if (!bucketable(p)) continue;
    const int s = std::clamp(static_cast<int>(std::floor((u_of(p) - lo) / st.width)), 0, n - 1);
    st.strip[s].push_back({across_x ? p.y : p.x, static_cast<int>(i)});
  }
  for (auto& s : st.strip)
    std::sort(s.begin(), s.end(), [](const Entry& a, const Entry& b) { return a.along < b.along; });
  return st;
}

bool EpipolarBand::passes(const Eigen::Vector3d& line, double norm2, int index) const {
  const Point& p = points_[index];
  const double num = line.x() * p.x + line.y() * p.y + line.z();
  return !(num * num / norm2 >= p.limit2);
}

void EpipolarBand::near(const Eigen::Vector3d& line, std::vector<int>* ids) const {
  ids->clear();
  hits_.clear();
  const double a = line.x(), b = line.y(), c = line.z(), norm2 = a * a + b * b;
  if (!std::isfinite(norm2) || !std::isfinite(c) || norm2 == 0) {
    for (size_t i = 0; i < points_.size(); ++i)
      if (passes(line, norm2, static_cast<int>(i))) ids->push_back(points_[i].id);
    return;
  }
  // u: the strips' coordinate, v: the one they are sorted by. The line is p u + q v + c = 0
  // with |q| >= |p| (so q != 0): v = -(c + p u) / q, and the points within distance D of it lie
  // within D * sqrt(norm2) / |q| of that in v; over a strip, v is extreme at its two ends.
  const bool across_x = std::abs(b) >= std::abs(a);
  const Strips& st = across_x ? by_x_ : by_y_;
  const double p = across_x ? a : b, q = across_x ? b : a;
  const double half = max_distance_ * std::sqrt(norm2) / std::abs(q) + 1.0;  // + 1 px of slack
  for (size_t s = 0; s < st.strip.size(); ++s) {
    const std::vector<Entry>& strip = st.strip[s];
    if (strip.empty()) continue;
    const double u0 = st.lo + s * st.width, u1 = u0 + st.width;
    const double v0 = -(c + p * u0) / q, v1 = -(c + p * u1) / q;
    const double lo = std::min(v0, v1) - half, hi = std::max(v0, v1) + half;
    auto it = std::lower_bound(strip.begin(), strip.end(), lo,
                               [](const Entry& e, double v) { return e.along < v; });
    for (; it != strip.end() && it->along <= hi; ++it)
      if (passes(line, norm2, it->index)) hits_.push_back(it->index);
  }
  for (int i : unbucketed_)
    if (passes(line, norm2, i)) hits_.push_back(i);
  std::sort(hits_.begin(), hits_.end());
  for (int i : hits_) ids->push_back(points_[i].id);
}

}  // namespace dynaorb::match
