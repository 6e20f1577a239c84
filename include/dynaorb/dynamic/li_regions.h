#pragma once
// Li et al. 2021, Sec. III-B, last paragraph: dynamic rectangles. "Starting at
// the dynamic feature point, the search for boundaries proceeds in the
// positive and negative directions of the x and y axes and stops when an
// occlusion-type boundary is found. The minimum enclosing rectangle is
// obtained for all found boundary points." One rectangle per moving object
// (cluster of dynamic points, li_rois.h).
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/dynamic/li_boundaries.h"
#include "dynaorb/dynamic/li_options.h"
#include "dynaorb/dynamic/li_rois.h"

namespace dynaorb::dynamic {

struct LiRegion {
  cv::Rect rect;            // the minimum enclosing rectangle (empty when rejected)
  int hits = 0;             // occlusion boundary points found
  int hit_directions = 0;   // of +x, -x, +y, -y, how many found at least one
  bool dynamic = false;     // hit_directions >= o.min_hit_directions
};

// For each cluster, rays from each member point along +-x and +-y through
// `labels` (CV_32SC1, -1 outside the segmented ROIs: a ray ends there) stop at
// the first boundary labelled occlusion; the hit is the last pixel before it.
// The rectangle encloses the hits and the cluster's own points.
std::vector<LiRegion> li_dynamic_rectangles(const std::vector<cv::Point2f>& points,
                                            const std::vector<LiCluster>& clusters,
                                            const cv::Mat& labels, const LiBoundaries& boundaries,
                                            const LiOptions& o);

// Sets `rect` (clipped to the image) in `mask` (CV_8UC1): every pixel, or
// with o.foreground_only and object_disparity > 0 those whose `disparity`
// (CV_32FC1, same size, 0 = none) is 0 or at least object_disparity -
// o.foreground_margin_px, and the rectangle's pixels within
// o.foreground_band_px of those. object_disparity: the smallest disparity of
// the object's dynamic points.
void li_mark_region(cv::Mat& mask, const cv::Rect& rect, const cv::Mat& disparity, float object_disparity,
                    const LiOptions& o);

}  // namespace dynaorb::dynamic
