#pragma once
// The per-keyframe dense cloud of the SLAM node (ROS-free, so that it is
// unit-tested): every pixel with a depth, in the camera frame, coloured from
// the image, minus the pixels the dynamic mask marks. STDyn-SLAM (Sec. III-D)
// builds its local cloud the same way from the left image, the segmentation
// and a depth image that its camera node computes from the stereo pair; for a
// stereo camera without a depth topic, dynamic::stereo_depth (the core's
// semi-global block matching) does that.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace dynaorb::node {

struct DenseCloudOptions {
  // STDyn-SLAM lets the user choose the maximum depth of the local cloud and
  // gives no value; 6 m keeps RGB-D sensors within their useful range.
  double max_depth = 6.0;  // metres
  double min_depth = 0.1;  // metres: closer values are sensor noise
  int stride = 2;          // every stride-th pixel in both directions (1: all)
};

struct DenseCloud {
  std::vector<Eigen::Vector3f> xyz;          // camera frame, metres
  std::vector<std::array<std::uint8_t, 3>> rgb;  // per point (grey repeated), empty when no colour
  // Pixels visited and why they gave no point.
  long pixels = 0, no_depth = 0, out_of_range = 0, masked = 0;
};

// Builds clouds for one camera; the per-pixel rays (undistorted with K and
// dist) are computed once per image size.
class DenseCloudBuilder {
 public:
  explicit DenseCloudBuilder(const DenseCloudOptions& options = {});

  // depth_m: 32FC1 metres (0, NaN: none); colour: 8UC3 in `rgb_order` or 8UC1,
  // same size, or empty; exclude: 8UC1, non-zero drops the pixel, or empty.
  // K: 3x3 of the depth pixels; dist: their distortion (empty: none).
  // Bad sizes or types give an empty cloud (never a crash); see `error`.
  DenseCloud build(const cv::Mat& depth_m, const cv::Mat& colour, bool rgb_order, const cv::Mat& exclude,
                   const cv::Mat& K, const cv::Mat& dist);
  const std::string& error() const { return error_; }
  const DenseCloudOptions& options() const { return options_; }

 private:
  DenseCloudOptions options_;
  std::string error_;
  cv::Mat rays_;  // CV_32FC2: normalised (x/z, y/z) per pixel
  cv::Mat rays_K_, rays_dist_;
};

// The exclusion mask of a label image: 255 where the label is one of the
// movable ids, else 0 (what python/dynaorb/runner does with a segmenter's
// labels). 8UC1 or 16UC1 labels; anything else gives an empty Mat.
cv::Mat movable_mask(const cv::Mat& labels, const std::vector<int>& movable_ids);

}  // namespace dynaorb::node
