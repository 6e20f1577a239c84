#pragma once
// The public API of dynaorb: one System per camera, fed frame by frame.
// ROS nodes, the pybind11 module and the dataset runners are thin adapters
// over this class. Thread-compatible: one caller thread feeds a System.
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "dynaorb/core/pose.h"
#include "dynaorb/core/sensor.h"
#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/io/settings.h"
#include "dynaorb/loop/loop_closer.h"
#include "dynaorb/mapping/local_mapper.h"
#include "dynaorb/place/keyframe_database.h"
#include "dynaorb/tracking/tracker.h"
#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb {

enum class TrackingState {
  kNoImagesYet,     // nothing fed yet
  kNotInitialized,  // frames accepted, no map yet
  kOk,              // pose estimated for this frame
  kLost,            // pose could not be estimated for this frame
};
std::string to_string(TrackingState state);

// Why a frame was refused before it reached tracking.
enum class RejectReason { kNone, kEmptyImage, kWrongSize, kWrongType, kStampNotIncreasing };
std::string to_string(RejectReason reason);

struct TrackResult {
  TrackingState state = TrackingState::kNoImagesYet;
  RejectReason rejected = RejectReason::kNone;
  std::optional<Pose> pose;                  // T_world_camera when state == kOk
  std::string message;                       // human-readable detail for rejections
  // Per-stage wall time: this frame's (preprocess, extract, stereo_matching,
  // tracking, and relocalization, part of tracking, when it was tried) and
  // those of the keyframes local mapping finished meanwhile
  // (local_mapping, triangulation, fuse, local_ba, keyframe_culling).
  std::map<std::string, double> stage_ms;
  int invalid_depth_pixels = 0;              // NaN / zero / negative depth (RGB-D)
  bool mask_used = false;                    // a valid mask came with the frame
  int keypoints = 0;                         // ORB keypoints extracted (outside the mask)
  int tracked_points = 0;                    // map points matched and inliers
  bool new_keyframe = false;
  std::string method;                        // init / motion_model / reference_keyframe /
                                             // relocalization / lost
  // The map the frame's pose is in: 0 for the first, one more each time a
  // lost map was given up (TrackerOptions::new_map_after_lost_s); poses of
  // different maps are in different worlds (for monocular, scales).
  int map = 0;
  bool map_dropped = false;                  // this frame gave up the lost map
  // The dynamic-object front end (SystemOptions::dynamic), when on. Its
  // times are in stage_ms: "dynamic" (the whole filter), "dynamic.<stage>"
  // and "dynamic.motion_cues".
  bool labels_used = false;                  // a valid label image came with the frame
  // Keypoints the filter's mask kept out of tracking: those an extraction
  // without the mask would have kept inside it (features::ExcludedCount).
  int dynamic_keypoints = 0;
  double dynamic_fraction = 0;               // share of the image the filter marked dynamic
  // The stages' reports: "<stage>.dynamic_points", "<stage>.static_points",
  // "<stage>.regions" and "<stage>.<value>" for each of its values; plus
  // "motion_cues.tracked_points", "motion_cues.ego_inliers", "motion_cues.ego_valid".
  std::map<std::string, double> dynamic_values;
};

// The last frame for a dense map (ROS cloud, OctoMap): colour, depth and the
// dynamic mask in the tracked image's pixels (the rectified left image for
// stereo), with that camera's intrinsics and pose.
struct DenseFrame {
  double stamp = 0;
  cv::Mat colour;    // CV_8UC3 BGR; the grey image as BGR when the input was grey
  // CV_32FC1 metres, 0 = none: RGB-D depth; for stereo, a stage's disparity
  // depth or else semi-global block matching (Dynamic.inpainting.stereo_*).
  cv::Mat depth;
  cv::Mat dynamic;   // CV_8UC1 255 = dynamic; zeros when the filter is off
  // The movable-class regions of the labels (CV_8UC1 255), empty without
  // labels; and whether the filter had a previous frame to check them for
  // motion. Unchecked (the first frame, the first after a reset), the
  // regions it did not mark are unverified, not known to be static.
  cv::Mat candidates;
  bool motion_checked = false;
  // The camera of these pixels in the world of trajectory(); empty when the
  // frame was not tracked. For rectified stereo: the rectified left camera.
  std::optional<Pose> T_wc;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  cv::Mat dist;      // distortion of these pixels (empty: none)
  bool inpainted = false;   // dynamic pixels filled from the remembered keyframes
  int inpainted_pixels = 0; // dynamic pixels that got a background colour
};

struct SystemOptions {
  // true: each keyframe is fully mapped (local BA included) before the next
  // frame is tracked; runs are then repeatable. false: local mapping runs
  // concurrently, as on a live camera.
  bool synchronous_mapping = false;
  tracking::TrackerOptions tracker;        // max_frames defaults to Camera.fps
  mapping::LocalMapperOptions mapping;
  // A bag-of-words vocabulary (e.g. ORB-SLAM2's ORBvoc.txt, or one trained
  // with Vocabulary::train): keyframes get bags of words and a keyframe
  // database, reference-keyframe matching goes through the vocabulary, and
  // lost frames are relocalised. Null: none of this (brute-force matching,
  // no relocalisation). Shared read-only; may serve several Systems.
  std::shared_ptr<const vocab::Vocabulary> vocabulary;
  place::KeyFrameDatabaseOptions database;
  // Loop closing (ORB-SLAM Sec. VI, dynaorb/loop/loop_closer.h) in its own
  // thread; needs the vocabulary (without one it is off whatever this says).
  // With synchronous_mapping, a keyframe's loop step and a global BA it
  // starts finish before the next frame is tracked (repeatable runs).
  bool loop_closing = true;
  loop::LoopCloserOptions loop;
  // Localisation only from the start (see System::set_localization_mode).
  bool localization_only = false;
  // The dynamic-object front end (dynamic/dynamic_filter.h): stages run on
  // every frame before ORB extraction and no keypoint is extracted in the
  // regions they mark. No stage for the sensor (the default): off, and the
  // System behaves as without it. A stage the sensor cannot run: InputError.
  dynamic::DynamicFilterOptions dynamic;
};

// The tracked frames of one map (TrackResult::map), in their own world.
struct TrajectorySegment {
  int map = 0;
  Trajectory poses;
};

struct MapSummary {
  long keyframes = 0;
  long points = 0;
  mapping::LocalMapperCounters mapping;
  loop::LoopCloserCounters loop;  // zero without loop closing
};

struct SystemCounters {
  long frames = 0;          // frames offered
  long rejected = 0;        // frames refused (see rejected_by_reason)
  long tracked = 0;         // frames with state kOk
  long masks_dropped = 0;   // masks ignored because of a wrong size or type
  long labels_dropped = 0;  // label images ignored because of a wrong size or type
  long dynamic_all_frames = 0;      // frames the filter marked (nearly) all dynamic
  long dynamic_stage_failures = 0;  // stage runs that threw (their regions dropped)
  long unchecked_kept = 0;   // first frames whose unchecked candidates were kept to start the map
  long lost = 0;            // frames with state kLost
  long initializations = 0; // map (re)initialisations
  long maps_dropped = 0;    // lost maps given up for a new one (TrackerOptions)
  long relocalizations = 0; // lost frames found again in the map (needs a vocabulary)
  long loops_closed = 0;    // loops detected and corrected (needs loop closing)
  long global_ba_runs = 0;  // global bundle adjustments finished after a loop
  std::map<std::string, long> rejected_by_reason;
};

class System {
 public:
  // Validates the settings for the sensor (throws InputError naming the key).
  System(const Settings& settings, Sensor sensor, const SystemOptions& options = {});
  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  // Images as stored by the camera (8-bit grey, BGR, or RGB when Camera.RGB=1
  // and the image came from a ROS topic); depth 16UC1 (scaled by
  // DepthMapFactor) or 32FC1 metres. `mask` (optional): 8-bit, same size as
  // the image, non-zero marks pixels whose keypoints stay out of tracking and
  // mapping (a label image is accepted: any non-zero label is "masked" unless
  // the dynamic front end decides otherwise). `labels` (optional): the
  // segmentation network's class ids for the dynamic filter (CV_8UC1, or
  // CV_16UC1 with ids above 255 saturated to 255), same size as the image;
  // ignored when the filter is off, counted and dropped when of a wrong size or type.
  TrackResult track_mono(const cv::Mat& image, double stamp, const cv::Mat& mask = cv::Mat(),
                         const cv::Mat& labels = cv::Mat());
  TrackResult track_stereo(const cv::Mat& left, const cv::Mat& right, double stamp,
                           const cv::Mat& mask = cv::Mat(), const cv::Mat& labels = cv::Mat());
  TrackResult track_rgbd(const cv::Mat& image, const cv::Mat& depth, double stamp,
                         const cv::Mat& mask = cv::Mat(), const cv::Mat& labels = cv::Mat());

  Sensor sensor() const;
  const Settings& settings() const;
  const SystemCounters& counters() const;
  // Poses of tracked frames, in order, through their reference keyframes'
  // current (bundle-adjusted) poses. Camera frame: the input camera (for
  // rectified stereo the unrectified left camera); world: its first pose.
  // When a lost map was given up (TrackResult::map), the map with the most
  // tracked frames, the latest of equals (ORB-SLAM3 saves its largest map).
  // Frames still waiting for their refinement (TrackerOptions::
  // refine_lag_keyframes) are solved against the map as it is now, each
  // call: about a millisecond each, a few dozen of them in a moving camera's
  // run (at most refine_max_pending), so not a call for every frame.
  Trajectory trajectory() const;
  // Every map's poses, in the order of the maps; one segment without a new map.
  std::vector<TrajectorySegment> trajectory_segments() const;
  std::vector<Eigen::Vector3d> map_points() const;  // world coordinates
  MapSummary map_summary() const;
  // Waits until local mapping has mapped every keyframe queued and loop
  // closing has finished (with any global BA it started), so that
  // trajectory(), map_points() and save_map() are final for the frames so
  // far: what a caller does after its last frame (ORB-SLAM2's Shutdown waits
  // for the global BA likewise). Returns at once with synchronous mapping
  // or before the first frame. Between frames.
  void wait_for_mapping();
  // Drops the map, the keyframe database and the trajectory; the next frame starts a new map.
  void reset();

  // Map files (map/map_io.h), between frames. save_map writes the current
  // map (InputError when it cannot). load_map replaces the map with the
  // file's and puts tracking into LOST, so that the next frame is relocalised
  // in it; it needs a vocabulary, and the file's sensor and calibration must
  // be this system's (InputError naming the file otherwise, the map kept).
  // Loop closing starts afresh on the loaded map: the file holds no loop
  // edges, and the old map's are dropped (also when the file is refused).
  void save_map(const std::string& path);
  void load_map(const std::string& path);
  // The dynamic filter's mask of the last frame, in the input image's pixels
  // (un-rectified for stereo); empty when the filter is off or before a frame.
  cv::Mat last_dynamic_mask() const;
  // The last frame for a dense map; inpaint: its dynamic pixels filled with
  // the background seen by the remembered keyframes (DDL-SLAM Sec. III-E).
  // Stereo depth is computed here (semi-global block matching, once per
  // frame and remembered keyframe), not in the tracking thread. Empty colour
  // before a frame was processed. Not to be called concurrently with track_*.
  DenseFrame dense_frame(bool inpaint = false) const;
  bool dynamic_filter_enabled() const;
  // The dynamic filter's movable label ids (its semantic stage's; empty
  // without one), and their replacement by a label source's own set (a
  // segmentation server announcing it after start-up; not during a track_* call).
  std::vector<int> movable_classes() const;
  void set_movable_classes(const std::vector<int>& ids);

  // Localisation only (ORB-SLAM2): tracking in the map, no new keyframes or points.
  void set_localization_mode(bool on);
  bool localization_mode() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dynaorb
