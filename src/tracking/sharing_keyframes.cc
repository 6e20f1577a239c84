#include "dynaorb/tracking/sharing_keyframes.h"

#include <algorithm>
#include <map>

namespace dynaorb::tracking {

std::vector<std::pair<map::KeyFrame*, int>> sharing_keyframes(const map::Frame& f, int max_keyframes) {
  std::map<long, std::pair<map::KeyFrame*, int>> counts;
  for (int i = 0; i < f.size(); ++i) {
    const auto& p = f.points[i];
    if (!p || p->erased() || f.outlier[i]) continue;
    for (const map::MapPoint::Observation& o : p->observations()) {
      if (o.keyframe->erased()) continue;
      auto& entry = counts[o.keyframe->id];
      entry.first = o.keyframe;
      ++entry.second;
    }
  }
  std::vector<std::pair<map::KeyFrame*, int>> ring;
  ring.reserve(counts.size());
  for (const auto& [id, kn] : counts) ring.push_back(kn);
  const auto cap = static_cast<size_t>(std::max(0, max_keyframes));
  if (cap > 0 && ring.size() > cap) {
    // Stable: among equal counts the lower id (earlier in `ring`) stays.
    std::stable_sort(ring.begin(), ring.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    ring.resize(cap);
    std::sort(ring.begin(), ring.end(), [](const auto& a, const auto& b) { return a.first->id < b.first->id; });
  }
  return ring;
}

}  // namespace dynaorb::tracking
