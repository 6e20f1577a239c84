#pragma once
// Li et al. 2021's improved SLIC (Sec. III-B, eq. 5-7): SLIC (Achanta et al.
// [29]) on a grey image, C = [gray], where each iteration reassigns only the
// "unstable" pixels near superpixel edges instead of every pixel in every
// centre's 2S x 2S window:
//  1. centres on a regular grid of step S (eq. 6); each pixel starts in its
//     grid cell, and the pixels on the cell edges are unstable;
//  2. each unstable pixel goes to the centre, among those whose 2S x 2S
//     window holds it, with the smallest D_SLIC (eq. 5);
//  3. the centres are updated, and the flags by eq. 7: a 4-neighbour p of a
//     pixel q visited in step 2 becomes unstable when it is in another
//     cluster than q or when q changed cluster (Flag_q);
//  4. steps 2-3 repeat until no pixel changes (or max_iterations).
#include <opencv2/core.hpp>

namespace dynaorb::dynamic {

struct LiSuperpixels {
  cv::Mat labels;        // CV_32SC1, size of the input, 0 .. count-1 (some may end empty)
  int count = 0;         // number of centres
  int iterations = 0;    // step-2 passes run
  long long visits = 0;  // unstable pixels evaluated over all passes (the work done)
  bool converged = false;
};

// grey: CV_8UC1 (usually a view of an ROI). step: S_step of eq. 6 (px). nc: N_c
// of eq. 5 (grey levels). Empty result on bad input.
LiSuperpixels li_slic(const cv::Mat& grey, double step, double nc, int max_iterations);

}  // namespace dynaorb::dynamic
