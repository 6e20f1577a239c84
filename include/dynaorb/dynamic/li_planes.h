#pragma once
// Li et al. 2021, eq. 8: one disparity plane d = alpha x + beta y + gamma per
// superpixel, fitted by RANSAC to the SGBM disparities of its pixels (SGBM
// mismatches and noise are the outliers), then refined by least squares on
// the inliers.
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/dynamic/li_options.h"

namespace dynaorb::dynamic {

struct LiPlane {
  double a = 0, b = 0, c = 0;  // d = a x + b y + c, x / y full-image px
  bool valid = false;
  int support = 0;   // pixels with disparity
  int inliers = 0;   // of them, within plane_inlier_px of the plane
  double at(double x, double y) const { return a * x + b * y + c; }
};

// RANSAC over (x, y, d) samples (at most o.plane_max_samples of them score
// the hypotheses; the final inliers are counted and refitted on all).
// invalid when fewer than o.plane_min_pixels points or no non-degenerate sample.
LiPlane li_fit_disparity_plane(const std::vector<cv::Point3f>& xyd, const LiOptions& o, cv::RNG& rng);

// The planes of superpixels 0 .. count-1 of `labels` (CV_32SC1, -1 = none),
// from `disparity` (CV_32FC1, 0 = none), visiting only the pixels of `areas`.
std::vector<LiPlane> li_fit_superpixel_planes(const cv::Mat& labels, int count, const cv::Mat& disparity,
                                              const std::vector<cv::Rect>& areas, const LiOptions& o);

}  // namespace dynaorb::dynamic
