#pragma once
// DDL-SLAM's multi-view geometry check (Ai et al. 2020, Sec. III-C,
// Algorithm 1), which is DynaSLAM's (Bescos et al. 2018, Sec. III-C): the
// keypoints of the previous keyframes that overlap most with the current
// frame are back-projected with their depth (X) and projected into the
// current frame with the pose of a low-cost tracking (x', projected depth
// z_proj); the parallax angle alpha = angle(x X x') above tau_alpha leaves a
// keypoint out; Delta z = z_proj - z', z' the current depth at x', above
// tau_d means something now stands in front of X: x' is dynamic. The
// dynamic points grow into regions over the current depth image (DynaSLAM:
// "a region growing algorithm"), and the regions are combined with the
// semantic mask (DDL-SLAM Fig. 1: "both semantic segmentation and
// multi-view geometry are utilized to combine masks": their union, as
// DynaSLAM's CombineMasks).
//
// Four additions of ours, all options (see DdlOptions), because
// Algorithm 1 alone fails in common cases:
//  - the pose. The paper checks with the pose of its low-cost tracking
//    (ORB-SLAM2 tracking the map on the static part); this stage is given
//    the ego-motion or SLAM's prediction, which can be pixels off, so it
//    re-estimates the pose from the reference keyframes' points followed
//    into the current image (LK + PnP RANSAC).
//  - a static surface that hides X from the current view (parallax
//    occlusion) passes the Delta z test just like a moving object, and
//    depth-continuous growing runs from an object onto the floor it stands
//    on and from there over the whole room. Each current pixel is therefore
//    checked against the reference keyframes the other way round (its own
//    depth back-projected into them): a pixel some keyframe saw with the
//    same depth and texture is static; it neither seeds nor takes a region.
//  - an object receding along the line of sight (a vehicle driving ahead of
//    the camera) never stands in front of an old keyframe point; it leaves
//    its own points behind, which the current frame sees through
//    (Delta z < -tau_d).
//  - a surface sliding along itself (the side of a vehicle driving beside
//    the camera) passes both depth tests: its old points land on it again
//    at their own depth. Where the keyframe check (above) finds other
//    texture at that depth, the point is dynamic too (seed_sliding_surfaces;
//    off by default, on in the `ddl` preset).
//
// Sensors: RGB-D; stereo when an earlier stage filled ctx.current.depth
// (e.g. Li's SGBM), else the frame is skipped (skipped_no_depth). Monocular
// has no depth image: not supported.
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "dynaorb/dynamic/stage.h"

namespace dynaorb::dynamic {

struct DdlOptions {
  // Algorithm 1 line 2, GetRefFrames: the previous keyframes with the highest
  // overlap. DDL-SLAM gives no number; DynaSLAM Sec. III-C uses 5 ("a
  // compromise between computational cost and accuracy").
  int reference_keyframes = 5;
  // A keyframe is a reference only when at least this fraction of its
  // keypoints with depth projects into the current image (ours: 0 = any
  // overlap at all; the papers rank by overlap without a floor).
  double min_overlap = 0.0;
  // Algorithm 1 line 7, tau_alpha (degrees): the angle between the
  // back-projections of x (keyframe) and x' (current) at X. DDL-SLAM gives
  // no value; DynaSLAM Sec. III-C: 30 degrees, above which "the point might be
  // occluded, and will be ignored from then on".
  double parallax_threshold_deg = 30.0;
  // Algorithm 1 as printed in DDL-SLAM sets "mask == dynamic" when
  // alpha > tau_alpha. Its source, DynaSLAM, ignores those points instead
  // (they may be occluded; marking them would mark every static point seen
  // from far enough away). false: DynaSLAM's reading (default); true: the
  // printed line.
  bool parallax_marks_dynamic = false;
  // Algorithm 1 line 11, tau_d (metres): Delta z = z_proj - z' above it is
  // dynamic. DDL-SLAM gives no value; DynaSLAM Sec. III-C: tau_z = 0.4 m
  // (chosen on TUM by maximising 0.7 precision + 0.3 recall).
  double depth_threshold_m = 0.4;
  // Keyframe keypoints farther than this, or projecting farther than this, are
  // not used (metres; 0: no limit). DynaSLAM's code keeps keyframe depths
  // below 6 m and projected depths below 7 m for the Kinect's range; ours
  // defaults to no limit, the sensor's own depth range applies.
  double max_depth_m = 0.0;
  // z' of Algorithm 1: the current depth at the projection x'. 0: that pixel
  // (the paper). r > 0: the depth closest to z_proj in a (2r+1)^2 window, so
  // a projection a pixel or two off a depth edge still finds X's surface
  // (DynaSLAM's code searches a 41x41 window for the depth closest below
  // z_proj).
  int depth_search_radius_px = 0;
  // Algorithm 1 tests one side: something in front of X (Delta z > tau_d).
  // When the current frame sees more than tau_d *behind* X (Delta z <
  // -tau_d), X is gone: a static point in view cannot be seen through. An
  // object receding along the line of sight (a vehicle driving ahead of the
  // camera at its speed) gives only this kind of evidence: its old points
  // are seen through, on the object itself. Ours: true; false is
  // Algorithm 1 as printed (keypoint recall on `dynaorb synth --movers 3`,
  // seeds 0 / 1 / 2: 0.96 / 0.95 / 0.92 with, 0.87 / 0.85 / 0.88 without,
  // precision 0.99-1.0 either way).
  // Background revealed behind an object that moved sideways gives the same
  // evidence, so with the keyframe check on (below) such an x' counts only
  // where the keyframes show motion of its own; without the check every
  // vanished point is taken.
  bool vanished_points_dynamic = true;
  // Keypoints within this many pixels of the image border are not projected
  // or tested (ours: DynaSLAM's code keeps 21 px, the size of its window).
  int border_px = 2;

  // Pose refinement (ours): DDL-SLAM checks with the pose of its low-cost
  // tracking, ORB-SLAM2's tracking of the map on the static part; the
  // ego-motion or the constant-velocity prediction this stage is given is
  // only near it, and the keyframe check below compares textures pixel by
  // pixel. The reference keyframes' points are followed by pyramidal LK
  // from their keyframe image into the current one, starting where the given
  // pose projects them (and kept when they land within refine_max_shift_px
  // of it), and the pose is re-estimated by PnP RANSAC (reprojection
  // threshold refine_reprojection_px); fewer than refine_min_inliers
  // inliers, or a result that does not put clearly more points (5 %) within
  // half that threshold than the given pose does, keep the given pose (a
  // frame full of movers can outvote the static points). On `dynaorb synth`
  // seed 0 with the given
  // pose off by 1 cm and 0.2 degrees (random axes), keypoint precision /
  // recall 0.998 / 0.961 with, 0.48 / 0.96 without; on a TUM walking_xyz
  // pair 3 s apart with its ground-truth poses the correction was 3 cm /
  // 0.5 degrees.
  bool refine_pose = true;
  double refine_reprojection_px = 1.5;
  double refine_max_shift_px = 30.0;
  int refine_min_inliers = 20;
  int refine_points_per_keyframe = 300;  // at most about this many per keyframe (evenly spread)

  // The keyframe check (ours, not in either paper): each current pixel's
  // surface P, back-projected with its depth and the current pose into each
  // reference keyframe, is
  //   static  when a keyframe's depth where P lands (nearest, or the least
  //           or greatest in a (2r+1)^2 window, r = confirm_search_radius_px)
  //           agrees within tau_d, and the keyframe's grey resampled through
  //           the current depth correlates with the current grey: zero-mean
  //           normalised cross-correlation at least confirm_min_zncc over the
  //           patch of radius confirm_patch_radius_px, counting only patch
  //           pixels on P's surface away from depth edges (fewer than a
  //           quarter of the patch, or a patch flatter than
  //           confirm_min_std_grey in both images: depth alone decides);
  //   moving  when, failing that, a keyframe saw through P's place (its
  //           whole window farther by more than tau_d) or saw other texture
  //           at P's depth (a surface sliding along itself, e.g. the side of
  //           a vehicle driving beside the camera, keeps its depth);
  //   unseen  otherwise (hidden or out of view in every keyframe).
  // A dynamic point at a static pixel is dropped, a vanished one (above)
  // needs a moving pixel, and region growing takes moving pixels only; both
  // count a moving pixel only inside a 3x3 block of them (an opening: a
  // real sensor's depth edges miss its colour edges by a pixel or two, which
  // leaves thin lines of "moving" along static silhouettes).
  // The keyframes' own dynamic masks are not used here: a wrong mask would
  // keep itself alive, each new keyframe inheriting it from the last.
  // Limitation: a moving surface without texture that keeps its depth over
  // the keyframes' span looks static.
  bool confirm_with_keyframes = true;
  // A keyframe point whose projection x' passes both depth tests (the
  // current surface at its own depth) but lands where the keyframe check
  // finds motion (moving_area above: other texture at that depth) is a
  // dynamic point and a seed as well (ours; false: only the depth tests
  // seed, as Algorithm 1). Needs confirm_with_keyframes. The vehicle of
  // `dynaorb synth --movers 3` drives beside the camera: where keyframes
  // come every frame or two, its ends move less than tau_d between them and
  // nothing on it seeds a region. Keypoint precision / recall of
  // [semantic, ddl] without the semantic union, seeds 0 / 1 / 2: 0.998 /
  // 0.903, 0.995 / 0.851, 0.999 / 0.830 without (vehicle 0.74 / 0.76 /
  // 0.57); 0.992 / 0.967, 0.974 / 0.945, 0.990 / 0.946 with (vehicle 0.96 /
  // 0.93 / 0.91); seeds 3-11 recall 0.69-0.94 -> 0.91-0.97, precision
  // 0.982-0.994 with.
  bool seed_sliding_surfaces = false;
  int confirm_search_radius_px = 1;
  // Correlation rather than grey differences: cameras change exposure
  // between keyframes. On `dynaorb synth` seed 0, keypoint precision /
  // recall: 0.8 -> 1.0 / 0.89, 0.9 -> 0.999 / 0.94, 0.95 -> 0.998 / 0.96
  // (a shifted smooth texture still correlates well). <= -1: no texture test.
  double confirm_min_zncc = 0.95;
  double confirm_min_std_grey = 3.0;  // grey levels (the synthetic image noise is 1.5)
  int confirm_patch_radius_px = 3;
  // Both images are compared after a Gaussian blur of this sigma (px; 0:
  // none): resampling a texture finer than the pixels (a floor at a grazing
  // angle) aliases differently in each view.
  double confirm_blur_sigma_px = 0.5;

  // Region growing on the current depth image (DynaSLAM Sec. III-C: "a region
  // growing algorithm" seeded at the dynamic points; no values in either
  // paper). A 4-neighbour joins when its inverse depth differs from the
  // pixel it is reached from by at most `grow_max_step_inv_depth` (1/m):
  // inverse depth is affine across a plane, so a surface seen at a grazing
  // angle grows, a depth edge (foreground against background) stops it.
  double grow_max_step_inv_depth = 0.01;
  // ... and when its depth is within `grow_max_from_seed_m` of the seed's
  // (metres; 0: no limit). DynaSLAM's code grows while the region's mean
  // depth stays within 0.20 m; ours defaults to no limit (a slanted side of
  // an object spans metres of depth) and relies on the keyframe check.
  double grow_max_from_seed_m = 0.0;
  // The dynamic region is widened by this many pixels (DDL-SLAM Fig. 1:
  // "delete ORB points in mask borders"; DynaSLAM's code dilates by 15 px).
  int dilation_px = 0;

  // Combine with the semantic mask (ctx.current.candidates) as DDL-SLAM
  // does: the union of both masks. false: only the geometric regions.
  bool combine_semantic = true;

  // Missing keys keep their defaults; keys are the member names.
  void read(const cv::FileNode& node);
  // InputError naming the first option out of range (a NaN, a negative radius,
  // a count or probability the estimators cannot use); read() and the stage call it.
  void validate() const;
};

namespace ddl {
struct KeyframeMaps;  // ddl_keyframes.h (internal)
}

class DdlStage : public Stage {
 public:
  explicit DdlStage(DdlOptions options = {}) : o_(std::move(options)) { o_.validate(); }

  std::string name() const override { return "ddl"; }
  bool supports(Sensor sensor) const override { return sensor == Sensor::kRGBD || sensor == Sensor::kStereo; }
  // The ego-motion (low-cost tracking on the static part, DDL-SLAM Fig. 2)
  // gives the current pose.
  bool needs_motion_cues() const override { return true; }
  // Pose of the current frame, best first: ctx.current.T_cw (already
  // tracked), the ego-motion composed with the previous frame's pose (the
  // paper's low-cost tracking on the static part: DM-SLAM's ego-motion from
  // the points outside the movable-class regions), SLAM's constant-velocity
  // prediction; then refined against the keyframes (refine_pose).
  //
  // report.values: pose_source (1 tracked, 2 ego-motion, 3 predicted),
  // pose_refined (refine_points, refine_inliers, refine_close,
  // refine_close_given_pose, pose_correction_m / _deg), keyframes_used,
  // projected, parallax_rejected, no_depth, dynamic (vanished of them: seen
  // behind; sliding: on a surface sliding along itself), static,
  // seen_static_rejected, vanished_rejected, tau_alpha_deg, tau_d_m, region_pixels, semantic_pixels, combined_pixels, and on
  // degenerate input one of skipped_no_depth, skipped_bad_input,
  // skipped_no_pose, skipped_no_keyframes. Wall time of its parts (ms):
  // refine_ms, check_ms (the projection test), grow_ms (region growing),
  // evidence_build_ms (the keyframe check's set-up, inside check_ms or
  // grow_ms).
  void process(Context& ctx, StageReport& report) override;
  // Forgets the prepared keyframe images.
  void reset() override;

  const DdlOptions& options() const { return o_; }

 private:
  // The prepared images of a keyframe's frame (from the cache; what it
  // lacks of the check images / the LK pyramid is made now).
  std::shared_ptr<const ddl::KeyframeMaps> keyframe_maps(const std::shared_ptr<const FrameData>& frame,
                                                         const std::vector<KeyFrameData>& keyframes, bool check,
                                                         bool pyramid);

  DdlOptions o_;
  // Rays of every current pixel, kept while the calibration and size stay.
  std::shared_ptr<const map::Calibration> rays_calib_;
  cv::Size rays_size_;
  std::vector<cv::Point2f> rays_;
  // The keyframe check's per-keyframe images and refine_pose's LK pyramid
  // (ddl::KeyframeMaps), prepared once per keyframe: a keyframe stays a
  // reference for many frames. Holds the keyframes' frames, so an entry's
  // address is never another frame's; entries of frames no longer among the
  // keyframes are dropped.
  std::vector<std::pair<std::shared_ptr<const FrameData>, std::shared_ptr<ddl::KeyframeMaps>>> keyframe_maps_;
};

// Region growing from `seeds` over `depth` (CV_32FC1 metres) with the
// options' depth rules; `blocked(x, y)`, when given, keeps a pixel out.
// Returns CV_8UC1 255 on the grown pixels (before dilation). Seeds without
// depth grow nothing.
cv::Mat ddl_grow_regions(const cv::Mat& depth, const std::vector<cv::Point>& seeds, const DdlOptions& o,
                         const std::function<bool(int, int)>& blocked = {});

}  // namespace dynaorb::dynamic
