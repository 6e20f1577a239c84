#pragma once
// The immutable part of a frame: keypoints (as detected and undistorted),
// descriptors, stereo / RGB-D depth and a grid for radius searches. A frame
// and the keyframe made from it share one Features by shared_ptr.
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/map/calibration.h"

namespace dynaorb::map {

struct Features {
  std::shared_ptr<const Calibration> calib;
  std::vector<cv::KeyPoint> keys;     // as detected (distorted image)
  std::vector<cv::KeyPoint> keys_un;  // undistorted
  cv::Mat descriptors;                // N x 32 CV_8U
  std::vector<float> u_right;         // virtual right coordinate, -1: none
  std::vector<float> depth;           // metres, -1: none

  int size() const { return static_cast<int>(keys_un.size()); }
  bool has_depth(int i) const { return depth[i] > 0; }
  bool is_close(int i) const { return depth[i] > 0 && depth[i] < calib->th_depth; }
  const unsigned char* descriptor(int i) const { return descriptors.ptr<unsigned char>(i); }

  // Builds the grid; call once after keys_un is final.
  void build_grid();
  // Indices of keypoints within `radius` (a square window, as ORB-SLAM) of
  // (x, y), on levels [min_level, max_level] (-1: any); cell by cell, row
  // major, ascending index within a cell.
  std::vector<int> in_area(double x, double y, double radius, int min_level = -1,
                           int max_level = -1) const;
  // The same into `out` (cleared first), for callers that reuse one buffer
  // over many searches.
  void in_area(double x, double y, double radius, int min_level, int max_level, std::vector<int>& out) const;

 private:
  static constexpr int kGridCols = 64, kGridRows = 48;
  // What a search tests of a keypoint, beside its index: the cells' keypoints
  // stored together (cell by cell, ascending index), cell k's in
  // [cell_start_[k], cell_start_[k + 1]). One allocation per frame instead of
  // one per occupied cell, and a search reads contiguous memory. Against a
  // vector per cell and a vector returned per search (out/prof/ab_grid.sh,
  // interleaved, asynchronous, unpaced): synthetic mono with movers, `full`,
  // tracking stage median of 10 + 10 runs 4.6 -> 3.35 ms, track call 23.7 ->
  // 22.6 ms; EuRoC V1 mono (initialisation attempts all along), 3 + 3 runs,
  // 18.8 -> 17.2 ms. Same matches (the seeds bench's trajectories identical).
  struct GridItem {
    float x, y;
    int octave, index;
  };
  double cell_inv_w_ = 0, cell_inv_h_ = 0;
  std::vector<int> cell_start_;
  std::vector<GridItem> cell_items_;
};

}  // namespace dynaorb::map
