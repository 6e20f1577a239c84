#include "dynaorb/map/map.h"

#include <limits>

namespace dynaorb::map {

void Map::add_keyframe(const std::shared_ptr<KeyFrame>& kf) { keyframes_[kf->id] = kf; }
void Map::add_point(const std::shared_ptr<MapPoint>& p) { points_[p->id] = p; }

void Map::add_observation(KeyFrame& kf, int index, const std::shared_ptr<MapPoint>& p) {
  kf.set_point(index, p);
  p->add_observation(&kf, index);
}

void Map::erase_observation(KeyFrame& kf, int index) {
  std::shared_ptr<MapPoint> p = kf.point(index);
  kf.clear_point(index);
  if (!p) return;
  p->erase_observation(&kf);
  if (p->observation_count() <= 2) erase_point(p);
}

void Map::erase_point(const std::shared_ptr<MapPoint>& p) {
  if (p->erased_) return;
  p->erased_ = true;
  for (const MapPoint::Observation& o : p->observations_)
    if (o.keyframe->point(o.index) == p) o.keyframe->clear_point(o.index);
  p->observations_.clear();
  p->n_obs_ = 0;
  points_.erase(p->id);
}

void Map::replace_point(const std::shared_ptr<MapPoint>& old_point, const std::shared_ptr<MapPoint>& keep) {
  if (old_point == keep || old_point->erased_ || keep->erased_) return;
  const std::vector<MapPoint::Observation> obs = old_point->observations_;
  old_point->observations_.clear();
  old_point->n_obs_ = 0;
  old_point->erased_ = true;
  old_point->replaced_by_ = keep;
  for (const MapPoint::Observation& o : obs) {
    if (keep->index_in(o.keyframe) < 0) {
      o.keyframe->set_point(o.index, keep);
      keep->add_observation(o.keyframe, o.index);
    } else {
      o.keyframe->clear_point(o.index);  // kf already sees `keep` at another keypoint
    }
  }
  keep->increase_found(old_point->found());
  keep->increase_visible(old_point->visible());
  keep->compute_distinctive_descriptor();
  points_.erase(old_point->id);
}

void Map::erase_keyframe(const std::shared_ptr<KeyFrame>& kf) {
  if (kf->erased_ || kf->id == 0) return;  // the first keyframe anchors the map
  for (const auto& [other, w] : kf->weights_) other->erase_connection(kf.get());
  for (int i = 0; i < static_cast<int>(kf->points_.size()); ++i)
    if (kf->points_[i]) erase_observation(*kf, i);

  // Re-link the children: each, in turn, to the candidate parent (the
  // grandparent or an already re-linked sibling) it is most covisible with.
  std::set<KeyFrame*> parents{kf->parent_};
  std::set<KeyFrame*> children = kf->children_;
  while (!children.empty()) {
    KeyFrame* best_child = nullptr;
    KeyFrame* best_parent = nullptr;
    int best_w = -1;
    for (KeyFrame* child : children) {
      for (KeyFrame* cand : child->covisibles()) {
        if (!parents.count(cand)) continue;
        const int w = child->weight(cand);
        if (w > best_w) {
          best_w = w;
          best_child = child;
          best_parent = cand;
        }
      }
    }
    if (!best_child) break;
    best_child->set_parent(best_parent);
    parents.insert(best_child);
    children.erase(best_child);
  }
  for (KeyFrame* child : children) child->set_parent(kf->parent_);
  if (kf->parent_) {
    kf->erased_parent_ = keyframe(kf->parent_->id);
    kf->T_c_parent_ = kf->T_cw_ * kf->parent_->T_wc();
    kf->parent_->children_.erase(kf.get());
  }
  kf->children_.clear();
  kf->weights_.clear();
  kf->ordered_.clear();
  kf->erased_ = true;
  keyframes_.erase(kf->id);
  if (observer_) observer_->keyframe_erased(*kf);
}

std::shared_ptr<KeyFrame> Map::keyframe(long id) const {
  auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : it->second;
}

std::shared_ptr<MapPoint> Map::point(long id) const {
  auto it = points_.find(id);
  return it == points_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<KeyFrame>> Map::keyframes() const {
  std::vector<std::shared_ptr<KeyFrame>> out;
  out.reserve(keyframes_.size());
  for (const auto& [id, kf] : keyframes_) out.push_back(kf);
  return out;
}

std::vector<std::shared_ptr<MapPoint>> Map::points() const {
  std::vector<std::shared_ptr<MapPoint>> out;
  out.reserve(points_.size());
  for (const auto& [id, p] : points_) out.push_back(p);
  return out;
}

void Map::clear() {
  for (auto& [id, p] : points_) {
    p->erased_ = true;
    p->observations_.clear();
  }
  for (auto& [id, kf] : keyframes_) {
    kf->erased_ = true;
    kf->points_.clear();
    kf->weights_.clear();
    kf->ordered_.clear();
    kf->children_.clear();
    kf->parent_ = nullptr;
  }
  points_.clear();
  keyframes_.clear();
  if (observer_) observer_->map_cleared();
  next_keyframe_id_ = 0;
  next_point_id_ = 0;
}

}  // namespace dynaorb::map
