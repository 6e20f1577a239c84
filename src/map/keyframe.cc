#include "dynaorb/map/keyframe.h"

#include <algorithm>

#include "dynaorb/map/map_point.h"

namespace dynaorb::map {

KeyFrame::KeyFrame(long id_, long frame_id_, double stamp_, std::shared_ptr<const Features> features_,
                   const Eigen::Isometry3d& T_cw)
    : id(id_), frame_id(frame_id_), stamp(stamp_), features(std::move(features_)), T_cw_(T_cw),
      points_(features->size()) {}

int KeyFrame::tracked_points(int min_obs) const {
  int n = 0;
  for (const auto& p : points_)
    if (p && !p->erased() && (min_obs <= 0 || p->observation_count() >= min_obs)) ++n;
  return n;
}

double KeyFrame::median_depth(double quantile) const {
  std::vector<double> z;
  z.reserve(points_.size());
  for (const auto& p : points_)
    if (p && !p->erased()) z.push_back((T_cw_ * p->position()).z());
  if (z.empty()) return 0.0;
  const size_t k = std::min(z.size() - 1, static_cast<size_t>(quantile * (z.size() - 1)));
  std::nth_element(z.begin(), z.begin() + k, z.end());
  return z[k];
}

Eigen::Vector3d KeyFrame::unproject(int i) const {
  const cv::KeyPoint& k = features->keys_un[i];
  return T_wc() * calib().unproject(k.pt.x, k.pt.y, features->depth[i]);
}

Eigen::Isometry3d KeyFrame::current_T_cw() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const KeyFrame* kf = this;
  while (kf->erased_ && kf->erased_parent_) {
    T = T * kf->T_c_parent_;
    kf = kf->erased_parent_.get();
  }
  return T * kf->T_cw_;
}

void KeyFrame::order_connections() {
  ordered_.clear();
  for (const auto& [kf, w] : weights_) ordered_.emplace_back(w, kf);
  // Heaviest first; ties by id so that runs are reproducible.
  std::sort(ordered_.begin(), ordered_.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second->id < b.second->id;
  });
}

void KeyFrame::update_connections(int min_weight) {
  std::map<KeyFrame*, int> counter;
  for (const auto& p : points_) {
    if (!p || p->erased()) continue;
    for (const MapPoint::Observation& o : p->observations())
      if (o.keyframe != this) ++counter[o.keyframe];
  }
  if (counter.empty()) return;
  // ORB-SLAM: edges with >= min_weight shared points; if none, the strongest one.
  KeyFrame* best = nullptr;
  int best_w = 0;
  std::map<KeyFrame*, int> kept;
  for (const auto& [kf, w] : counter) {
    if (w > best_w || (w == best_w && best && kf->id < best->id)) {
      best_w = w;
      best = kf;
    }
    if (w >= min_weight) kept[kf] = w;
  }
  if (kept.empty()) kept[best] = best_w;
  for (const auto& [kf, w] : kept) {
    kf->weights_[this] = w;
    kf->order_connections();
  }
  weights_ = kept;
  order_connections();
  if (first_connection_ && id != 0) {
    first_connection_ = false;
    set_parent(ordered_.front().second);
  }
}

void KeyFrame::erase_connection(KeyFrame* kf) {
  if (weights_.erase(kf) > 0) order_connections();
}

std::vector<KeyFrame*> KeyFrame::covisibles(int n) const {
  std::vector<KeyFrame*> out;
  for (const auto& [w, kf] : ordered_) {
    if (n >= 0 && static_cast<int>(out.size()) >= n) break;
    out.push_back(kf);
  }
  return out;
}

std::vector<KeyFrame*> KeyFrame::covisibles_min_weight(int min_w) const {
  std::vector<KeyFrame*> out;
  for (const auto& [w, kf] : ordered_) {
    if (w < min_w) break;
    out.push_back(kf);
  }
  return out;
}

int KeyFrame::weight(KeyFrame* kf) const {
  auto it = weights_.find(kf);
  return it == weights_.end() ? 0 : it->second;
}

void KeyFrame::set_parent(KeyFrame* p) {
  if (parent_) parent_->children_.erase(this);
  parent_ = p;
  if (p) p->children_.insert(this);
}

}  // namespace dynaorb::map
