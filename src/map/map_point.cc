#include "dynaorb/map/map_point.h"

#include <algorithm>
#include <cstring>

#include "dynaorb/map/keyframe.h"
#include "dynaorb/match/hamming.h"

namespace dynaorb::map {

MapPoint::MapPoint(long id_, const Eigen::Vector3d& position, KeyFrame* reference,
                   long first_keyframe_id_)
    : id(id_), first_keyframe_id(first_keyframe_id_), position_(position), reference_(reference) {}

int MapPoint::index_in(const KeyFrame* kf) const {
  for (const Observation& o : observations_)
    if (o.keyframe == kf) return o.index;
  return -1;
}

void MapPoint::add_observation(KeyFrame* kf, int index) {
  if (index_in(kf) >= 0) return;
  observations_.push_back({kf, index});
  n_obs_ += kf->f().u_right[index] >= 0 ? 2 : 1;
}

void MapPoint::erase_observation(KeyFrame* kf) {
  auto it = std::find_if(observations_.begin(), observations_.end(),
                         [kf](const Observation& o) { return o.keyframe == kf; });
  if (it == observations_.end()) return;
  n_obs_ -= kf->f().u_right[it->index] >= 0 ? 2 : 1;
  observations_.erase(it);
  if (reference_ == kf) reference_ = observations_.empty() ? nullptr : observations_.front().keyframe;
}

void MapPoint::set_descriptor(const std::uint8_t* d) { std::memcpy(descriptor_.data(), d, 32); }

void MapPoint::compute_distinctive_descriptor() {
  const size_t n = observations_.size();
  if (n == 0) return;
  std::vector<const std::uint8_t*> descs;
  descs.reserve(n);
  for (const Observation& o : observations_) descs.push_back(o.keyframe->f().descriptor(o.index));
  std::vector<int> dist(n * n, 0);
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j) dist[i * n + j] = dist[j * n + i] = match::hamming(descs[i], descs[j]);
  int best = INT32_MAX;
  size_t best_i = 0;
  std::vector<int> row(n);
  for (size_t i = 0; i < n; ++i) {
    std::copy(dist.begin() + i * n, dist.begin() + (i + 1) * n, row.begin());
    std::nth_element(row.begin(), row.begin() + (n - 1) / 2, row.end());
    const int median = row[(n - 1) / 2];
    if (median < best) {
      best = median;
      best_i = i;
    }
  }
  set_descriptor(descs[best_i]);
}

void MapPoint::update_normal_and_depth() {
  if (observations_.empty() || reference_ == nullptr) return;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (const Observation& o : observations_) normal += (position_ - o.keyframe->center()).normalized();
  const KeyFrame& ref = *reference_;
  const int i = index_in(&ref);
  if (i < 0) return;
  const double dist = (position_ - ref.center()).norm();
  const ScalePyramid& s = ref.calib().scale;
  const int level = ref.f().keys_un[i].octave;
  // ORB-SLAM: the point could be seen down to level 0 and up to the top level.
  max_distance_ = dist * s.scale[level];
  min_distance_ = max_distance_ / s.scale[s.n_levels - 1];
  normal_ = normal / static_cast<double>(observations_.size());
}

void MapPoint::set_normal_and_depth(const Eigen::Vector3d& normal, double min_d, double max_d) {
  normal_ = normal;
  min_distance_ = min_d;
  max_distance_ = max_d;
}

}  // namespace dynaorb::map
