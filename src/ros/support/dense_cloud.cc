#include "dense_cloud.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace dynaorb::node {

DenseCloudBuilder::DenseCloudBuilder(const DenseCloudOptions& options) : options_(options) {
  options_.stride = std::max(1, options_.stride);
}

namespace {

bool same_matrix(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty()) return a.empty() && b.empty();
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

}  // namespace

DenseCloud DenseCloudBuilder::build(const cv::Mat& depth_m, const cv::Mat& colour, bool rgb_order,
                                    const cv::Mat& exclude, const cv::Mat& K_in, const cv::Mat& dist_in) {
  DenseCloud cloud;
  error_.clear();
  if (depth_m.empty() || depth_m.type() != CV_32FC1) {
    error_ = "depth must be a non-empty 32FC1 image in metres";
    return cloud;
  }
  if (!colour.empty() && (colour.size() != depth_m.size() || colour.depth() != CV_8U ||
                          (colour.channels() != 1 && colour.channels() != 3))) {
    error_ = "colour must be 8UC1 or 8UC3 of the depth's size";
    return cloud;
  }
  if (!exclude.empty() && (exclude.size() != depth_m.size() || exclude.type() != CV_8UC1)) {
    error_ = "the exclusion mask must be 8UC1 of the depth's size";
    return cloud;
  }
  cv::Mat K, dist;
  K_in.convertTo(K, CV_64F);
  if (K.rows != 3 || K.cols != 3) {
    error_ = "K must be 3x3";
    return cloud;
  }
  if (!dist_in.empty()) dist_in.convertTo(dist, CV_64F);
  if (cv::countNonZero(dist) == 0) dist.release();

  if (rays_.size() != depth_m.size() || !same_matrix(K, rays_K_) || !same_matrix(dist, rays_dist_)) {
    std::vector<cv::Point2f> pixels;
    pixels.reserve(depth_m.total());
    for (int v = 0; v < depth_m.rows; ++v)
      for (int u = 0; u < depth_m.cols; ++u) pixels.emplace_back(static_cast<float>(u), static_cast<float>(v));
    std::vector<cv::Point2f> normalised;
    cv::undistortPoints(pixels, normalised, K, dist);  // no P: normalised coordinates
    rays_ = cv::Mat(normalised, true).reshape(2, depth_m.rows);
    rays_K_ = K.clone();
    rays_dist_ = dist.clone();
  }

  const int step = options_.stride;
  const bool colour3 = !colour.empty() && colour.channels() == 3;
  for (int v = 0; v < depth_m.rows; v += step) {
    const float* d = depth_m.ptr<float>(v);
    const cv::Vec2f* ray = rays_.ptr<cv::Vec2f>(v);
    const std::uint8_t* m = exclude.empty() ? nullptr : exclude.ptr<std::uint8_t>(v);
    for (int u = 0; u < depth_m.cols; u += step) {
      ++cloud.pixels;
      if (m && m[u]) {
        ++cloud.masked;
        continue;
      }
      const float z = d[u];
      if (!std::isfinite(z) || z <= 0.0f) {
        ++cloud.no_depth;
        continue;
      }
      if (z < options_.min_depth || z > options_.max_depth) {
        ++cloud.out_of_range;
        continue;
      }
      cloud.xyz.emplace_back(ray[u][0] * z, ray[u][1] * z, z);
      if (colour.empty()) continue;
      if (colour3) {
        const cv::Vec3b c = colour.at<cv::Vec3b>(v, u);
        cloud.rgb.push_back(rgb_order ? std::array<std::uint8_t, 3>{c[0], c[1], c[2]}
                                      : std::array<std::uint8_t, 3>{c[2], c[1], c[0]});
      } else {
        const std::uint8_t g = colour.at<std::uint8_t>(v, u);
        cloud.rgb.push_back({g, g, g});
      }
    }
  }
  return cloud;
}

cv::Mat movable_mask(const cv::Mat& labels, const std::vector<int>& movable_ids) {
  if (labels.empty() || labels.channels() != 1 || (labels.depth() != CV_8U && labels.depth() != CV_16U)) return {};
  cv::Mat mask(labels.size(), CV_8UC1, cv::Scalar(0));
  std::vector<bool> movable(labels.depth() == CV_8U ? 256 : 65536, false);
  for (int id : movable_ids)
    if (id >= 0 && id < static_cast<int>(movable.size())) movable[id] = true;
  for (int v = 0; v < labels.rows; ++v) {
    std::uint8_t* out = mask.ptr<std::uint8_t>(v);
    if (labels.depth() == CV_8U) {
      const std::uint8_t* in = labels.ptr<std::uint8_t>(v);
      for (int u = 0; u < labels.cols; ++u) out[u] = movable[in[u]] ? 255 : 0;
    } else {
      const std::uint16_t* in = labels.ptr<std::uint16_t>(v);
      for (int u = 0; u < labels.cols; ++u) out[u] = movable[in[u]] ? 255 : 0;
    }
  }
  return mask;
}

}  // namespace dynaorb::node
