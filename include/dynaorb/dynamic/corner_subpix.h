// Sub-pixel corner refinement: cv::cornerSubPix (Foerstner's least-squares
// corner: the point every gradient in the window points away from) with
// OpenCV's floating-point operations in OpenCV's order, two or four corners
// at a time on SIMD lanes: the same positions, bit for bit, in 35-45 % of the
// time (src/dynamic/corner_subpix.cc).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace dynaorb::dynamic {

// Refines `corners` in place on the 8-bit grey image, as
//   cv::cornerSubPix(grey, corners, Size(half_window, half_window), Size(-1, -1),
//                    TermCriteria(COUNT | EPS, max_iterations, epsilon))
// does: at most max_iterations steps, stopping when a step is shorter than
// epsilon px; a corner that ends more than half_window px from where it
// started keeps its start. Throws cv::Exception on what cornerSubPix refuses
// (not 8-bit single channel, image smaller than the window, a corner outside
// the image).
void refine_corners_subpix(const cv::Mat& grey, std::vector<cv::Point2f>& corners, int half_window,
                           int max_iterations, double epsilon);

namespace detail {
// The corners refined side by side: 4 where the CPU has AVX2, else 2.
int subpix_lanes_available();
// refine_corners_subpix with that many lanes (2, or 4 where available): the tests run both.
void refine_corners_subpix_lanes(const cv::Mat& grey, std::vector<cv::Point2f>& corners, int half_window,
                                 int max_iterations, double epsilon, int lanes);
}  // namespace detail

}  // namespace dynaorb::dynamic
