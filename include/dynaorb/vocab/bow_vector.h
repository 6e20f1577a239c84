#pragma once
// Bag-of-words vectors as DBoW2 defines them (Galvez-Lopez & Tardos, T-RO
// 2012): a sparse, sorted word -> weight map (the image's "inverse index"
// entry) and a node -> feature-indices map (the "direct index", which lets
// matching compare only features that fall under the same vocabulary node).
#include <cstdint>
#include <map>
#include <vector>

namespace dynaorb::vocab {

using WordId = std::uint32_t;
using NodeId = std::uint32_t;

class BowVector : public std::map<WordId, double> {
 public:
  using std::map<WordId, double>::map;
  // Adds w to the weight of word id (inserting it at 0 first).
  void add_weight(WordId id, double w) { (*this)[id] += w; }
  // Sum of |weight|.
  double l1_norm() const;
  // Scales the weights to sum of |weight| = 1; an all-zero vector is left as it is.
  void normalize_l1();
};

class FeatureVector : public std::map<NodeId, std::vector<unsigned>> {
 public:
  using std::map<NodeId, std::vector<unsigned>>::map;
  void add_feature(NodeId node, unsigned feature) { (*this)[node].push_back(feature); }
};

// Walks two sorted maps (BowVector or FeatureVector) in key order and calls
// fn(value in a, value in b) for each key both hold, skipping ahead with
// lower_bound (what the L1 score and direct-index matching both need).
template <typename Map, typename Fn>
void for_each_shared_key(const Map& a, const Map& b, Fn&& fn) {
  auto ia = a.begin();
  auto ib = b.begin();
  while (ia != a.end() && ib != b.end()) {
    if (ia->first < ib->first) {
      ia = a.lower_bound(ib->first);
    } else if (ib->first < ia->first) {
      ib = b.lower_bound(ia->first);
    } else {
      fn(ia->second, ib->second);
      ++ia;
      ++ib;
    }
  }
}

// DBoW2's L1 score, 1 - 0.5 * | a/|a| - b/|b| |_1, in [0, 1]: 1 for vectors
// with the same direction, 0 when no word is shared (or either is empty).
double score_l1(const BowVector& a, const BowVector& b);
// The same score with both vectors' l1_norm() given: the norms of stored bags
// of words are computed once (map::BagOfWords::words_l1) instead of walking
// both maps again for every pair scored; the result is bit for bit the same.
double score_l1(const BowVector& a, double a_l1, const BowVector& b, double b_l1);

}  // namespace dynaorb::vocab
