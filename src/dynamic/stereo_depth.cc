#include "dynaorb/dynamic/stereo_depth.h"

#include <cstdint>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

namespace dynaorb::dynamic {

void StereoDepthOptions::validate() const {
  if (num_disparities < 16 || num_disparities % 16 != 0)
    throw std::invalid_argument("stereo num_disparities must be a positive multiple of 16, not " +
                                std::to_string(num_disparities));
  if (block_size < 1 || block_size % 2 == 0)
    throw std::invalid_argument("stereo block_size must be odd and >= 1, not " + std::to_string(block_size));
  if (uniqueness_ratio < 0 || speckle_window < 0 || speckle_range < 0)
    throw std::invalid_argument("stereo uniqueness_ratio, speckle_window and speckle_range must be >= 0");
}

namespace {

cv::Mat grey_of(const cv::Mat& in) {
  if (in.channels() == 1) return in;
  cv::Mat g;
  if (in.channels() == 3) cv::cvtColor(in, g, cv::COLOR_BGR2GRAY);
  return g;
}

}  // namespace

cv::Mat stereo_depth(const cv::Mat& left_in, const cv::Mat& right_in, double bf, const StereoDepthOptions& o) {
  if (left_in.empty() || right_in.empty() || left_in.size() != right_in.size() || left_in.depth() != CV_8U ||
      right_in.depth() != CV_8U || !(bf > 0.0))
    return {};
  const cv::Mat left = grey_of(left_in), right = grey_of(right_in);
  if (left.empty() || right.empty()) return {};
  o.validate();
  const int b = o.block_size;
  auto sgbm = cv::StereoSGBM::create(0, o.num_disparities, b, 8 * b * b, 32 * b * b, o.disp12_max_diff, 0,
                                     o.uniqueness_ratio, o.speckle_window, o.speckle_range,
                                     o.three_way ? cv::StereoSGBM::MODE_SGBM_3WAY : cv::StereoSGBM::MODE_SGBM);
  cv::Mat disparity16;
  sgbm->compute(left, right, disparity16);  // fixed point, 4 fractional bits
  cv::Mat depth(left.size(), CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < depth.rows; ++v) {
    const std::int16_t* dp = disparity16.ptr<std::int16_t>(v);
    float* out = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u)
      if (dp[u] > 0) out[u] = static_cast<float>(bf * 16.0 / dp[u]);
  }
  return depth;
}

}  // namespace dynaorb::dynamic
