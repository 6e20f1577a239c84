#include "dynaorb/dynamic/li_disparity.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace dynaorb::dynamic {

cv::Mat li_disparity(const cv::Mat& left, const cv::Mat& right, const LiOptions& o) {
  if (left.empty() || right.empty() || left.type() != CV_8UC1 || right.type() != CV_8UC1 ||
      left.size() != right.size())
    return cv::Mat();
  const double s = std::clamp(o.sgbm_scale, 1e-3, 1.0);
  cv::Mat l = left, r = right;
  if (s < 1.0) {
    // INTER_AREA: the average over each source block, so texture finer than
    // the new pixel does not alias into false matches.
    cv::resize(left, l, cv::Size(), s, s, cv::INTER_AREA);
    cv::resize(right, r, cv::Size(), s, s, cv::INTER_AREA);
  }
  if (l.cols < 8 || l.rows < 8) return cv::Mat();
  const int n_disp = std::max(16, static_cast<int>(std::ceil(o.sgbm_num_disparities * s / 16.0)) * 16);
  const int bs = o.sgbm_block_size;
  const int p1 = static_cast<int>(std::lround(o.sgbm_p1_per_pixel * bs * bs));
  const int p2 = static_cast<int>(std::lround(o.sgbm_p2_per_pixel * bs * bs));
  auto sgbm = cv::StereoSGBM::create(0, n_disp, bs, p1, p2, o.sgbm_disp12_max_diff, 0,
                                     o.sgbm_uniqueness_ratio, o.sgbm_speckle_window,
                                     o.sgbm_speckle_range,
                                     o.sgbm_three_way ? cv::StereoSGBM::MODE_SGBM_3WAY
                                                      : cv::StereoSGBM::MODE_SGBM);
  cv::Mat fixed;  // CV_16S, disparity * 16, (minDisparity - 1) * 16 where unmatched
  sgbm->compute(l, r, fixed);
  cv::Mat d;
  fixed.convertTo(d, CV_32F, 1.0 / (16.0 * s));
  cv::threshold(d, d, 0.0, 0.0, cv::THRESH_TOZERO);
  if (s < 1.0) cv::resize(d, d, left.size(), 0, 0, cv::INTER_NEAREST);
  return d;
}

cv::Mat li_fill_occlusions(const cv::Mat& disparity) {
  if (disparity.empty() || disparity.type() != CV_32FC1) return cv::Mat();
  cv::Mat out = disparity.clone();
  for (int y = 0; y < out.rows; ++y) {
    float* d = out.ptr<float>(y);
    int last = -1;  // last column with a disparity
    for (int x = 0; x <= out.cols; ++x) {
      if (x < out.cols && !(d[x] > 0.f)) continue;
      if (x - last > 1) {
        float fill = 0.f;
        if (last >= 0 && x < out.cols) fill = std::min(d[last], d[x]);
        else if (last >= 0) fill = d[last];
        else if (x < out.cols) fill = d[x];
        for (int u = last + 1; u < x; ++u) d[u] = fill;
      }
      last = x;
    }
  }
  return out;
}

cv::Mat li_depth_from_disparity(const cv::Mat& disparity, double bf) {
  if (disparity.empty() || disparity.type() != CV_32FC1 || !(bf > 0)) return cv::Mat();
  cv::Mat depth(disparity.size(), CV_32FC1, cv::Scalar(0));
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    float* z = depth.ptr<float>(y);
    for (int x = 0; x < disparity.cols; ++x)
      if (d[x] > 0.f && std::isfinite(d[x])) z[x] = static_cast<float>(bf / d[x]);
  }
  return depth;
}

}  // namespace dynaorb::dynamic
