#pragma once
// ORB-SLAM's rotation consistency check: matches are binned by the
// difference of their keypoint angles; only the three fullest bins survive
// (the second and third only with at least 10 % of the fullest).
#include <algorithm>
#include <cmath>
#include <vector>

namespace dynaorb::match {

class RotationHistogram {
 public:
  explicit RotationHistogram(int bins) : bins_(bins), hist_(bins) {}

  void add(int id, double angle1_deg, double angle2_deg) {
    double rot = angle1_deg - angle2_deg;
    if (rot < 0) rot += 360.0;
    int bin = static_cast<int>(std::lround(rot * bins_ / 360.0));
    if (bin == bins_) bin = 0;
    hist_[std::clamp(bin, 0, bins_ - 1)].push_back(id);
  }

  // Ids of the matches outside the dominant bins.
  std::vector<int> rejected() const {
    int m1 = -1, m2 = -1, m3 = -1;
    auto size = [this](int b) { return b < 0 ? 0 : static_cast<int>(hist_[b].size()); };
    for (int b = 0; b < bins_; ++b) {
      const int s = size(b);
      if (s > size(m1)) {
        m3 = m2;
        m2 = m1;
        m1 = b;
      } else if (s > size(m2)) {
        m3 = m2;
        m2 = b;
      } else if (s > size(m3)) {
        m3 = b;
      }
    }
    if (size(m2) < 0.1 * size(m1)) m2 = m3 = -1;
    else if (size(m3) < 0.1 * size(m1)) m3 = -1;
    std::vector<int> out;
    for (int b = 0; b < bins_; ++b)
      if (b != m1 && b != m2 && b != m3) out.insert(out.end(), hist_[b].begin(), hist_[b].end());
    return out;
  }

 private:
  int bins_;
  std::vector<std::vector<int>> hist_;
};

}  // namespace dynaorb::match
