#pragma once
// The dynamic-object front end: one interface for the four papers' detectors.
//
// A DynamicFilter (dynamic_filter.h) runs its stages in a configured order on
// each frame, before ORB extraction. Every stage reads the current and the
// previous frame (images, depth, semantic labels), the recent keyframes the
// filter remembers, the ego-motion estimate and what earlier stages decided,
// and marks dynamic regions (pixels) and dynamic points. The union of the
// regions becomes the extraction exclusion mask: no ORB feature is extracted
// inside it, so moving things stay out of tracking and out of the map.
//
// Images are in the tracked image's pixels: the rectified left image for
// stereo, the raw (possibly distorted) image for monocular and RGB-D;
// `calib` says which (K, dist). Geometry on pixel coordinates must undistort
// them first (cv::undistortPoints with calib.K / calib.dist) when dist is set.
#include <Eigen/Geometry>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "dynaorb/core/sensor.h"
#include "dynaorb/dynamic/candidate_regions.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic {

// One frame as the filter sees and remembers it.
struct FrameData {
  long id = -1;
  double stamp = 0;
  cv::Mat grey;    // CV_8UC1, the tracked image
  cv::Mat colour;  // CV_8UC3 BGR when the input had colour (for inpainting), else empty
  cv::Mat right;   // CV_8UC1 rectified right image (stereo), else empty
  cv::Mat depth;   // CV_32FC1 metres, 0 = none (RGB-D: the sensor's depth; stereo: filled
                   //   by a stage that computes disparity, e.g. Li's SGBM), else empty
  cv::Mat labels;  // CV_8UC1 semantic class ids (0 = background) or empty: no network
  // Movable-class regions from the labels (CV_8UC1 255 = a movable class,
  // widened by the configured edge margin), empty without labels. Set by the
  // semantic stage; later stages (and the next frame) read it.
  cv::Mat candidates;
  // T_camera_world from SLAM once the frame is tracked (empty before, or when lost).
  std::optional<Eigen::Isometry3d> T_cw;
  cv::Mat dynamic;  // CV_8UC1 final dynamic mask of this frame (255 = dynamic), set by the filter
  // Set by the filter: a previous frame was there to judge motion against.
  // When false (the first frame, the first after a reset) the geometric
  // stages could not check the movable-class regions, so what they left
  // unmarked is unverified rather than static.
  bool motion_checked = false;
};

// A point followed from the previous frame into the current one: shared
// motion cues, computed once per frame by the filter (dynamic/motion_cues.h)
// for the stages that need them: Harris corners on the previous image,
// pyramidal Lucas-Kanade into the current image with a forward-backward check.
struct TrackedPoint {
  cv::Point2f prev;     // pixel in the previous image
  cv::Point2f cur;      // pixel in the current image
  float prev_depth = 0; // metres in the previous frame (RGB-D depth, stereo disparity), 0 = none
  bool in_candidate = false;  // inside a potentially dynamic (movable-class) region of either frame
};

// Camera motion from the previous to the current frame estimated from the
// points outside the candidate regions only (DM-SLAM's "ego-motion
// estimation": light tracking, no map): PnP RANSAC on points with depth
// (stereo, RGB-D) or the fundamental matrix (monocular).
struct EgoMotion {
  bool valid = false;
  Eigen::Isometry3d T_cur_prev = Eigen::Isometry3d::Identity();  // (stereo, RGB-D)
  cv::Matx33d F;              // fundamental matrix prev -> cur, undistorted pixels (see has_F)
  bool has_F = false;         // monocular; stereo / RGB-D only when asked for (estimate_ego_motion)
  int inliers = 0;
  std::vector<unsigned char> inlier;  // per TrackedPoint (1: used and inlier)
};

// A keyframe the filter remembers (the last few, for DDL-SLAM's multi-view
// check and background inpainting): its frame (images, depth, pose, mask) and
// its keypoints with depth, as SLAM made it.
struct KeyFrameData {
  std::shared_ptr<const FrameData> frame;
  std::vector<cv::Point2f> keypoints;  // pixels in the tracked image
  std::vector<float> depth;            // metres, 0 = none
};

// Everything a stage may read for the current frame.
struct Context {
  Sensor sensor = Sensor::kStereo;
  std::shared_ptr<const map::Calibration> calib;
  FrameData& current;                         // stages may fill current.depth (stereo disparity)
                                              //   and current.candidates (semantic stage)
  std::shared_ptr<const FrameData> previous;  // null on the first frame (or after a reset)
  // Regions decided dynamic so far (CV_8UC1 255): each stage ORs its own in.
  cv::Mat dynamic;
  // Shared motion cues (filled on demand by the filter before the first stage that asks).
  const std::vector<TrackedPoint>* tracked = nullptr;
  const EgoMotion* ego = nullptr;
  // T_cw of the current frame predicted by SLAM's constant-velocity model
  // (empty before two tracked frames).
  std::optional<Eigen::Isometry3d> T_cw_predicted;
  const std::vector<KeyFrameData>* keyframes = nullptr;  // newest last
  // The candidate regions of this frame (candidate_regions.h), cut once for
  // the stages that ask with the same inputs.
  RegionsMemo regions;
};

// What one stage reports for one frame (stats.json, tests).
struct StageReport {
  std::vector<cv::Point2f> dynamic_points;  // the points it judged dynamic
  std::vector<cv::Point2f> static_points;   // the points it judged static
  int regions = 0;                          // regions (objects, ROIs, superpixels) marked dynamic
  std::map<std::string, double> values;     // stage-specific numbers (thresholds, ratios, counts)
};

class Stage {
 public:
  virtual ~Stage() = default;
  virtual std::string name() const = 0;
  // Which sensors the stage supports (the filter refuses a preset that puts a
  // stage on a sensor it cannot run on, naming both).
  virtual bool supports(Sensor sensor) const = 0;
  // Whether the filter must compute TrackedPoint / EgoMotion for it.
  virtual bool needs_motion_cues() const { return false; }
  // Whether it needs them on this frame, given what the earlier stages left
  // in ctx (e.g. no candidate regions: nothing for it to judge). The filter
  // computes the cues before the first stage that says so; a stage that
  // says no must not read ctx.tracked / ctx.ego. Default: needs_motion_cues().
  virtual bool needs_motion_cues_for(const Context& ctx) const { return needs_motion_cues(); }
  // The candidate regions (ctx.regions.get's arguments) it will ask for on
  // this frame, when it can tell before the motion cues are computed (the
  // earlier stages have run): the filter cuts them on its worker thread while
  // it computes the cues, and the stage finds them in ctx.regions. Asked of
  // the stages that use the cues, from the first that needs them on this
  // frame on, right before they are computed. Default: none.
  virtual std::optional<RegionsRequest> regions_wanted(const Context& ctx) const { return std::nullopt; }
  // Runs on one frame: ORs dynamic regions into ctx.dynamic (may read and
  // write ctx.current.candidates), fills `report`. Must not throw on degenerate input
  // (no previous frame, no labels, too few points): it then marks nothing and
  // says why in report.values (e.g. "skipped_no_previous" = 1).
  virtual void process(Context& ctx, StageReport& report) = 0;
  // Forgets the previous frames (a SLAM reset).
  virtual void reset() {}
};

}  // namespace dynaorb::dynamic
