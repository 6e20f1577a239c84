// Sub-pixel corner refinement: cv::cornerSubPix (Foerstner's least-squares
// corner: the point every gradient in the window points away from) with
// OpenCV's floating-point operations in OpenCV's order, two corners at a
// time on SIMD lanes: the same positions, bit for bit, in about half the time
// (src/dynamic/corner_subpix.cc).
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

}  // namespace dynaorb::dynamic
