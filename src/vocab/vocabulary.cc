// The vocabulary tree: training (hierarchical k-means, then IDF weights from
// the training images), the descent of a descriptor to its word, TF-IDF bag
// of words with the direct index, and the L1 score (DBoW2, Galvez-Lopez &
// Tardos, T-RO 2012, Sec. IV-V). File formats live in vocabulary_io.cc.
#include "dynaorb/vocab/vocabulary.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "dynaorb/match/hamming.h"
#include "kmeans.h"

namespace dynaorb::vocab {

using std::to_string;

// ---------------------------------------------------------------- BowVector

double BowVector::l1_norm() const {
  double s = 0.0;
  for (const auto& [id, w] : *this) s += std::fabs(w);
  return s;
}

void BowVector::normalize_l1() {
  const double n = l1_norm();
  if (n <= 0.0) return;
  for (auto& [id, w] : *this) w /= n;
}

double score_l1(const BowVector& a, const BowVector& b) { return score_l1(a, a.l1_norm(), b, b.l1_norm()); }

double score_l1(const BowVector& a, const double na, const BowVector& b, const double nb) {
  if (na <= 0.0 || nb <= 0.0) return 0.0;
  // 1 - 0.5 * sum_i |a_i - b_i| over normalised vectors equals
  // 0.5 * sum over shared words of |a_i| + |b_i| - |a_i - b_i|.
  double s = 0.0;
  for_each_shared_key(a, b, [&](double wa, double wb) {
    const double x = wa / na, y = wb / nb;
    s += std::fabs(x) + std::fabs(y) - std::fabs(x - y);
  });
  return std::clamp(0.5 * s, 0.0, 1.0);
}

// ---------------------------------------------------------------- Vocabulary

namespace {

void check_descriptors(const cv::Mat& d, const char* what) {
  if (d.empty()) return;
  if (d.type() != CV_8UC1 || d.cols != Vocabulary::kDescriptorBytes)
    throw std::invalid_argument(std::string(what) + ": descriptors must be N x 32 CV_8U, got " +
                                std::to_string(d.rows) + " x " + std::to_string(d.cols) +
                                " of type " + std::to_string(d.type()));
}

}  // namespace

Vocabulary Vocabulary::train(const std::vector<cv::Mat>& descriptors_per_image, int k, int L,
                             unsigned seed) {
  if (k < 2) throw std::invalid_argument("Vocabulary::train: branching k must be >= 2");
  if (L < 1) throw std::invalid_argument("Vocabulary::train: depth L must be >= 1");
  std::size_t total = 0;
  for (const cv::Mat& d : descriptors_per_image) {
    check_descriptors(d, "Vocabulary::train");
    total += static_cast<std::size_t>(d.rows);
  }
  if (total == 0) throw std::invalid_argument("Vocabulary::train: no descriptors");
  if (total >= 0xFFFFFFFFu) throw std::invalid_argument("Vocabulary::train: too many descriptors");

  std::vector<std::uint8_t> all;
  all.reserve(total * kDescriptorBytes);
  for (const cv::Mat& d : descriptors_per_image)
    for (int r = 0; r < d.rows; ++r)
      all.insert(all.end(), d.ptr<std::uint8_t>(r), d.ptr<std::uint8_t>(r) + kDescriptorBytes);

  detail::KmeansTree tree = detail::build_kmeans_tree(all, k, L, seed, kMaxKmeansIterations);
  Vocabulary v;
  v.k_ = k;
  v.L_ = L;
  v.parent_ = std::move(tree.parent);
  v.descriptors_ = std::move(tree.descriptors);
  NodeId bad = 0;
  std::string problem;
  if (!v.finish(tree.is_leaf, std::vector<double>(v.parent_.size(), 0.0), bad, problem))
    throw std::logic_error("Vocabulary::train built a bad tree at node " + std::to_string(bad) +
                           ": " + problem);
  v.compute_idf(descriptors_per_image);
  return v;
}

// As in DBoW2, the IDF comes from the final tree: each training descriptor is
// sent down it, and a word's n_i counts the images with at least one hit.
void Vocabulary::compute_idf(const std::vector<cv::Mat>& descriptors_per_image) {
  const double n_images = static_cast<double>(descriptors_per_image.size());
  std::vector<std::uint32_t> n_i(size(), 0), last(size(), 0xFFFFFFFFu);
  for (std::size_t img = 0; img < descriptors_per_image.size(); ++img) {
    const cv::Mat& d = descriptors_per_image[img];
    for (int r = 0; r < d.rows; ++r) {
      const WordId w = transform(d.ptr<std::uint8_t>(r));
      if (last[w] != img) last[w] = static_cast<std::uint32_t>(img), ++n_i[w];
    }
  }
  for (std::size_t w = 0; w < size(); ++w)
    word_weight_[w] = n_i[w] > 0 ? std::log(n_images / n_i[w]) : 0.0;
}

bool Vocabulary::finish(const std::vector<std::uint8_t>& is_leaf,
                        const std::vector<double>& node_weight, NodeId& bad_node,
                        std::string& problem) {
  const std::size_t n = parent_.size();
  auto fail = [&](std::size_t node, std::string what) {
    bad_node = static_cast<NodeId>(node);
    problem = std::move(what);
    return false;
  };
  if (n < 2) return fail(0, "the vocabulary has no nodes besides the root");
  if (parent_[0] != kNoNode) return fail(0, "node 0 must be the root");
  if (is_leaf[0]) return fail(0, "the root cannot be a leaf");
  std::vector<std::uint32_t> n_children(n, 0), node_depth(n, 0);
  for (std::size_t i = 1; i < n; ++i) {
    const NodeId p = parent_[i];
    if (p >= i)
      return fail(i, "parent id " + to_string(p) + " out of range (must be < " + to_string(i) +
                         ")");
    if (is_leaf[p]) return fail(i, "parent " + to_string(p) + " is a leaf");
    if (++n_children[p] > static_cast<std::uint32_t>(k_))
      return fail(i, "parent " + to_string(p) + " has more than k = " + to_string(k_) +
                         " children");
    node_depth[i] = node_depth[p] + 1;
    if (node_depth[i] > static_cast<std::uint32_t>(L_))
      return fail(i, "node at depth " + to_string(node_depth[i]) + " > L = " + to_string(L_));
    if (!std::isfinite(node_weight[i]) || node_weight[i] < 0.0)
      return fail(i, "word weight must be finite and >= 0");
  }
  for (std::size_t i = 0; i < n; ++i)
    if (!is_leaf[i] && n_children[i] == 0)
      return fail(i, "inner node (not a leaf) without children");

  child_begin_.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) child_begin_[i + 1] = child_begin_[i] + n_children[i];
  children_.assign(n - 1, 0);
  std::vector<std::uint32_t> fill(child_begin_.begin(), child_begin_.end() - 1);
  for (std::size_t i = 1; i < n; ++i) children_[fill[parent_[i]]++] = static_cast<NodeId>(i);

  node_word_.assign(n, kNoWord);
  word_node_.clear();
  word_weight_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (!is_leaf[i]) continue;
    node_word_[i] = static_cast<WordId>(word_node_.size());
    word_node_.push_back(static_cast<NodeId>(i));
    word_weight_.push_back(node_weight[i]);
  }
  return true;
}

NodeId Vocabulary::descend(const std::uint8_t* d, int fv_depth, NodeId* fv_node) const {
  NodeId node = kRoot;
  int depth = 0;
  if (fv_node) *fv_node = kRoot;
  while (node_word_[node] == kNoWord) {
    const std::uint32_t cb = child_begin_[node], ce = child_begin_[node + 1];
    NodeId best = children_[cb];
    int best_d = match::hamming(d, node_descriptor(best));
    for (std::uint32_t c = cb + 1; c < ce; ++c) {
      const NodeId child = children_[c];
      const int h = match::hamming(d, node_descriptor(child));
      if (h < best_d) best_d = h, best = child;
    }
    node = best;
    if (++depth <= fv_depth && fv_node) *fv_node = node;
  }
  return node;
}

WordId Vocabulary::transform(const std::uint8_t* descriptor) const {
  if (empty()) throw std::logic_error("Vocabulary::transform: the vocabulary is empty");
  return node_word_[descend(descriptor, 0, nullptr)];
}

void Vocabulary::transform(const cv::Mat& descriptors, BowVector& bow, FeatureVector& fv,
                           int levels_up) const {
  if (empty()) throw std::logic_error("Vocabulary::transform: the vocabulary is empty");
  if (levels_up < 0) throw std::invalid_argument("Vocabulary::transform: levels_up must be >= 0");
  check_descriptors(descriptors, "Vocabulary::transform");
  bow.clear();
  fv.clear();
  const int n = descriptors.rows;
  if (n == 0) return;
  const int fv_depth = std::max(0, L_ - levels_up);
  const double tf = 1.0 / n;
  for (int i = 0; i < n; ++i) {
    NodeId fv_node = kRoot;
    const WordId w = node_word_[descend(descriptors.ptr<std::uint8_t>(i), fv_depth, &fv_node)];
    fv.add_feature(fv_node, static_cast<unsigned>(i));
    if (word_weight_[w] > 0.0) bow.add_weight(w, word_weight_[w] * tf);
  }
  bow.normalize_l1();
}

void Vocabulary::transform(const cv::Mat& descriptors, BowVector& bow) const {
  if (empty()) throw std::logic_error("Vocabulary::transform: the vocabulary is empty");
  check_descriptors(descriptors, "Vocabulary::transform");
  bow.clear();
  const int n = descriptors.rows;
  if (n == 0) return;
  const double tf = 1.0 / n;
  for (int i = 0; i < n; ++i) {
    const WordId w = transform(descriptors.ptr<std::uint8_t>(i));
    if (word_weight_[w] > 0.0) bow.add_weight(w, word_weight_[w] * tf);
  }
  bow.normalize_l1();
}

NodeId Vocabulary::parent_at_level(WordId word, int levels_up) const {
  if (levels_up < 0)
    throw std::invalid_argument("Vocabulary::parent_at_level: levels_up must be >= 0");
  NodeId node = word_node_.at(word);
  int depth = 0;
  for (NodeId p = node; p != kRoot; p = parent_[p]) ++depth;
  const int target = std::max(0, L_ - levels_up);
  for (; depth > target; --depth) node = parent_[node];
  return node;
}

}  // namespace dynaorb::vocab
