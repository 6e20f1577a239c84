#pragma once
// Li et al. 2021, Sec. III-A, first half: dynamic feature points. FAST corners
// of the previous left image spread by a quadtree, tracked into the current
// image by pyramidal Lucas-Kanade, a fundamental matrix by RANSAC, and the
// distance of each current point to its epipolar line (eq. 1-2) against a
// threshold that grows with the point's disparity (eq. 3).
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/dynamic/li_options.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic {

struct LiTrack {
  cv::Point2f prev, cur;     // tracked-image pixels (previous, current)
  cv::Point2f prev_u, cur_u; // the same, undistorted (the pixels of eq. 1-2)
  float disparity = 0;       // d_i of eq. 3 at `cur`, full-resolution px; 0: none, not judged
  double distance = -1;      // D_epi of eq. 2, px (-1: not judged)
  double threshold = 0;      // T_epi of eq. 3, px
  bool dynamic = false;
  double rigid_residual = -1;  // px, li_rigidity.h (-1: not checked)
  double rigid_threshold = 0;  // px, the residual's threshold there
};

struct LiEpipolarResult {
  std::vector<LiTrack> tracks;  // every pair LK tracked
  int corners = 0;              // quadtree corners on the previous image
  int judged = 0;               // tracks with a disparity (classified by eq. 3)
  int dynamic = 0;
  bool has_F = false;
  cv::Matx33d F;                // q^T F p = 0, p previous, q current (undistorted px)
  int f_inliers = 0;            // of the pairs F was fitted to
  int f_fitted = 0;             // pairs F was fitted to
  int f_excluded = 0;           // pairs in the previous frame's dynamic mask (f_exclude_previous_dynamic)
  std::string failure;          // "" or "too_few_points" / "f_failed"
  double corners_ms = 0, flow_ms = 0, fmatrix_ms = 0;
};

// Sec. III-A steps 1-4: FAST in fast_cell_px squares (fast_threshold, then
// fast_min_threshold where a square found nothing), then the quadtree keeps
// the strongest corner of each of ~n_points leaves. Corners within border_px
// of the edge are dropped. Empty on a non-CV_8UC1 image.
std::vector<cv::Point2f> li_quadtree_fast(const cv::Mat& grey, const LiOptions& o);

// The disparity at p: the pixel's, else the median of the valid ones within
// `radius`, else 0.
float li_disparity_at(const cv::Mat& disparity, const cv::Point2f& p, int radius);

// The whole step on the previous and current left images (CV_8UC1, same
// size) and the current disparity (CV_32FC1, full resolution). Never throws:
// too few tracks or a failed F give `failure` and no dynamic point.
// prev_dynamic: the previous frame's dynamic mask (CV_8UC1, the images'
// size; else ignored), whose pairs F is not fitted to when
// o.f_exclude_previous_dynamic is set.
LiEpipolarResult li_epipolar_check(const cv::Mat& prev_grey, const cv::Mat& cur_grey,
                                   const cv::Mat& disparity, const map::Calibration& calib,
                                   const LiOptions& o, const cv::Mat& prev_dynamic = cv::Mat());

}  // namespace dynaorb::dynamic
