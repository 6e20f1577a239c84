#pragma once
// Li et al. 2021, Sec. III-A, second half: dynamic regions of interest. Two
// dynamic points belong to one object when they are within T_s = alpha_s +
// beta_s * d of each other (eq. 4) and their disparities differ by at most
// T_disp; the groups are the connected components of that relation, and a
// group with more than four points is a moving object whose area is an ROI.
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/dynamic/li_options.h"

namespace dynaorb::dynamic {

struct LiCluster {
  std::vector<int> members;  // indices into the points given
  double mean_disparity = 0;
  float min_disparity = 0;    // of its farthest member
  cv::Rect bounds;           // bounding box of the members' pixels
  cv::Rect roi;              // bounds grown by roi_margin_factor * T_s(mean_disparity), clipped
};

// points / disparities: the dynamic points (current image) and their
// disparities (> 0). Only clusters with at least o.min_cluster_points points
// are returned, largest first.
std::vector<LiCluster> li_cluster_dynamic_points(const std::vector<cv::Point2f>& points,
                                                 const std::vector<float>& disparities,
                                                 const cv::Size& image, const LiOptions& o);

// Unions overlapping rectangles until none overlap (SLIC then runs once on
// each merged area instead of twice on the shared pixels).
std::vector<cv::Rect> li_merge_overlapping(std::vector<cv::Rect> rects);

}  // namespace dynaorb::dynamic
