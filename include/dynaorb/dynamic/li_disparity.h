#pragma once
// Dense disparity of the rectified stereo pair by semi-global block matching
// (Li et al. 2021, Sec. III: "the disparity of each point is calculated using
// SGBM [24]"), and the depth it gives.
#include <opencv2/core.hpp>

#include "dynaorb/dynamic/li_options.h"

namespace dynaorb::dynamic {

// cv::StereoSGBM on left/right (CV_8UC1, same size), run on the pair scaled by
// o.sgbm_scale and brought back to the full resolution (nearest neighbour, so
// no disparity is invented across an edge). Returns CV_32FC1 disparity in
// full-resolution pixels, 0 where SGBM found no match. Empty on bad input.
cv::Mat li_disparity(const cv::Mat& left, const cv::Mat& right, const LiOptions& o);

// The disparity with every run of zeros along a row filled by the smaller of
// the disparities at its two ends (one end at the image border: that end's);
// rows without any disparity stay 0. SPS-Stereo's occlusion filling.
cv::Mat li_fill_occlusions(const cv::Mat& disparity);

// depth = bf / disparity (CV_32FC1 metres, 0 where the disparity is 0); empty
// when bf <= 0 or the disparity is empty.
cv::Mat li_depth_from_disparity(const cv::Mat& disparity, double bf);

}  // namespace dynaorb::dynamic
