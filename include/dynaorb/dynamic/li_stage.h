#pragma once
// Li et al. 2021 ("Robust Stereo Visual SLAM for Dynamic Environments With
// Moving Object", IEEE Access 9) as one stage of the dynamic filter: a
// network-free, stereo-only detector of moving objects.
//   1. SGBM disparity of the current pair (li_disparity.h); the depth it gives
//      (bf / d) goes into ctx.current.depth for the later stages and the map;
//   2. quadtree FAST on the previous left image, LK into the current one,
//      RANSAC F, epipolar distance vs alpha_epi + beta_epi * d (eq. 1-3,
//      li_epipolar.h); (ours, LiOptions::rigid_check) also the pairs'
//      reprojection error under the camera's motion from PnP on the previous
//      frame's depth, with agreeing neighbours (li_rigidity.h);
//   3. dynamic points clustered into ROIs (eq. 4, > 4 points, li_rois.h);
//   4. improved SLIC on the ROIs (eq. 5-7, li_superpixels.h);
//   5. a RANSAC disparity plane per superpixel (eq. 8, li_planes.h);
//   6. co-planar / hinge / occlusion boundaries (eq. 9-11, li_boundaries.h);
//   7. a rectangle per object from the occlusion boundaries around its
//      dynamic points (li_regions.h), ORed into ctx.dynamic: no ORB feature is
//      extracted inside it (Sec. III-C); (ours, LiOptions::foreground_only)
//      only its part as near as the object, and 15 px around that;
//   8. (ours, LiOptions::keep_frames > 0) the rectangles of the last frames
//      that the new ones do not cover, moved by the flow, ORed in too.
// It computes its own motion cues (the paper's FAST + LK), so it asks the
// filter for none, and it reads no semantic input.
//
// What the method cannot see: a point moving along its own epipolar line
// (an object travelling parallel to the camera's translation, e.g. a vehicle
// driving beside a forward-moving camera) passes eq. 2-3 and is static to it;
// so is a slow mover whose flow stays under T_epi (the paper's Sec. V).
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/dynamic/li_boundaries.h"
#include "dynaorb/dynamic/li_epipolar.h"
#include "dynaorb/dynamic/li_options.h"
#include "dynaorb/dynamic/li_planes.h"
#include "dynaorb/dynamic/li_regions.h"
#include "dynaorb/dynamic/li_rigidity.h"
#include "dynaorb/dynamic/li_rois.h"
#include "dynaorb/dynamic/stage.h"

namespace dynaorb::dynamic {

// Everything one frame produced, kept for tests, visualisation and benchmarks.
struct LiFrameDetail {
  cv::Mat disparity;                 // CV_32FC1 full-resolution px, 0 = none
  LiEpipolarResult epipolar;
  LiRigidityResult rigidity;         // rigid_check (ours)
  std::vector<int> dynamic_tracks;   // indices into epipolar.tracks; cluster members index this
  std::vector<LiCluster> clusters;   // the moving objects' ROIs
  std::vector<cv::Rect> slic_areas;  // the merged ROIs SLIC ran on
  cv::Mat labels;                    // CV_32SC1 superpixels of the whole image, -1 outside the areas
  int superpixels = 0;
  std::vector<LiPlane> planes;
  LiBoundaries boundaries;
  std::vector<LiRegion> regions;     // one per cluster
  std::vector<cv::Rect> rectangles;  // the dynamic ones
  std::vector<float> rectangle_disparity;  // per rectangle, its dynamic points' smallest disparity (0: none)
  std::vector<cv::Rect> kept;        // earlier frames' rectangles carried into this one (keep_frames)
};

class LiStage : public Stage {
 public:
  explicit LiStage(LiOptions options = {});

  std::string name() const override { return "li"; }
  bool supports(Sensor sensor) const override { return sensor == Sensor::kStereo; }
  bool needs_motion_cues() const override { return false; }
  // report.values: the counts (corners, tracked, judged, dynamic, static,
  // f_inliers, rois, roi_pixels, superpixels, slic_iterations,
  // slic_visits_per_pixel, planes, boundaries, coplanar, hinge,
  // occlusion_boundaries, unlabelled_boundaries, rectangles,
  // rejected_clusters, marked_fraction, disparity_valid, depth_filled) and the
  // per-step times (disparity_ms, corners_ms, flow_ms, fmatrix_ms, rois_ms,
  // slic_ms, planes_ms, boundaries_ms, rectangles_ms, total_ms); on degenerate
  // input one of skipped_no_calibration, skipped_bad_input, skipped_no_right,
  // skipped_no_previous, skipped_previous_mismatch, too_few_points, f_failed,
  // no_moving_object, failed_opencv (= 1) and nothing new is marked;
  // kept_rectangles: the earlier frames' rectangles marked again (keep_frames);
  // epipolar_dynamic: the pairs eq. 3 found dynamic;
  // with rigid_check: rigid_ms,
  // rigid_prior, rigid_candidates, rigid_inliers, rigid_judged,
  // rigid_over_threshold, rigid_added, and rigid_<failure> = 1 when it could
  // not run (no_previous_depth, too_few_points, pnp_failed).
  void process(Context& ctx, StageReport& report) override;
  void reset() override { kept_.clear(); }

  const LiOptions& options() const { return o_; }
  const LiFrameDetail& last() const { return last_; }

 private:
  // Steps 4-7 on this frame's clusters: superpixels, planes, boundary labels,
  // rectangles ORed into ctx.dynamic.
  void segment_and_mark(const cv::Mat& grey, Context& ctx, StageReport& report);
  // Step 2, ours (rigid_check): the pairs against the camera's motion in 3-D
  // (li_rigidity.h), with SLAM's prediction when it has one.
  void rigidity_check(Context& ctx, StageReport& report);
  // Steps 1-7 (process without the time and the carried rectangles).
  void detect(Context& ctx, StageReport& report);
  // Step 8: moves the kept rectangles by this frame's flow; drops those the
  // new rectangles cover, those older than keep_frames and those found in
  // fewer than keep_min_hits frames; marks the rest; keeps the new ones.
  void carry_rectangles(Context& ctx, StageReport& report);

  struct KeptRectangle {
    cv::Rect rect;
    int age = 0;   // frames since a new rectangle last found it
    int hits = 1;  // frames a new rectangle found it in (keep_min_hits)
    float disparity = 0;  // its object's smallest disparity (foreground_only)
  };

  LiOptions o_;
  LiFrameDetail last_;
  std::vector<KeptRectangle> kept_;
};

}  // namespace dynaorb::dynamic
