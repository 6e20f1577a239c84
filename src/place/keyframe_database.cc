#include "dynaorb/place/keyframe_database.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace dynaorb::place {

using map::KeyFrame;

KeyFrameDatabase::KeyFrameDatabase(map::Map& map, std::shared_ptr<const vocab::Vocabulary> vocabulary,
                                   const KeyFrameDatabaseOptions& options)
    : map_(map), vocabulary_(std::move(vocabulary)), o_(options) {
  if (!vocabulary_ || vocabulary_->empty())
    throw std::invalid_argument("KeyFrameDatabase: the vocabulary is missing or empty");
  index_.resize(vocabulary_->size());
  std::lock_guard<std::mutex> lk(map_.mutex());
  map_.set_observer(this);
}

KeyFrameDatabase::~KeyFrameDatabase() {
  std::lock_guard<std::mutex> lk(map_.mutex());
  map_.set_observer(nullptr);
}

void KeyFrameDatabase::add(KeyFrame& kf) {
  if (!kf.bow())
    throw std::invalid_argument("KeyFrameDatabase::add: keyframe " + std::to_string(kf.id) +
                                " has no bag of words");
  std::lock_guard<std::mutex> lk(mutex_);
  if (!indexed_.insert(&kf).second) return;
  for (const auto& [word, weight] : kf.bow()->words)
    if (word < index_.size()) index_[word].push_back(&kf);
}

void KeyFrameDatabase::erase(const KeyFrame& kf) {
  std::lock_guard<std::mutex> lk(mutex_);
  if (indexed_.erase(&kf) == 0) return;
  for (const auto& [word, weight] : kf.bow()->words) {
    if (word >= index_.size()) continue;
    auto& list = index_[word];
    list.erase(std::remove(list.begin(), list.end(), &kf), list.end());
  }
}

void KeyFrameDatabase::clear() {
  std::lock_guard<std::mutex> lk(mutex_);
  for (auto& list : index_) list.clear();
  indexed_.clear();
}

std::size_t KeyFrameDatabase::size() const {
  std::lock_guard<std::mutex> lk(mutex_);
  return indexed_.size();
}

std::vector<PlaceCandidate> KeyFrameDatabase::relocalization_candidates(const vocab::BowVector& bow) const {
  return candidates(bow, bow.l1_norm(), nullptr, 0.0);
}

std::vector<PlaceCandidate> KeyFrameDatabase::loop_candidates(const KeyFrame& query, double min_score) const {
  if (!query.bow())
    throw std::invalid_argument("KeyFrameDatabase::loop_candidates: keyframe " + std::to_string(query.id) +
                                " has no bag of words");
  std::unordered_set<const KeyFrame*> connected;
  for (const KeyFrame* n : query.covisibles()) connected.insert(n);
  connected.insert(&query);
  return candidates(query.bow()->words, query.bow()->words_l1, &connected, min_score);
}

std::vector<PlaceCandidate> KeyFrameDatabase::candidates(const vocab::BowVector& bow, const double bow_l1,
                                                         const std::unordered_set<const KeyFrame*>* excluded,
                                                         double min_score) const {
  // Keyframes sharing words with the query (the excluded ones aside), and how many.
  std::unordered_map<KeyFrame*, int> common;
  {
    std::lock_guard<std::mutex> lk(mutex_);
    for (const auto& [word, weight] : bow)
      if (word < index_.size())
        for (KeyFrame* kf : index_[word])
          if (!excluded || !excluded->count(kf)) ++common[kf];
  }
  if (common.empty()) return {};
  int max_common = 0;
  for (const auto& [kf, n] : common) max_common = std::max(max_common, n);
  const double min_common = o_.min_common_words_ratio * max_common;

  // Those sharing enough words, scored (bags of words are immutable once set,
  // their norms computed with them).
  std::unordered_map<KeyFrame*, double> score;
  for (const auto& [kf, n] : common)
    if (n > min_common) score[kf] = vocab::score_l1(bow, bow_l1, kf->bow()->words, kf->bow()->words_l1);

  // Each keyframe scoring at least min_score, with its best covisibles that
  // were scored too: the group's score accumulates, its best keyframe stands
  // for it. Visited in id order, so ties resolve the same way every run.
  std::vector<std::pair<KeyFrame*, double>> scored(score.begin(), score.end());
  std::sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) { return a.first->id < b.first->id; });
  std::unordered_map<KeyFrame*, PlaceCandidate> best_of_group;
  double best_group = 0;
  for (const auto& [kf, s] : scored) {
    if (s < min_score) continue;
    PlaceCandidate c{kf, s, s};
    for (KeyFrame* n : kf->covisibles(o_.group_covisibles)) {
      const auto it = score.find(n);
      if (it == score.end()) continue;
      c.group_score += it->second;
      if (it->second > c.score) {
        c.keyframe = n;
        c.score = it->second;
      }
    }
    best_group = std::max(best_group, c.group_score);
    PlaceCandidate& kept = best_of_group[c.keyframe];
    if (!kept.keyframe || c.group_score > kept.group_score) kept = c;
  }
  const double min_group = o_.min_group_score_ratio * best_group;
  std::vector<PlaceCandidate> out;
  for (const auto& [kf, c] : best_of_group)
    if (c.group_score > min_group) out.push_back(c);
  std::sort(out.begin(), out.end(), [](const PlaceCandidate& a, const PlaceCandidate& b) {
    return a.group_score != b.group_score ? a.group_score > b.group_score : a.keyframe->id < b.keyframe->id;
  });
  return out;
}

}  // namespace dynaorb::place
