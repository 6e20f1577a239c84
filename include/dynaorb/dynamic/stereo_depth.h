#pragma once
// Dense depth of a rectified stereo pair by OpenCV's semi-global block
// matching (Hirschmueller 2008): the depth STDyn-SLAM's camera node gives
// its dense map, and what the dense frame (System::dense_frame) and the ROS
// node's keyframe clouds use when the sensor has no depth of its own.
#include <opencv2/core.hpp>

namespace dynaorb::dynamic {

// No paper of ours fixes these (STDyn-SLAM and Li et al. 2021 only name
// SGBM): the defaults are OpenCV's recommended smoothness terms
// P1 = 8 * block^2, P2 = 32 * block^2 on grey images, and its sample's
// uniqueness / speckle values.
struct StereoDepthOptions {
  int num_disparities = 128;  // multiple of 16: the nearest depth is bf / 128
  int block_size = 5;         // odd
  int uniqueness_ratio = 10;  // percent margin of the best cost over the second
  int speckle_window = 100;   // pixels of a disparity blob treated as speckle
  int speckle_range = 2;      // disparity variation inside a blob
  int disp12_max_diff = 1;    // left-right consistency [px]
  bool three_way = true;      // MODE_SGBM_3WAY: OpenCV's faster variant of the same cost

  // Throws std::invalid_argument naming the option that is out of range.
  void validate() const;
};

// Metres (CV_32FC1, 0 where SGBM found no disparity) of the left image of a
// rectified pair; bf = baseline * fx. Grey or BGR 8-bit images of one size;
// anything else, or bf <= 0, gives an empty Mat.
cv::Mat stereo_depth(const cv::Mat& left, const cv::Mat& right, double bf, const StereoDepthOptions& o = {});

}  // namespace dynaorb::dynamic
