#pragma once
// The dynamic-object front end as one object: the configured stages run in
// order on every frame before ORB extraction (stage.h). The filter owns what
// the stages share: the previous frame, the last keyframes and the motion
// cues (computed once per frame, when a stage asks for them).
//
// Preset file (OpenCV YAML, the ORB-SLAM2 settings style; config/dynamic/):
//   Dynamic.stages: [semantic, dm]            every sensor, in this order; or
//   Dynamic.stages: {rgbd: [semantic, dm, ddl], stereo: [semantic, dm, li], mono: [semantic, dm]}
//                                             per sensor (a sensor not listed is refused)
//   Dynamic.keyframes: 15                     keyframes remembered
//   Dynamic.all_dynamic_fraction: 0.95        see DynamicFilterOptions
//   Dynamic.motion_cues: {max_corners: 1000, ...}   MotionCueOptions
//   Dynamic.motion_cues.rgbd: {lk_window: 15}  that sensor's changes to them
//                                             (also .stereo, .mono)
//   Dynamic.inpainting: {depth_tolerance_m: 0.2, ...} InpaintOptions (System::dense_frame)
//   Dynamic.semantic: {classes: voc, margin: 15, policy: drop}
//   Dynamic.<stage>: {...}                    that stage's options (missing keys: defaults)
// `Dynamic.stages: []` turns the filter off. Other keys (Camera.* ...) are
// ignored, so a settings file may carry its preset.
#include <Eigen/Geometry>
#include <functional>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "dynaorb/core/sensor.h"
#include "dynaorb/dynamic/inpainting.h"
#include "dynaorb/dynamic/motion_cues.h"
#include "dynaorb/dynamic/stage.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic {

struct DynamicFilterOptions {
  std::string source;               // the preset file (messages); empty when built in code
  std::vector<std::string> stages;  // in order, for every sensor; empty: off
  std::map<Sensor, std::vector<std::string>> sensor_stages;  // replaces `stages` for that sensor
  // The file's nodes Dynamic.<stage> (each stage's options); null: defaults.
  std::shared_ptr<const cv::FileStorage> file;
  MotionCueOptions motion_cues;
  // Dynamic.motion_cues.<sensor>: motion_cues with that sensor's section read
  // over it (keys it leaves out keep motion_cues' values).
  std::map<Sensor, MotionCueOptions> sensor_motion_cues;
  InpaintOptions inpainting;  // background inpainting of System::dense_frame
  // DDL-SLAM Sec. III-D: the background is inpainted from "the last 15
  // previous keyframes"; the multi-view check reads them too.
  int keyframes = 15;
  // Ours: a frame whose dynamic mask covers at least this share of the image
  // counts as "all moving objects" (FilterResult::all_dynamic, counted by the System).
  double all_dynamic_fraction = 0.95;
  // Non-empty: the semantic stage's movable ids, whatever the preset says (the
  // label source knows its label set: labels.json, a model card).
  std::vector<int> movable_classes;
  // Ours: whether the System runs the filter on the tracking thread while a
  // worker thread detects the frame's ORB corners (OrbExtractor::detect; the
  // filter's mask only decides which of them are kept and described, so the
  // features are the same). 1: always; 0: never (the filter, then the
  // extraction); -1 (auto): for stereo always, for mono and RGB-D with at
  // least 4 hardware threads.
  // Stereo detects both images, level by level, on the FrameBuilder's helper
  // thread beside the filter; the tracking thread takes the levels left once
  // the filter is done, then the two threads share the levels' description
  // (HelperThread::share_async, tracking/frame_builder.h). Measured when the
  // helper detected the right image and then the left one unless the filter
  // ended first, and described the right image while the tracking thread
  // described the left: `full`, asynchronous mapping, 3 + 3
  // interleaved runs, track call medians without -> with: KITTI 06 with the
  // network (dm05) paced 20.64 -> 19.08 ms (with the labels' time 23.03 ->
  // 20.90), unpaced 23.23 -> 21.42 (26.04 -> 23.81); the synthetic stereo
  // sequence with movers (seed 0, label images) paced 16.07 -> 14.35,
  // unpaced 17.92 -> 15.76; EuRoC V1_01 (the filter 0.2 ms: nothing to
  // decide) 13.22 -> 12.32; every one of the 15 run pairs faster. The filter
  // itself takes 0.5-1.5 ms longer beside the detection, the extraction after
  // it 7.6 -> 5.7 ms (KITTI), 5.0 -> 2.4 (synthetic). Synchronous runs give
  // the same trajectories either way; paced, the ATE stays (KITTI 0.053-0.055
  // m, synthetic 3.0-3.1 mm); unpaced, where local mapping gets only the wall
  // time of the track calls, it rises with the faster tracking (KITTI
  // 0.037-0.046 -> 0.041-0.052 m, synthetic 3.1-3.8 -> 4.1-5.2 mm). (Stereo's
  // earlier overlap, both detections on a thread of their own, was slower:
  // KITTI paced 20.05 -> 22.8 ms.)
  // Mono and RGB-D on 2 cores: the second core is taken already, by the next
  // frame's motion-cue corners (MotionCueCache::ahead), local mapping and the
  // network; their detection runs on a thread of its own. There, `full` with
  // asynchronous mapping, overlapped against not (medians of interleaved
  // runs, track call): synthetic RGB-D with movers 19.4 against 18.6 ms
  // (8 + 8), without 13.8 against 13.0 (6 + 6); synthetic mono with movers
  // 16.0 against 15.9 (8 + 8), without 14.0 against 12.7 (6 + 6); EuRoC MH_05
  // mono with the network 15.4 against 14.2 (4 + 4); stereo (its own thread
  // then) 27.5 against 27.2 (5 + 5); the filter alone 12.2 -> 9.3 ms (RGB-D)
  // and 8.4 -> 6.3 ms (mono), as the detection no longer shares its core. Before the motion cues' worker (3
  // runs each) the overlap had gained 36.3 -> 33.0 ms (mono) and 38.0 ->
  // 34.4 ms (RGB-D). Paced as well (`--realtime`, the cores idle between
  // frames): synthetic mono with movers 10.3-12.5 ms overlapped against
  // 8.2-12.0 not (5 + 5 interleaved runs, ATE the same). Again at 25109d3,
  // with the extraction's levels shared with the FrameBuilder's helper:
  // that clip unpaced, 6 + 6 interleaved runs, track call 12.5-14.3 ms
  // overlapped (median 13.0; the filter 6.3-7.8) against 10.1-13.0 (12.0;
  // the filter 3.5-4.5). On 4 or more cores: not measured here.
  int overlap_extraction = -1;
  bool overlaps_extraction(unsigned hardware_threads, Sensor sensor) const;

  // Reads a preset file (the `%YAML:1.0` first line may be left out);
  // InputError naming the file and the key for a missing
  // Dynamic.stages, an unknown stage, an unknown Dynamic.* key, an unknown or
  // ill-typed option of a stage, or a stage listed for a sensor it does not support.
  static DynamicFilterOptions load(const std::string& path);
  // The same from YAML text (`source` names it in messages).
  static DynamicFilterOptions parse(const std::string& yaml, const std::string& source);

  const std::vector<std::string>& stages_for(Sensor sensor) const;
  const MotionCueOptions& motion_cues_for(Sensor sensor) const;
  bool enabled(Sensor sensor) const { return !stages_for(sensor).empty(); }
  // Dynamic.<stage> of the file, or an empty node.
  cv::FileNode stage_node(const std::string& stage) const;
  // Throws InputError (naming the source, the stage and the sensor) when a
  // stage of stages_for(sensor) is unknown or does not support the sensor, or
  // when the preset lists stages per sensor and not for this one.
  void validate(Sensor sensor) const;
};

// A stage from its options node (empty node: defaults). Throws InputError for bad options.
using StageFactory = std::function<std::unique_ptr<Stage>(const cv::FileNode& options)>;
// Adds (or replaces) a stage in the registry the filter builds its stages from.
// The built-in stages (semantic, dm, stdyn, ddl, li) are there from the start.
void register_stage(const std::string& name, StageFactory factory);
std::vector<std::string> registered_stages();
bool is_registered(const std::string& name);

struct FilterResult {
  cv::Mat mask;          // CV_8UC1 255 = dynamic (also FrameData::dynamic), image size
  double fraction = 0;   // of the image
  bool all_dynamic = false;  // fraction >= all_dynamic_fraction
  // Wall time per stage ("<stage>", and "motion_cues" when computed), and the whole filter.
  std::map<std::string, double> stage_ms;
  double total_ms = 0;
  std::map<std::string, StageReport> reports;  // by stage name
  // Stages that failed with an exception on this frame (a bug, not bad
  // input): their regions are left out, the frame goes on.
  std::vector<std::string> failed;
  std::vector<std::string> failure_messages;  // "<stage>: <what>"
  bool motion_cues = false;    // computed for this frame
  // Wall time of the motion cues' parts (MotionCueCache::ms: corners,
  // pyramids, flow, stereo; and ego, the ego-motion), within
  // stage_ms["motion_cues"]; also regions_wait (within) and regions_ahead
  // (the worker's, beside them): see process().
  std::map<std::string, double> motion_cue_ms;
  int tracked_points = 0;      // of the motion cues
  bool ego_valid = false;
  int ego_inliers = 0;
};

class DynamicFilter {
 public:
  // options.validate(sensor) first: InputError for a stage the sensor cannot run.
  DynamicFilter(const DynamicFilterOptions& options, Sensor sensor,
                std::shared_ptr<const map::Calibration> calib);

  bool enabled() const { return !stages_.empty(); }
  std::vector<std::string> stage_names() const;
  // The semantic stage's movable label ids (empty without that stage).
  std::vector<int> movable_classes() const;
  // Replaces them (options.movable_classes): a label source announcing its
  // label set after start-up. Between process() calls; empty ids: unchanged.
  void set_movable_classes(const std::vector<int>& ids);
  Sensor sensor() const { return sensor_; }
  const std::shared_ptr<const map::Calibration>& calib() const { return calib_; }

  // Runs the stages on `current` (grey set; colour, right, depth, labels as
  // the sensor has them) and sets current.dynamic. The filter keeps the
  // frame's images (cv::Mat buffers shared, not copied): the caller must not
  // write into them afterwards. T_cw_predicted: SLAM's constant-velocity
  // prediction for this frame, if any.
  //
  // While the motion cues are computed (LK, which OpenCV spreads over the
  // cores, then the ego-motion), the worker thread of the corners ahead cuts
  // the candidate regions the stages still to run will ask for
  // (Stage::regions_wanted: DM-SLAM's split by class, 1.2-1.5 ms at 640x480
  // with movers), and the stages find them in ctx.regions
  // (FilterResult::motion_cue_ms: regions_ahead, the job's own time, and
  // regions_wait, the wait for it after the cues). Old and new builds
  // interleaved, `full` with label images, asynchronous mapping, track call,
  // median of the runs' medians, paced (--realtime) / as fast as possible:
  // synthetic RGB-D with movers 15.1 -> 13.5 / 14.8 -> 13.0 ms (6 + 6 runs),
  // monocular with movers 13.2 -> 12.5 / 14.5 -> 15.0 (6 + 6; its keyframe
  // timing varies unpaced; pooled mean 15.7 both), stereo with movers
  // 21.7 -> 20.9 / 23.4 -> 24.3 (5 + 5; pooled mean 24.8 -> 24.5), KITTI 06
  // paced 26.8 -> 24.4 (5 + 5). The same regions (synchronous runs: the same
  // trajectories).
  FilterResult process(FrameData& current, const std::optional<Eigen::Isometry3d>& T_cw_predicted);
  // After tracking the frame of the last process(): its pose (empty when lost).
  // It becomes the previous frame of the next process() (also without this call).
  void frame_tracked(const std::optional<Eigen::Isometry3d>& T_cw);
  // Starts the detection of the last process()'s frame's corners for the
  // next frame's motion cues on the motion cues' worker thread, when that
  // process() prepared it (see the end of this comment). System calls it once the frame's ORB features are
  // extracted: started during the filter, the detection (Harris with
  // sub-pixel refinement: 5-6 ms a frame; for stereo also 3.5-5 ms of LK
  // into the right image) took the second core from the extraction's other
  // half (the right image, or half the pyramid levels). Started after it,
  // it runs beside stereo matching, tracking and, live, the wait for the
  // next frame. Old and new builds interleaved, asynchronous mapping,
  // `full` with label images (KITTI 06: `dynaorb segment`'s), track call,
  // median of the runs' medians, at the camera's rate (--realtime) / as fast
  // as possible: KITTI 06 30.8 -> 27.5 / 34.4 -> 32.7 ms (5 + 5 runs);
  // synthetic stereo with movers 23.1 -> 20.9 / 24.2 -> 24.2, without
  // 19.8 -> 17.9 / 21.1 -> 19.4; monocular with movers 15.6 -> 13.7 /
  // 15.0 -> 15.2, without 11.1 -> 10.6 (6 + 6) / 12.7 -> 12.8; RGB-D (1 ms
  // of FAST corners there) 16.4 -> 16.5 / 16.1 -> 16.1 with movers (4 + 4
  // each but KITTI and the 6 + 6). The corners are the same (synchronous
  // runs give the same trajectories). Not called: the next process()
  // starts it, before its own stages. Prepared when the frame or the one
  // before it used the cues (a frame that uses them after one that did not
  // prepares them too: on KITTI 06 with `dynaorb segment`'s labels, where
  // 10 of 51 frames have no movable object, 1 frame a run instead of 6
  // then detected its previous frame's corners itself, paced; track call
  // mean 26.7 -> 26.4 ms, 90th percentile 38.4 -> 37.7, 5 + 5 runs).
  void start_corners_ahead();
  // The frame of the last process() became a keyframe with these keypoints
  // (tracked-image pixels) and depths (metres, <= 0: none).
  void keyframe_made(const std::vector<cv::Point2f>& keypoints, const std::vector<float>& depth);
  // The caller tracked the last frame with its candidates after all (System:
  // a first frame the map could not start from without them): that frame's
  // dynamic mask loses them, so it says what tracking left out (saved masks,
  // dense clouds, DDL-SLAM's keyframe points). Nothing without candidates.
  void keep_candidates();
  // Forgets frames and keyframes (a SLAM reset); stages reset too.
  void reset();

  std::shared_ptr<const FrameData> last_frame() const;  // of the last process(); null before
  const std::vector<KeyFrameData>& keyframes() const { return keyframes_; }  // newest last

 private:
  void settle_pending();  // the last processed frame becomes the previous one

  DynamicFilterOptions o_;
  Sensor sensor_;
  std::shared_ptr<const map::Calibration> calib_;
  std::vector<std::unique_ptr<Stage>> stages_;
  std::shared_ptr<FrameData> pending_;          // processed, not yet told tracked
  std::shared_ptr<const FrameData> previous_;
  std::shared_ptr<FrameData> last_;             // of the last process(), tracked or not
  std::vector<KeyFrameData> keyframes_;
  MotionCueCache motion_cue_cache_;  // the last frame's LK pyramid, corners detected ahead
  std::shared_ptr<const FrameData> ahead_pending_;  // processed, its corners not yet started ahead
  bool cues_last_frame_ = true;      // the last frame computed motion cues (or none yet)
};

}  // namespace dynaorb::dynamic
