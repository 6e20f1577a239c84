#pragma once
// Background inpainting for the dense map (DDL-SLAM Sec. III-E, after
// DynaSLAM Sec. III-E): the pixels of the current frame's dynamic mask are
// filled with the static background the previous keyframes saw there. Each
// keyframe's static pixels (outside its own dynamic mask) with depth are
// warped into the current view with the keyframes' and the current poses;
// a z-buffer keeps the nearest surface, newer keyframes win ties. The
// inpainted colour (or grey) and depth images feed the dense cloud / octree
// map, never tracking.
//
// What no keyframe saw stays empty: colour / grey 0 and depth 0 (DDL-SLAM
// Sec. III-E: such blocks "cannot be rebuilt just with geometric
// approaches"); no texture is invented.
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/dynamic/stage.h"
#include "dynaorb/dynamic/stereo_depth.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic {

struct InpaintOptions {
  // DDL-SLAM Sec. III-E: "the last 15 previous keyframes are selected to
  // project into the dynamic parts of the current frame" (DynaSLAM: 20).
  int keyframes = 15;
  // Two warped samples within this depth of each other are the same surface
  // (z-buffer ties: the newer keyframe keeps the pixel), and a keyframe
  // pixel counts as seeing the warped surface when its own depth is within
  // it (metres). Neither paper gives a value; DynaSLAM's code uses 0.2 m
  // (MIN_DEPTH_THRESHOLD). The tolerance grows with depth as
  // max(depth_tolerance_m, depth_tolerance_ratio * z) (ours: depth noise of
  // structured-light and stereo sensors grows with depth).
  double depth_tolerance_m = 0.2;
  double depth_tolerance_ratio = 0.03;
  // Keyframe depths beyond this are not warped (metres; 0: no limit).
  // DynaSLAM's code keeps depths below 7 m (the Kinect's range).
  double max_depth_m = 0.0;
  // The keyframe's dynamic mask is widened by this many pixels before its
  // pixels are used (ours: colour at an object's silhouette often belongs to
  // the object while the mask stops a pixel short).
  int keyframe_mask_margin_px = 2;
  // Ours: where the current frame has depth, a fill must lie behind the
  // surface it replaces by more than the tolerance (the background is hidden
  // by the moving object, so it is farther). This rejects parts of a moving
  // object that a keyframe's mask missed, which otherwise "fill" the object
  // with itself. A static pixel wrongly marked dynamic then stays empty.
  bool background_behind_object = true;
  // Stereo has no depth of its own: System::dense_frame(true) computes it
  // (current frame and remembered keyframes, each once) by semi-global
  // block matching with these options. Keys: stereo_num_disparities,
  // stereo_block_size, stereo_uniqueness_ratio, stereo_speckle_window,
  // stereo_speckle_range, stereo_disp12_max_diff, stereo_three_way.
  StereoDepthOptions stereo;

  // Missing keys keep their defaults; keys are the member names.
  void read(const cv::FileNode& node);
};

struct InpaintResult {
  cv::Mat colour;  // CV_8UC3 BGR when the current frame has colour, else empty
  cv::Mat grey;    // CV_8UC1 (from the current grey image)
  cv::Mat depth;   // CV_32FC1 metres (the current depth, or zeros without one)
  cv::Mat filled;  // CV_8UC1 255 on the dynamic pixels that were filled
  int target_pixels = 0;   // dynamic pixels of the current frame
  int filled_pixels = 0;
  double filled_fraction = 0;  // filled / target (0 when there is no target)
  int keyframes_used = 0;
  // Counters and why nothing was done: skipped_bad_input, skipped_no_pose,
  // skipped_no_keyframes, nothing_to_fill; keyframes_without_pose_or_depth.
  std::map<std::string, double> values;
};

// Fills current.dynamic (CV_8UC1, 255 = dynamic) in copies of current.colour
// / current.grey / current.depth from the last `o.keyframes` keyframes of
// `keyframes` (newest last) that have a pose, a depth image and an image.
// Needs current.T_cw. Never throws: degenerate input leaves every dynamic
// pixel empty and says why in values.
InpaintResult inpaint_background(const FrameData& current, const std::vector<KeyFrameData>& keyframes,
                                 const map::Calibration& calib, const InpaintOptions& o = {});

}  // namespace dynaorb::dynamic
