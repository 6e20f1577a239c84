// Quadtree keypoint distribution (ORB-SLAM, T-RO 2015, Sec. III-A; the node
// splitting of ORB-SLAM2's extractor). Written from the published description:
//  1. Start with round(W/H) nodes side by side so that they are roughly square.
//  2. Repeatedly split every node holding more than one keypoint into four
//     quadrants; empty quadrants are dropped.
//  3. When a full round would overshoot the target, split the most populated
//     nodes first and stop as soon as the target is reached.
//  4. Each leaf keeps its keypoint with the highest FAST response.
// The keypoints of a node are a contiguous range of an index array; splitting
// partitions that range in place, so no per-node allocation happens.
#include "quadtree.h"

#include <algorithm>
#include <cmath>

namespace dynaorb::features::detail {

namespace {

using Node = QuadtreeScratch::Node;

bool splittable(const Node& n) {
  // Distinct integer positions separate once a node is < 1 px wide; the size
  // guard only stops endless splitting on duplicated positions.
  return n.end - n.begin > 1 && (n.x1 - n.x0 > 0.5f || n.y1 - n.y0 > 0.5f);
}

// Replaces nodes[i] by its non-empty quadrants (the first one takes slot i,
// the others are appended).
void split(std::vector<Node>& nodes, size_t i, const std::vector<cv::KeyPoint>& kps,
           std::vector<int>& index) {
  const Node n = nodes[i];
  const float mx = 0.5f * (n.x0 + n.x1), my = 0.5f * (n.y0 + n.y1);
  int* first = index.data() + n.begin;
  int* last = index.data() + n.end;
  int* mid_x = std::partition(first, last, [&](int k) { return kps[k].pt.x < mx; });
  int* mid_l = std::partition(first, mid_x, [&](int k) { return kps[k].pt.y < my; });
  int* mid_r = std::partition(mid_x, last, [&](int k) { return kps[k].pt.y < my; });
  const int b = n.begin;
  auto off = [&](int* p) { return b + static_cast<int>(p - first); };
  const Node children[4] = {
      {n.x0, n.y0, mx, my, off(first), off(mid_l)},
      {n.x0, my, mx, n.y1, off(mid_l), off(mid_x)},
      {mx, n.y0, n.x1, my, off(mid_x), off(mid_r)},
      {mx, my, n.x1, n.y1, off(mid_r), off(last)},
  };
  bool replaced = false;
  for (const Node& c : children) {
    if (c.end == c.begin) continue;
    if (!replaced) {
      nodes[i] = c;
      replaced = true;
    } else {
      nodes.push_back(c);
    }
  }
}

}  // namespace

void distribute_quadtree(const std::vector<cv::KeyPoint>& kps, float min_x, float max_x,
                         float min_y, float max_y, int target, QuadtreeScratch& s,
                         std::vector<int>& keep) {
  keep.clear();
  const int n = static_cast<int>(kps.size());
  if (n == 0 || target <= 0) return;

  // Step 1: initial nodes, round(W/H) columns (at least one), filled by a
  // counting sort of the keypoints on their column.
  const float w = max_x - min_x, h = max_y - min_y;
  const int n_ini = std::max(1, static_cast<int>(std::lround(w / std::max(h, 1.0f))));
  const float col_w = w / n_ini;
  s.bucket_count.assign(n_ini + 1, 0);
  auto column = [&](const cv::KeyPoint& k) {
    return std::clamp(static_cast<int>((k.pt.x - min_x) / col_w), 0, n_ini - 1);
  };
  for (const cv::KeyPoint& k : kps) ++s.bucket_count[column(k) + 1];
  for (int c = 0; c < n_ini; ++c) s.bucket_count[c + 1] += s.bucket_count[c];
  s.index.resize(n);
  s.order.assign(s.bucket_count.begin(), s.bucket_count.end() - 1);  // write cursors
  for (int k = 0; k < n; ++k) s.index[s.order[column(kps[k])]++] = k;
  s.nodes.clear();
  for (int c = 0; c < n_ini; ++c) {
    if (s.bucket_count[c + 1] == s.bucket_count[c]) continue;
    s.nodes.push_back({min_x + c * col_w, min_y, min_x + (c + 1) * col_w, max_y,
                       s.bucket_count[c], s.bucket_count[c + 1]});
  }

  // Steps 2 and 3.
  while (static_cast<int>(s.nodes.size()) < target) {
    int expandable = 0;
    for (const Node& nd : s.nodes) expandable += splittable(nd) ? 1 : 0;
    if (expandable == 0) break;
    const size_t n_nodes = s.nodes.size();
    if (static_cast<int>(n_nodes) + 3 * expandable <= target) {
      // A full round cannot overshoot: split every node with > 1 keypoint.
      for (size_t i = 0; i < n_nodes; ++i)
        if (splittable(s.nodes[i])) split(s.nodes, i, kps, s.index);
    } else {
      // Close to the target: split the most populated nodes first.
      s.order.clear();
      for (size_t i = 0; i < n_nodes; ++i)
        if (splittable(s.nodes[i])) s.order.push_back(static_cast<int>(i));
      std::stable_sort(s.order.begin(), s.order.end(), [&](int a, int b) {
        return s.nodes[a].end - s.nodes[a].begin > s.nodes[b].end - s.nodes[b].begin;
      });
      for (int i : s.order) {
        split(s.nodes, static_cast<size_t>(i), kps, s.index);
        if (static_cast<int>(s.nodes.size()) >= target) break;
      }
    }
  }

  // Step 4: the strongest corner of each leaf.
  keep.reserve(s.nodes.size());
  for (const Node& nd : s.nodes) {
    int best = s.index[nd.begin];
    for (int j = nd.begin + 1; j < nd.end; ++j)
      if (kps[s.index[j]].response > kps[best].response) best = s.index[j];
    keep.push_back(best);
  }
}

}  // namespace dynaorb::features::detail
