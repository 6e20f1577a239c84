#pragma once
// The motion cues the dynamic stages share, computed once per frame by the
// filter: corners tracked from the previous into the current image
// (TrackedPoint) and the camera's ego-motion estimated from the points
// outside the movable-class regions (EgoMotion). Both are in stage.h.
#include <future>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/core/helper_thread.h"
#include "dynaorb/core/sensor.h"
#include "dynaorb/dynamic/stage.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic {

struct MotionCueOptions {
  // Which corners are tracked: "harris" (below, the papers' codes) or
  // "fast": ORB's own FAST corners (cv::FAST with non-maximum suppression,
  // ORB-SLAM's iniThFAST as fast_threshold; inside the candidates
  // candidate_fast_threshold, its minThFAST, when lower), the strongest first
  // at least min_distance apart, at most max_corners of each detection. DM-SLAM
  // (Sec. 3.2.3-3.2.4) judges the frame's ORB feature points; FAST finds the
  // same kind of point for a fraction of the Harris response's and the
  // sub-pixel refinement's cost (set subpix_window 0 with it: FAST corners
  // are pixel positions).
  std::string detector = "harris";
  int fast_threshold = 20;
  int candidate_fast_threshold = 7;
  // Corners: the goodFeaturesToTrack call of DS-SLAM's released code
  // (Frame::ProcessMovingObject: 1000 corners, quality 0.01, distance 8,
  // block 3, Harris with k = 0.04), the corner detector STDyn-SLAM Sec. III-A
  // names ("a Harris detector") without giving values.
  int max_corners = 1000;
  double quality_level = 0.01;
  double min_distance = 8;  // px
  int block_size = 3;
  bool use_harris = true;
  double harris_k = 0.04;
  // Ours: at most this many corners outside the frame's movable-class
  // candidates (after the semantic stage); those inside are all kept. The
  // corners outside only feed global estimates (the ego-motion's PnP and F,
  // STDyn's F, DM-SLAM's static offsets), which a spatially even subset
  // serves; every one of them costs its sub-pixel refinement and its LK
  // tracks. Chosen evenly over the image: a grid of about this many cells,
  // the strongest corner of each cell first. 0: all (the papers' codes).
  int max_background_corners = 0;
  // Ours: the same for the corners inside the candidates, spread over the
  // candidates' bounding box. Every one of them is judged (DM-SLAM's
  // offsets, STDyn's epipolar distances) and votes for its object, which
  // needs a few points per object, not hundreds. 0: all.
  int max_candidate_corners = 0;
  // Ours: inside the candidates, corners down to this quality relative to
  // the strongest corner inside them (a second goodFeaturesToTrack over the
  // candidates only), instead of quality_level relative to the whole image's
  // strongest. A low-contrast mover in a scene with a strong corner elsewhere
  // (a checkerboard) otherwise gets no corners, so no point of it is judged
  // and it is never found moving. Used when 0 < value < quality_level;
  // <= 0 (the default, the papers' codes): one detection over the image;
  // a value >= quality_level is refused (validate).
  double candidate_quality_level = -1;
  // Sub-pixel corner refinement: cornerSubPix half-window of DS-SLAM's code
  // (Size(10, 10)); 0 turns it off.
  int subpix_window = 10;  // px
  // Pyramidal Lucas-Kanade: DM-SLAM Sec. 3.2.4 uses LK [41] without values;
  // these are DS-SLAM's code (calcOpticalFlowPyrLK window 22x22, 5 pyramid
  // levels above the image). With 3 levels a person 2 m away moving 12 cm
  // between frames loses over 90 % of its tracks (measured on rendered views).
  int lk_window = 22;  // px, square
  int lk_levels = 5;
  // Per-level stop of each LK track. DS-SLAM's code stops at 20 iterations
  // (TermCriteria(COUNT | EPS, 20, 0.01)); ours allows 30: with 20, three of
  // 60 masks changed on the synthetic stereo sequence (3 movers, seed 0) and
  // `full`'s ATE went from 0.0034 to 0.0042 m.
  int lk_max_iterations = 30;
  double lk_epsilon = 0.01;  // px
  // Ours: a track is kept only when tracking the current point back lands
  // within this many pixels of where it started (rejects occlusions and drift).
  // <= 0: no backward tracking (DS-SLAM's code has none), half the LK cost.
  double forward_backward_max = 1.0;  // px
  // The same check for a corner's stereo match (LK along the row into the
  // right image, stereo_depths): ours, kept apart from the flow's, so the
  // flow can go without it while the depths keep it. <= 0: none.
  double stereo_depth_forward_backward_max = 1.0;  // px
  // STDyn-SLAM Sec. III-A: "the Harris points pair is discarded if at least one
  // of the points is on the edge corner or close to it" (no value in the paper;
  // 10 px is ours).
  int border = 10;  // px
  // Ours: a depth-image corner whose depth varies by more than this ratio
  // within depth_edge_radius px lies on a depth edge (a silhouette): it gets
  // no depth. On rendered RGB-D sequences these corners were the static
  // points with the largest reprojection offsets. 0 turns the check off.
  int depth_edge_radius = 2;          // px
  double depth_edge_max_ratio = 0.1;  // of the corner's depth
  // Ego-motion RANSAC (ours; DM-SLAM's ego-motion reuses DynaSLAM's light
  // tracking with ORB-SLAM2's thresholds, which work on map points instead).
  double ransac_reprojection_px = 2.0;  // PnP reprojection / F epipolar distance, px
  double ransac_confidence = 0.99;
  int ransac_iterations = 200;
  int min_ego_points = 12;  // fewer usable points (or inliers): no estimate

  // Missing keys keep their defaults; keys are the member names.
  void read(const cv::FileNode& node);
  // InputError naming the first option out of its range (a NaN, a count
  // below 1, a ratio outside (0, 1), a candidate quality level at or above
  // quality_level, ...); DynamicFilterOptions::parse (at load) and validate call it.
  void validate() const;
};

// The corners of an image detected ahead, on another thread, and for a
// rectified stereo pair the depth of each from LK into the right image (0:
// none; empty when not computed there).
struct AheadCorners {
  std::vector<cv::Point2f> corners;
  std::vector<float> right_depth;
  // Their own wall time (ms) on the worker thread: the detection with its
  // sub-pixel refinement, and the LK into the right image (stereo).
  double corners_ms = 0;
  double stereo_ms = 0;
};

// What track_points keeps from one call to the next, for one set of
// options: the current image's LK pyramid, which is the next call's previous
// image's (same result as building it from the image again), and the
// corners of the next previous image, detected ahead on another thread
// (detect_corners_ahead). Also the time of its parts.
struct MotionCueCache {
  // The worker the corners ahead are detected on: started off the calling
  // thread's CPU (helper_thread.h). Interleaved runs, the synthetic
  // sequences with movers, `full`, asynchronous mapping, against a std::async
  // thread per frame (track call, median of the runs' medians): stereo 29.0
  // -> 27.3 ms (10 + 10 runs), mono 18.2 -> 17.1 ms (12 + 12), RGB-D 21.0 ->
  // 20.1 ms (8 + 8); the same corners (synchronous runs: identical
  // trajectories). Owned through a pointer so that the cache stays movable:
  // `cache = MotionCueCache()` starts afresh (the old worker finishes its job
  // in flight, then ends).
  std::unique_ptr<HelperThread> ahead = std::make_unique<HelperThread>();
  cv::Mat image;  // holds the buffer: no other image can have its address while cached
  std::vector<cv::Mat> pyramid;
  int window = 0, levels = -1;
  // Corners detected ahead (detect_corners_ahead): those of the image the
  // next track_points call starts from (corners_image, held likewise) and
  // those started after them; when detect_corners_ahead runs after the
  // frame's track_points, the next call's are the latter.
  cv::Mat corners_image, next_corners_image;
  std::shared_future<AheadCorners> corners, next_corners;
  // Wall time (ms) of the last call's parts: corners (detection and
  // sub-pixel refinement, or the wait for them when detected ahead),
  // pyramids, flow (LK forward-backward), stereo (LK into the right image;
  // absent when not run in the call: not needed, or done ahead with the
  // corners). Corners detected ahead add what they took on the worker
  // thread, beside the frame before: corners_ahead, and stereo_ahead when
  // their depths came with them (not part of the call's time, but a core's).
  std::map<std::string, double> ms;
};

// The corners track_points tracks from an image: goodFeaturesToTrack's
// (harris_corners with use_harris; or FAST, MotionCueOptions::detector) inside the border (inside `candidates`
// a detection of their own when candidate_quality_level, or
// candidate_fast_threshold, is set below the image's), at most max_background_corners of them outside
// `candidates` (CV_8UC1 of the image's size; else all count as outside) and
// max_candidate_corners inside,
// cornerSubPix, near-duplicates removed. May throw cv::Exception on options
// OpenCV refuses.
std::vector<cv::Point2f> detect_corners(const cv::Mat& grey, const MotionCueOptions& o,
                                        const cv::Mat& candidates = cv::Mat());

// Depth (calib.bf / disparity) of each of `points` of a rectified left
// image by LK into the right one and back (stereo_depth_forward_backward_max;
// pyramids of the same window and levels); 0 where the match fails, leaves
// the row by more than 1 px or has no positive disparity.
std::vector<float> stereo_depths(const std::vector<cv::Mat>& left_pyramid, const std::vector<cv::Mat>& right_pyramid,
                                 const std::vector<cv::Point2f>& points, double bf, const MotionCueOptions& o);

// Starts detect_corners(frame.grey, o, frame.candidates) on another thread,
// for the track_points call whose previous frame is `frame` (the next
// frame's): the detection depends on that frame alone, so it overlaps the
// rest of this frame's work. For stereo without a depth image (frame.right
// set, calib.bf > 0) it also finds the corners' depth in frame.right, which
// track_points would otherwise compute on the calling thread, from the LK
// pyramid of frame.grey the cache holds when that frame's own track_points
// call came first (else built there). Same corners
// and depths as computing them then (LK tracks each point on its own). Call
// it once per frame, before or after that frame's track_points: the corners
// started at the last call move to the current slot, those started now take
// the next one, and track_points reads the slot that holds its previous
// image's.
void detect_corners_ahead(const FrameData& frame, const map::Calibration& calib, Sensor sensor,
                          const MotionCueOptions& o, MotionCueCache& cache);

// Harris corners on prev.grey (detect_corners with prev.candidates), followed
// by pyramidal LK into cur.grey with a forward-backward check
// (forward_backward_max); pairs with either end within `border` of the
// image edge are rejected. prev_depth comes from prev.depth (CV_32FC1 metres)
// when set; else, for stereo, from LK of the corner along the rectified row
// into prev.right (|dy| <= 1 px, disparity > 0, depth = calib.bf /
// disparity); else 0. Depth-image corners on a depth edge get 0 (depth_edge_*
// options). in_candidate: inside prev.candidates at prev or cur.candidates at
// cur (either may be empty). Pixels are raw (possibly distorted) image
// pixels. Degenerate input (empty or mismatched images) gives no points.
// cache (optional): reuses the previous call's current-image pyramid when
// prev.grey is that image, and keeps cur.grey's for the next call; takes
// prev.grey's corners (and depths) from the cache when they were detected
// ahead.
std::vector<TrackedPoint> track_points(const FrameData& prev, const FrameData& cur,
                                       const map::Calibration& calib, Sensor sensor,
                                       const MotionCueOptions& o, MotionCueCache* cache = nullptr);

// Ego-motion from the points with in_candidate == false only (DM-SLAM Sec.
// 3.2.3): stereo / RGB-D: solvePnPRansac (EPnP) on the undistorted points with
// their previous depth, refined by Levenberg-Marquardt on its inliers, then
// inliers recounted (in front of the camera, within ransac_reprojection_px)
// -> T_cur_prev; monocular, and the other sensors when with_F: F by RANSAC
// (OpenCV's USAC_ACCURATE) on the undistorted pixels (q^T F p = 0, p
// previous, q current; has_F false when not estimated). valid: the sensor's
// estimate (T_cur_prev for stereo / RGB-D, F for monocular) is usable;
// inlier/inliers count the inliers of that estimate. Never throws: too few
// points or a RANSAC failure give valid = false.
EgoMotion estimate_ego_motion(const std::vector<TrackedPoint>& points, const map::Calibration& calib,
                              Sensor sensor, const MotionCueOptions& o, bool with_F = true);

}  // namespace dynaorb::dynamic
