// Harris corners chosen as cv::goodFeaturesToTrack chooses them, with the
// response in exact integer arithmetic (src/dynamic/harris_corners.cc).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace dynaorb::dynamic {

// The corners of
//   cv::goodFeaturesToTrack(grey, corners, max_corners, quality_level, min_distance, mask,
//                           block_size, /*useHarrisDetector=*/true, k)
// by the same rules: the Harris response R = AC - B^2 - k (A + C)^2 of the
// 3x3 Sobel gradients' products summed over a block_size box (A = sum dx^2,
// B = sum dx dy, C = sum dy^2; BORDER_REFLECT_101); the pixels off the
// image's outer ring where `mask` is set (empty: everywhere) whose response
// is above quality_level times the largest inside the mask and is the
// largest in their 3x3 neighbourhood; strongest first (equal ones: the later in
// raster order first); each kept unless a kept one lies nearer than
// min_distance px; at most max_corners (0: all).
//
// What differs is the arithmetic. OpenCV scales the gradients by 1 / (4 *
// 255 * block_size) and rounds every step to float; here the gradients, their
// products and the box sums are exact integers and R is formed from them in
// double (AC - B^2 and (A + C)^2 exactly, two roundings after). The scale
// does not change which pixels pass or their order, so the corners are
// OpenCV's except where two responses are equal to within OpenCV's float
// rounding (measured on real and rendered frames in the gtests). It takes
// about a third of OpenCV's time; its buffers (24 bytes a pixel: 7.4 MB for
// 640x480) are kept per thread between calls.
//
// For a submatrix (OpenCV's filters read its parent image past its edge,
// these reflect at it), images under 3x3, a box larger than the image, and
// block_size above 45 (where the sums could overflow) or below 1, it calls
// cv::goodFeaturesToTrack itself. Throws cv::Exception on
// what goodFeaturesToTrack refuses (not 8-bit single channel, a mask of
// another size or type, quality_level <= 0, min_distance < 0,
// max_corners < 0).
std::vector<cv::Point2f> harris_corners(const cv::Mat& grey, int max_corners, double quality_level,
                                        double min_distance, const cv::Mat& mask, int block_size, double k);

}  // namespace dynaorb::dynamic
