#pragma once
// Private header of src/features: the keypoint distribution of ORB-SLAM
// (Mur-Artal et al., T-RO 2015, Sec. III-A; ORB-SLAM2's "octree"), also
// described in Li et al. 2021, Sec. III-A: a quadtree over the detection area
// is refined until it has as many non-empty leaves as the wanted number of
// keypoints, and each leaf keeps its strongest corner.
#include <opencv2/core.hpp>
#include <vector>

namespace dynaorb::features::detail {

// Reusable buffers, so that repeated calls do not allocate.
struct QuadtreeScratch {
  struct Node {
    float x0, y0, x1, y1;  // bounds, [x0, x1) x [y0, y1)
    int begin, end;        // range of QuadtreeScratch::index holding its keypoints
  };
  std::vector<int> index;
  std::vector<Node> nodes;
  std::vector<int> order;
  std::vector<int> bucket_count;
};

// keypoints: candidates of one pyramid level, inside [min_x, max_x) x [min_y, max_y).
// target: wanted number of keypoints. keep: on return, the indices of the
// chosen keypoints (at most target + 3; fewer when there are not enough
// separable candidates).
void distribute_quadtree(const std::vector<cv::KeyPoint>& keypoints, float min_x, float max_x,
                         float min_y, float max_y, int target, QuadtreeScratch& scratch,
                         std::vector<int>& keep);

}  // namespace dynaorb::features::detail
