#pragma once
// A frame's or keyframe's descriptors in a vocabulary (ORB-SLAM Sec. III-D):
// the bag of words (place recognition, relocalisation) and the direct index
// (node -> keypoints, so that matching compares only keypoints under the same
// vocabulary node). Computed once from the immutable Features and shared
// read-only, like them.
#include <memory>
#include <utility>

#include "dynaorb/map/features.h"
#include "dynaorb/vocab/bow_vector.h"

namespace dynaorb::vocab {
class Vocabulary;
}

namespace dynaorb::map {

struct BagOfWords {
  // Direct-index level: nodes this many levels above the words (DBoW2 /
  // ORB-SLAM2 use 4; with a 6-level tree, nodes at depth 2).
  static constexpr int kLevelsUp = 4;

  BagOfWords(vocab::BowVector w, vocab::FeatureVector n)
      : words(std::move(w)), words_l1(words.l1_norm()), nodes(std::move(n)) {}

  const vocab::BowVector words;
  const double words_l1;  // words.l1_norm(), for vocab::score_l1
  const vocab::FeatureVector nodes;

  static std::shared_ptr<const BagOfWords> compute(const vocab::Vocabulary& vocabulary,
                                                   const Features& features,
                                                   int levels_up = kLevelsUp);
};

}  // namespace dynaorb::map
