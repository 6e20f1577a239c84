#pragma once
// The keyframe database (ORB-SLAM Sec. III-D): an inverse index from each
// vocabulary word to the keyframes whose bag of words contains it, queried
// for relocalisation candidates (Sec. V-C, ORB-SLAM2's
// DetectRelocalizationCandidates): the keyframes that share enough words with
// the query, scored, grouped with their covisible keyframes, and the best
// keyframe of every group whose accumulated score is close to the best group's.
//
// Keyframes enter when local mapping inserts them (with their bag of words)
// and leave with the map: the database observes its Map, so a culled keyframe
// is erased and a cleared map clears the index.
//
// Threads: the index has its own mutex. The query also reads the candidates'
// covisibility, which the map's mutex guards: call it with that mutex held
// (lock order: the map's, then the database's; add() likewise).
#include <cstddef>
#include <memory>
#include <mutex>
#include <unordered_set>
#include <vector>

#include "dynaorb/map/map.h"
#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb::place {

struct KeyFrameDatabaseOptions {
  // Candidates share more than this share of the words that the keyframe
  // sharing the most with the query shares (ORB-SLAM: 0.8).
  double min_common_words_ratio = 0.8;
  // A candidate's score accumulates over its best covisible keyframes (ORB-SLAM: 10).
  int group_covisibles = 10;
  // Groups kept with an accumulated score above this share of the best group's (ORB-SLAM: 0.75).
  double min_group_score_ratio = 0.75;
};

struct PlaceCandidate {
  map::KeyFrame* keyframe = nullptr;  // the best-scoring keyframe of its group
  double score = 0;                   // its own L1 score against the query
  double group_score = 0;             // accumulated over its group
};

class KeyFrameDatabase : public map::MapObserver {
 public:
  // Registers itself as the map's observer (taking the map's mutex); the
  // destructor detaches it. The vocabulary must be the one bags of words are computed with.
  KeyFrameDatabase(map::Map& map, std::shared_ptr<const vocab::Vocabulary> vocabulary,
                   const KeyFrameDatabaseOptions& options = {});
  ~KeyFrameDatabase() override;
  KeyFrameDatabase(const KeyFrameDatabase&) = delete;
  KeyFrameDatabase& operator=(const KeyFrameDatabase&) = delete;

  // Indexes kf under the words of kf.bow() (which must be set: std::invalid_argument
  // otherwise); a keyframe already indexed is left as it is.
  void add(map::KeyFrame& kf);
  void erase(const map::KeyFrame& kf);
  void clear();
  std::size_t size() const;  // keyframes indexed

  // Relocalisation candidates for a frame's bag of words, best group first
  // (ties by keyframe id). Call with the map's mutex held.
  std::vector<PlaceCandidate> relocalization_candidates(const vocab::BowVector& bow) const;

  // Loop candidates for keyframe kf (ORB-SLAM2's DetectLoopCandidates): the
  // keyframes sharing words with kf that are neither kf nor covisible with it,
  // sharing more than min_common_words_ratio of the most words shared, with an
  // L1 score >= min_score; grouped with their best covisibles like the
  // relocalisation candidates; the best keyframe of each group whose
  // accumulated score exceeds min_group_score_ratio of the best group's, best
  // group first. kf's bag of words must be set. Call with the map's mutex held.
  std::vector<PlaceCandidate> loop_candidates(const map::KeyFrame& kf, double min_score) const;

  const vocab::Vocabulary& vocabulary() const { return *vocabulary_; }

  // map::MapObserver
  void keyframe_erased(const map::KeyFrame& kf) override { erase(kf); }
  void map_cleared() override { clear(); }

 private:
  // ORB-SLAM's scoring and covisibility grouping, shared by both queries:
  // keyframes in `excluded` are skipped, groups are seeded by keyframes
  // scoring at least min_score. bow_l1: bow.l1_norm().
  std::vector<PlaceCandidate> candidates(const vocab::BowVector& bow, double bow_l1,
                                         const std::unordered_set<const map::KeyFrame*>* excluded,
                                         double min_score) const;
  map::Map& map_;
  const std::shared_ptr<const vocab::Vocabulary> vocabulary_;
  const KeyFrameDatabaseOptions o_;
  mutable std::mutex mutex_;
  std::vector<std::vector<map::KeyFrame*>> index_;  // per word; non-owning, kept in step with the map
  std::unordered_set<const map::KeyFrame*> indexed_;
};

}  // namespace dynaorb::place
