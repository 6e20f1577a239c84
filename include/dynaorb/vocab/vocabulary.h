#pragma once
// A hierarchical bag-of-binary-words vocabulary for 256-bit ORB descriptors,
// after DBoW2 (Galvez-Lopez & Tardos, "Bags of Binary Words for Fast Place
// Recognition in Image Sequences", T-RO 2012): a tree of branching k and
// depth L built by hierarchical k-means++ under the Hamming distance, whose
// leaves are the words; TF-IDF weighting and the L1 score. It reads ORB-SLAM2's
// ORBvoc.txt (DBoW2's text format) and has a binary form that loads in a
// fraction of the time.
//
// Storage is flat and indexed by NodeId (root = 0): parent, children as a CSR
// list, descriptors as one contiguous byte array, the word of each leaf and
// the node and IDF weight of each word.
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/vocab/bow_vector.h"

namespace dynaorb::vocab {

class Vocabulary {
 public:
  // DBoW2's numbering in file headers; only these two are supported.
  enum class Weighting : std::uint32_t { kTfIdf = 0 };
  enum class Scoring : std::uint32_t { kL1 = 0 };

  static constexpr int kDescriptorBytes = 32;
  static constexpr NodeId kRoot = 0;
  static constexpr int kMaxKmeansIterations = 20;  // per node; stops earlier when stable

  Vocabulary() = default;  // empty(): transform() throws std::logic_error

  // Hierarchical k-means++ over the descriptors (N x 32 CV_8U per image;
  // images may be empty). A node with <= k distinct descriptors gets one child
  // per descriptor; nodes at depth L are leaves. Cluster centres are bitwise
  // majority votes. IDF of a word = log(N_images / N_images containing it);
  // 0 for a word seen in no image. Deterministic for a given seed.
  // Throws std::invalid_argument for k < 2, L < 1, bad matrices or no descriptors.
  static Vocabulary train(const std::vector<cv::Mat>& descriptors_per_image, int k, int L,
                          unsigned seed = 0);

  // ORB-SLAM2's ORBvoc.txt: "k L scoring weighting", then per node (ids
  // 1, 2, ... in file order) "parent is_leaf d0 .. d31 weight". Words are the
  // leaves in file order. Throws dynaorb::InputError (a std::runtime_error)
  // naming the file and line.
  static Vocabulary load_orbvoc_text(const std::string& path);
  void save_orbvoc_text(const std::string& path) const;  // weights written exactly

  // Binary form, little-endian: "DYNVOCAB", u32 version (1), k, L, scoring,
  // weighting, node count n (root included), then u32 parent[n] (root:
  // 0xFFFFFFFF), u8 is_leaf[n], u8 descriptor[n][32], f64 weight[n].
  static Vocabulary load(const std::string& path);
  void save(const std::string& path) const;
  // Binary when the file starts with the magic, else ORBvoc text.
  static Vocabulary load_any(const std::string& path);

  // descriptors: N x 32 CV_8U (or empty). bow: TF-IDF weights (idf * n_w / N),
  // L1-normalised; words of weight 0 are left out. fv: for every feature, the
  // node on its path at depth max(0, L - levels_up) (DBoW2 / ORB-SLAM2 use
  // levels_up = 4), or its leaf where the leaf is shallower. Every feature index
  // appears in fv exactly once, in increasing order per node.
  void transform(const cv::Mat& descriptors, BowVector& bow, FeatureVector& fv,
                 int levels_up) const;
  void transform(const cv::Mat& descriptors, BowVector& bow) const;
  // The word of one 32-byte descriptor (nearest child by Hamming at each level).
  WordId transform(const std::uint8_t* descriptor) const;
  // The node transform() would file a feature of this word under.
  NodeId parent_at_level(WordId word, int levels_up) const;

  double score(const BowVector& a, const BowVector& b) const { return score_l1(a, b); }

  bool empty() const { return word_node_.empty(); }
  std::size_t size() const { return word_node_.size(); }  // number of words
  std::size_t node_count() const { return parent_.size(); }
  int branching() const { return k_; }
  int depth() const { return L_; }
  Weighting weighting() const { return Weighting::kTfIdf; }
  Scoring scoring() const { return Scoring::kL1; }
  double word_weight(WordId word) const { return word_weight_.at(word); }
  NodeId word_node(WordId word) const { return word_node_.at(word); }
  bool is_leaf(NodeId node) const { return node_word_[node] != kNoWord; }
  NodeId parent(NodeId node) const { return parent_[node]; }  // root: kNoNode
  const std::uint8_t* node_descriptor(NodeId node) const {
    return descriptors_.data() + static_cast<std::size_t>(node) * kDescriptorBytes;
  }

  static constexpr NodeId kNoNode = 0xFFFFFFFFu;
  static constexpr WordId kNoWord = 0xFFFFFFFFu;

 private:
  // Takes parent_ and descriptors_ as filled by a loader, plus the leaf flag
  // and weight of each node; checks the tree (root first, parents before
  // children, leaves childless, inner nodes with 1..k children, depth <= L)
  // and builds the other arrays. On a bad tree returns false with the node
  // and the problem, for the caller to name the file and line.
  bool finish(const std::vector<std::uint8_t>& is_leaf, const std::vector<double>& node_weight,
              NodeId& bad_node, std::string& problem);
  void compute_idf(const std::vector<cv::Mat>& descriptors_per_image);
  NodeId descend(const std::uint8_t* descriptor, int fv_depth, NodeId* fv_node) const;

  int k_ = 0, L_ = 0;
  std::vector<NodeId> parent_;             // per node
  std::vector<std::uint8_t> descriptors_;  // per node, 32 bytes each
  std::vector<std::uint32_t> child_begin_; // per node + 1, into children_
  std::vector<NodeId> children_;
  std::vector<WordId> node_word_;          // per node; kNoWord for inner nodes
  std::vector<NodeId> word_node_;          // per word
  std::vector<double> word_weight_;        // per word (IDF)
};

}  // namespace dynaorb::vocab
