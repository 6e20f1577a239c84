// Matching for the monocular initialisation (ORB-SLAM2's
// ORBmatcher::SearchForInitialization): no pose and no map yet, so the
// keypoints of the reference frame are searched in a window around where
// they were last seen, on the finest pyramid level only.
#include <climits>

#include "dynaorb/match/hamming.h"
#include "dynaorb/match/matcher.h"
#include "rotation_histogram.h"

namespace dynaorb::match {

int Matcher::search_for_initialization(const map::Features& f1, const map::Features& f2,
                                       std::vector<Eigen::Vector2d>& prev_matched,
                                       std::vector<int>& matches12, double window,
                                       double nn_ratio) const {
  matches12.assign(f1.size(), -1);
  if (static_cast<int>(prev_matched.size()) != f1.size()) {
    prev_matched.resize(f1.size());
    for (int i = 0; i < f1.size(); ++i)
      prev_matched[i] = {f1.keys_un[i].pt.x, f1.keys_un[i].pt.y};
  }
  std::vector<int> matched_distance(f2.size(), INT_MAX), matches21(f2.size(), -1);
  RotationHistogram hist(o_.histogram_bins);
  int n = 0;
  std::vector<int> cand;
  for (int i1 = 0; i1 < f1.size(); ++i1) {
    const int level = f1.keys_un[i1].octave;
    if (level > 0) continue;  // ORB-SLAM2: the finest level only
    f2.in_area(prev_matched[i1].x(), prev_matched[i1].y(), window, level, level, cand);
    int best = INT_MAX, second = INT_MAX, best_i2 = -1;
    for (int i2 : cand) {
      const int d = hamming(f1.descriptor(i1), f2.descriptor(i2));
      if (matched_distance[i2] <= d) continue;
      if (d < best) {
        second = best;
        best = d;
        best_i2 = i2;
      } else if (d < second) {
        second = d;
      }
    }
    if (best_i2 < 0 || best > o_.th_low) continue;
    if (!(best < nn_ratio * static_cast<double>(second))) continue;
    if (matches21[best_i2] >= 0) {
      matches12[matches21[best_i2]] = -1;
      --n;
    }
    matches12[i1] = best_i2;
    matches21[best_i2] = i1;
    matched_distance[best_i2] = best;
    ++n;
    if (o_.check_orientation) hist.add(i1, f1.keys_un[i1].angle, f2.keys_un[best_i2].angle);
  }
  if (o_.check_orientation) {
    for (int i1 : hist.rejected()) {
      if (matches12[i1] >= 0) {
        matches12[i1] = -1;
        --n;
      }
    }
  }
  for (int i1 = 0; i1 < f1.size(); ++i1)
    if (matches12[i1] >= 0)
      prev_matched[i1] = {f2.keys_un[matches12[i1]].pt.x, f2.keys_un[matches12[i1]].pt.y};
  return n;
}

}  // namespace dynaorb::match
