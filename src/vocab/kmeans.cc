// Hierarchical k-means++ for binary descriptors (DBoW2, Galvez-Lopez & Tardos,
// T-RO 2012, Sec. IV; k-means++ seeding after Arthur & Vassilvitskii 2007).
// All descriptors stay in one array; a node owns a range of a permutation of
// their indices, and splitting a node partitions its range in place, so the
// children's ranges are sub-ranges and the scratch buffers are shared by the
// whole recursion.
#include "kmeans.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <random>

#include "dynaorb/match/hamming.h"

namespace dynaorb::vocab::detail {

namespace {

constexpr int kBytes = 32;
constexpr int kBits = 256;
constexpr std::uint32_t kNone = 0xFFFFFFFFu;

// Byte b -> 8 byte lanes holding its bits (lane t = bit t), so that adding
// these words counts the bits of up to 255 descriptors per lane at once.
std::array<std::uint64_t, 256> make_bit_lanes() {
  std::array<std::uint64_t, 256> t{};
  for (int b = 0; b < 256; ++b)
    for (int bit = 0; bit < 8; ++bit)
      if (b & (1 << bit)) t[b] |= std::uint64_t{1} << (8 * bit);
  return t;
}

class Builder {
 public:
  Builder(const std::vector<std::uint8_t>& descriptors, int k, int L, unsigned seed,
          int max_iterations, KmeansTree& out)
      : data_(descriptors.data()),
        k_(k),
        L_(L),
        max_iterations_(max_iterations),
        rng_(seed),
        out_(out),
        lanes_(make_bit_lanes()) {
    const std::size_t n = descriptors.size() / kBytes;
    idx_.resize(n);
    for (std::size_t i = 0; i < n; ++i) idx_[i] = static_cast<std::uint32_t>(i);
    tmp_.resize(n);
    assign_.resize(n);
    dist_.resize(n);
    counts_.resize(static_cast<std::size_t>(k) * kBits);
    acc_.resize(static_cast<std::size_t>(k) * kBytes);
    pending_.resize(k);
    sizes_.resize(k);
  }

  void run() {
    const std::uint8_t zero[kBytes] = {};
    add_node(kNone, zero);
    split(0, 0, idx_.size(), 0);
  }

 private:
  const std::uint8_t* desc(std::size_t pos) const {
    return data_ + static_cast<std::size_t>(idx_[pos]) * kBytes;
  }

  NodeId add_node(NodeId parent, const std::uint8_t* d) {
    out_.parent.push_back(parent);
    out_.descriptors.insert(out_.descriptors.end(), d, d + kBytes);
    out_.is_leaf.push_back(0);
    return static_cast<NodeId>(out_.parent.size() - 1);
  }

  std::uint64_t rand64() {
    const std::uint64_t hi = rng_();
    return (hi << 32) | rng_();
  }

  // Nearest of m centres (lowest index on ties).
  static std::uint32_t nearest(const std::uint8_t* d, const std::vector<std::uint8_t>& centres,
                               int m) {
    std::uint32_t best = 0;
    int best_d = kBits + 1;
    for (int c = 0; c < m; ++c) {
      const int h = match::hamming(d, centres.data() + static_cast<std::size_t>(c) * kBytes);
      if (h < best_d) best_d = h, best = static_cast<std::uint32_t>(c);
    }
    return best;
  }

  // One cluster per distinct descriptor of [b, e); returns their number.
  int distinct(std::size_t b, std::size_t e, std::vector<std::uint8_t>& centres) {
    int m = 0;
    for (std::size_t i = b; i < e; ++i) {
      int c = 0;
      while (c < m && std::memcmp(centres.data() + c * kBytes, desc(i), kBytes) != 0) ++c;
      if (c == m) std::memcpy(centres.data() + m++ * kBytes, desc(i), kBytes);
      assign_[i] = static_cast<std::uint32_t>(c);
    }
    return m;
  }

  // k-means++ seeding: the first centre uniformly, each next one with
  // probability proportional to D(x)^2. Stops early when every descriptor
  // coincides with a centre.
  int seed_centres(std::size_t b, std::size_t e, std::vector<std::uint8_t>& centres) {
    const std::size_t n = e - b;
    const std::size_t first = b + static_cast<std::size_t>(rand64() % n);
    std::memcpy(centres.data(), desc(first), kBytes);
    for (std::size_t i = b; i < e; ++i)
      dist_[i] = static_cast<std::uint32_t>(match::hamming(desc(i), centres.data()));
    int m = 1;
    while (m < k_) {
      std::uint64_t total = 0;
      for (std::size_t i = b; i < e; ++i) total += std::uint64_t{dist_[i]} * dist_[i];
      if (total == 0) break;
      const std::uint64_t r = rand64() % total;
      std::uint64_t cum = 0;
      std::size_t pick = e - 1;
      for (std::size_t i = b; i < e; ++i) {
        cum += std::uint64_t{dist_[i]} * dist_[i];
        if (cum > r) {
          pick = i;
          break;
        }
      }
      std::uint8_t* c = centres.data() + static_cast<std::size_t>(m) * kBytes;
      std::memcpy(c, desc(pick), kBytes);
      ++m;
      for (std::size_t i = b; i < e; ++i) {
        const auto h = static_cast<std::uint32_t>(match::hamming(desc(i), c));
        if (h < dist_[i]) dist_[i] = h;
      }
    }
    return m;
  }

  // Centre of each cluster = bitwise majority vote of its members (a bit is
  // set when at least half the members have it); empty clusters keep theirs.
  void majority(std::size_t b, std::size_t e, int m, std::vector<std::uint8_t>& centres) {
    std::fill(counts_.begin(), counts_.begin() + static_cast<std::size_t>(m) * kBits, 0u);
    std::fill(acc_.begin(), acc_.begin() + static_cast<std::size_t>(m) * kBytes, 0u);
    std::fill(pending_.begin(), pending_.begin() + m, 0u);
    std::fill(sizes_.begin(), sizes_.begin() + m, 0u);
    for (std::size_t i = b; i < e; ++i) {
      const std::uint32_t c = assign_[i];
      const std::uint8_t* d = desc(i);
      std::uint64_t* acc = acc_.data() + static_cast<std::size_t>(c) * kBytes;
      for (int j = 0; j < kBytes; ++j) acc[j] += lanes_[d[j]];
      ++sizes_[c];
      if (++pending_[c] == 255) flush(c);
    }
    for (int c = 0; c < m; ++c) {
      flush(static_cast<std::uint32_t>(c));
      if (sizes_[c] == 0) continue;
      const std::uint32_t* cnt = counts_.data() + static_cast<std::size_t>(c) * kBits;
      std::uint8_t* out = centres.data() + static_cast<std::size_t>(c) * kBytes;
      for (int j = 0; j < kBytes; ++j) {
        std::uint8_t v = 0;
        for (int t = 0; t < 8; ++t)
          if (2 * cnt[8 * j + t] >= sizes_[c]) v |= static_cast<std::uint8_t>(1u << t);
        out[j] = v;
      }
    }
  }

  void flush(std::uint32_t c) {
    std::uint64_t* acc = acc_.data() + static_cast<std::size_t>(c) * kBytes;
    std::uint32_t* cnt = counts_.data() + static_cast<std::size_t>(c) * kBits;
    for (int j = 0; j < kBytes; ++j) {
      for (int t = 0; t < 8; ++t)
        cnt[8 * j + t] += static_cast<std::uint32_t>((acc[j] >> (8 * t)) & 0xFF);
      acc[j] = 0;
    }
    pending_[c] = 0;
  }

  // Clusters [b, e) into at most k non-empty clusters; returns their number.
  int kmeans(std::size_t b, std::size_t e, std::vector<std::uint8_t>& centres) {
    int m = seed_centres(b, e, centres);
    for (std::size_t i = b; i < e; ++i) assign_[i] = kNone;
    for (int it = 0; it < max_iterations_; ++it) {
      bool changed = false;
      for (std::size_t i = b; i < e; ++i) {
        const std::uint32_t c = nearest(desc(i), centres, m);
        if (c != assign_[i]) assign_[i] = c, changed = true;
      }
      if (!changed) break;
      majority(b, e, m, centres);
    }
    // Drop empty clusters, renumbering the others in order.
    std::vector<std::uint32_t> remap(m, kNone);
    for (std::size_t i = b; i < e; ++i) remap[assign_[i]] = 0;
    int kept = 0;
    for (int c = 0; c < m; ++c) {
      if (remap[c] == kNone) continue;
      if (kept != c)
        std::memcpy(centres.data() + kept * kBytes, centres.data() + c * kBytes, kBytes);
      remap[c] = static_cast<std::uint32_t>(kept++);
    }
    for (std::size_t i = b; i < e; ++i) assign_[i] = remap[assign_[i]];
    return kept;
  }

  void split(NodeId node, std::size_t b, std::size_t e, int depth) {
    if (depth >= L_) {
      out_.is_leaf[node] = 1;
      return;
    }
    std::vector<std::uint8_t> centres(static_cast<std::size_t>(k_) * kBytes);
    const int m = (e - b <= static_cast<std::size_t>(k_)) ? distinct(b, e, centres)
                                                           : kmeans(b, e, centres);
    if (m <= 1) {
      out_.is_leaf[node] = 1;
      return;
    }
    // Stable counting sort of the range by cluster.
    std::vector<std::size_t> begin(m + 1, 0);
    for (std::size_t i = b; i < e; ++i) ++begin[assign_[i] + 1];
    for (int c = 0; c < m; ++c) begin[c + 1] += begin[c];
    std::vector<std::size_t> fill(begin.begin(), begin.end() - 1);
    for (std::size_t i = b; i < e; ++i) tmp_[b + fill[assign_[i]]++] = idx_[i];
    std::copy(tmp_.begin() + b, tmp_.begin() + e, idx_.begin() + b);

    const auto first = static_cast<NodeId>(out_.parent.size());
    for (int c = 0; c < m; ++c)
      add_node(node, centres.data() + static_cast<std::size_t>(c) * kBytes);
    for (int c = 0; c < m; ++c)
      split(first + static_cast<NodeId>(c), b + begin[c], b + begin[c + 1], depth + 1);
  }

  const std::uint8_t* data_;
  int k_, L_, max_iterations_;
  std::mt19937 rng_;
  KmeansTree& out_;
  const std::array<std::uint64_t, 256> lanes_;
  std::vector<std::uint32_t> idx_, tmp_;   // permutation of descriptors; partition scratch
  std::vector<std::uint32_t> assign_;      // per position: cluster
  std::vector<std::uint32_t> dist_;        // per position: k-means++ D(x)
  std::vector<std::uint32_t> counts_;      // per cluster: 256 bit counts
  std::vector<std::uint64_t> acc_;         // per cluster: 32 byte-lane accumulators
  std::vector<std::uint32_t> pending_, sizes_;
};

}  // namespace

KmeansTree build_kmeans_tree(const std::vector<std::uint8_t>& descriptors, int k, int L,
                             unsigned seed, int max_iterations) {
  KmeansTree out;
  Builder(descriptors, k, L, seed, max_iterations, out).run();
  return out;
}

}  // namespace dynaorb::vocab::detail
