#pragma once
// Hierarchical k-means++ over 256-bit binary descriptors (private to the
// vocabulary): Hamming distance, cluster centre = bitwise majority vote, as in
// DBoW2 (Galvez-Lopez & Tardos, T-RO 2012, Sec. IV).
#include <cstdint>
#include <vector>

#include "dynaorb/vocab/bow_vector.h"

namespace dynaorb::vocab::detail {

// Node 0 is the root (zero descriptor). The children of a node get
// consecutive ids, all larger than their parent's.
struct KmeansTree {
  std::vector<NodeId> parent;          // root: 0xFFFFFFFF
  std::vector<std::uint8_t> descriptors;  // 32 bytes per node
  std::vector<std::uint8_t> is_leaf;
};

// descriptors: n x 32 bytes, contiguous. A node at depth L, or with a single
// distinct descriptor, is a leaf; a node with <= k descriptors gets one child
// per distinct descriptor; otherwise k-means++ seeding then at most
// max_iterations of assign / majority-vote rounds (fewer when the assignment
// stops changing); empty clusters are dropped. Deterministic for a seed.
KmeansTree build_kmeans_tree(const std::vector<std::uint8_t>& descriptors, int k, int L,
                             unsigned seed, int max_iterations);

}  // namespace dynaorb::vocab::detail
