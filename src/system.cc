#include "dynaorb/system.h"

#include <chrono>
#include <deque>
#include <limits>
#include <map>
#include <thread>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "dynaorb/core/grey_image.h"
#include "dynaorb/dynamic/inpainting.h"
#include "dynaorb/dynamic/stereo_depth.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/map/frame.h"
#include "dynaorb/map/map.h"
#include "dynaorb/map/map_io.h"
#include "dynaorb/tracking/frame_builder.h"
#include "dynaorb/tracking/frame_refinement.h"
#include "dynaorb/core/stopwatch.h"

namespace dynaorb {

std::string to_string(TrackingState state) {
  switch (state) {
    case TrackingState::kNoImagesYet: return "NO_IMAGES_YET";
    case TrackingState::kNotInitialized: return "NOT_INITIALIZED";
    case TrackingState::kOk: return "OK";
    case TrackingState::kLost: return "LOST";
  }
  return "UNKNOWN";
}

std::string to_string(RejectReason reason) {
  switch (reason) {
    case RejectReason::kNone: return "none";
    case RejectReason::kEmptyImage: return "empty_image";
    case RejectReason::kWrongSize: return "wrong_size";
    case RejectReason::kWrongType: return "wrong_type";
    case RejectReason::kStampNotIncreasing: return "stamp_not_increasing";
  }
  return "unknown";
}

namespace {

std::string size_text(const cv::Size& s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

// BGR copy of a 3- or 4-channel 8-bit image (the dynamic filter's colour, for
// inpainting and the dense map); empty for grey or unusable input.
cv::Mat to_bgr(const cv::Mat& in, bool rgb_order) {
  cv::Mat bgr;
  if (in.depth() != CV_8U) return bgr;
  if (in.channels() == 3) {
    if (rgb_order) cv::cvtColor(in, bgr, cv::COLOR_RGB2BGR);
    else bgr = in.clone();
  } else if (in.channels() == 4) {
    cv::cvtColor(in, bgr, rgb_order ? cv::COLOR_RGBA2BGR : cv::COLOR_BGRA2BGR);
  }
  return bgr;
}

}  // namespace

// A tracked frame, kept relative to its reference keyframe so that the
// trajectory follows later corrections of the map (ORB-SLAM2).
struct FrameRecord {
  double stamp;
  std::shared_ptr<map::KeyFrame> reference;
  Eigen::Isometry3d T_c_ref;
  int map;  // the keyframe keeps its last pose once its map is given up
  // Until the frame's pose is refined (TrackerOptions::refine_lag_keyframes):
  // its tracked points, and the count of keyframes mapped when it was tracked.
  std::vector<tracking::FrameObservation> obs;
  long mapped_at = 0;
};

struct System::Impl {
  Settings settings;
  Sensor sensor;
  SystemOptions options;
  SystemCounters counters;
  // records is written by the tracking thread (new frames) and the mapping
  // thread (refined poses): records_mutex, taken before the map's mutex.
  std::vector<FrameRecord> records;
  mutable std::mutex records_mutex;
  std::deque<size_t> pending;     // records waiting for their refinement, oldest first
  long mapped_keyframes = 0;      // keyframes local mapping has finished
  unsigned long records_epoch = 0;  // bumped when records are cleared
  optimize::Intrinsics refine_K;    // the tracked camera's, set with the core
  int map_index = 0;  // TrackResult::map
  TrackingState state = TrackingState::kNoImagesYet;
  long next_frame_id = 0;
  // Tracked (rectified) camera -> input camera rotation, for the output poses.
  Eigen::Isometry3d T_rect_input = Eigen::Isometry3d::Identity();

  // The core, built at the first accepted frame (its size fixes the calibration).
  map::Map map;
  std::unique_ptr<place::KeyFrameDatabase> database;  // with a vocabulary; outlives the mapper thread
  std::unique_ptr<mapping::LocalMapper> mapper;
  std::unique_ptr<loop::LoopCloser> loop_closer;  // with a vocabulary and loop_closing
  std::unique_ptr<tracking::FrameBuilder> builder;
  std::unique_ptr<tracking::Tracker> tracker;
  cv::Size expected_size;  // from the settings, or from the first accepted frame
  double last_stamp = -INFINITY;
  cv::Mat rect_map_l1, rect_map_l2, rect_map_r1, rect_map_r2;

  // Per-frame working images after preprocessing.
  cv::Mat grey, grey_right, depth_m, mask;

  // The dynamic-object front end (built with the core; null when off). Its
  // per-frame images: the input's colour (BGR) and the label image, both in
  // the tracked image's pixels.
  std::unique_ptr<dynamic::DynamicFilter> filter;
  bool overlap_extraction = false;  // the filter runs beside the corner detection (DynamicFilterOptions)
  cv::Mat colour, labels;
  cv::Mat unrectify_map;  // input pixel -> rectified pixel (CV_32FC2), for last_dynamic_mask()
  // Stereo depth by semi-global block matching of the frames dense_frame()
  // needed (the current one, remembered keyframes), computed once per frame;
  // keyed by the frame and its stamp, pruned to the frames still remembered.
  std::map<std::pair<const dynamic::FrameData*, double>, cv::Mat> stereo_depth;

  cv::Mat stereo_depth_of(const dynamic::FrameData& f) {
    if (!f.depth.empty()) return f.depth;
    if (sensor != Sensor::kStereo || f.right.empty() || !builder || !(builder->calib()->bf > 0)) return cv::Mat();
    const auto key = std::make_pair(&f, f.stamp);
    auto it = stereo_depth.find(key);
    if (it == stereo_depth.end())
      it = stereo_depth.emplace(key, dynamic::stereo_depth(f.grey, f.right, builder->calib()->bf,
                                                           options.dynamic.inpainting.stereo)).first;
    return it->second;
  }

  void prune_stereo_depth(const dynamic::FrameData& current) {
    for (auto it = stereo_depth.begin(); it != stereo_depth.end();) {
      bool kept = it->first.first == &current;
      for (const dynamic::KeyFrameData& kf : filter->keyframes()) kept = kept || kf.frame.get() == it->first.first;
      it = kept ? std::next(it) : stereo_depth.erase(it);
    }
  }
  bool dynamic_on() const { return options.dynamic.enabled(sensor); }

  Impl(const Settings& s, Sensor k, const SystemOptions& o) : settings(s), sensor(k), options(o) {
    settings.validate(sensor);
    options.dynamic.validate(sensor);  // a stage the sensor cannot run: refused now, not at the first frame
    options.tracker.validate();
    options.mapping.validate();
    options.loop.validate();
    if (options.vocabulary && options.vocabulary->empty())
      throw InputError("the vocabulary is empty (load or train one, or pass none)");
    if (settings.camera.width > 0 && settings.camera.height > 0)
      expected_size = {settings.camera.width, settings.camera.height};
    const StereoRectification& q = settings.rectification;
    if (sensor == Sensor::kStereo && q.enabled()) {
      const cv::Size size(q.width, q.height);
      cv::initUndistortRectifyMap(q.K_l, q.D_l, q.R_l, q.P_l.colRange(0, 3), size, CV_16SC2, rect_map_l1, rect_map_l2);
      cv::initUndistortRectifyMap(q.K_r, q.D_r, q.R_r, q.P_r.colRange(0, 3), size, CV_16SC2, rect_map_r1, rect_map_r2);
      expected_size = size;
      Eigen::Matrix3d R;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) R(r, c) = q.R_l.at<double>(r, c);
      T_rect_input.linear() = R;
    }
  }

  ~Impl() {
    // No keyframe reaches the loop closer once the mapper is paused; the loop
    // closer (and its global BA, which pauses the mapper too) goes before the mapper.
    if (mapper) mapper->pause();
    loop_closer.reset();
  }

  void ensure_core(const cv::Size& size) {
    if (tracker) return;
    auto calib = map::Calibration::make(settings, sensor, size.width, size.height);
    builder = std::make_unique<tracking::FrameBuilder>(settings, calib, options.tracker.mono_init_feature_factor,
                                                       options.tracker.stereo_right_budget_max_factor);
    builder->set_exclude_margin(options.tracker.mask_margin);
    refine_K = {calib->fx, calib->fy, calib->cx, calib->cy, calib->bf};
    if (options.vocabulary)
      database = std::make_unique<place::KeyFrameDatabase>(map, options.vocabulary, options.database);
    // Under synchronous mapping tracking waits for the optimisations: they may take every core.
    mapping::LocalMapperOptions mapping = options.mapping;
    loop::LoopCloserOptions loop = options.loop;
    if (options.synchronous_mapping) {
      const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
      mapping.ba_threads = mapping.ba_threads_synchronous > 0 ? mapping.ba_threads_synchronous : cores;
      loop.threads = loop.threads_synchronous > 0 ? loop.threads_synchronous : cores;
    }
    mapper = std::make_unique<mapping::LocalMapper>(map, sensor, mapping, options.vocabulary, database.get());
    if (database && options.loop_closing)
      loop_closer = std::make_unique<loop::LoopCloser>(map, sensor, *database, *mapper, loop);
    // Each mapped keyframe: the frames it makes old enough are refined (on the
    // mapper's thread), then the keyframe goes to the loop closer.
    mapper->set_keyframe_sink([this, lc = loop_closer.get()](std::shared_ptr<map::KeyFrame> kf) {
      refine_due_frames();
      if (lc) lc->insert_keyframe(std::move(kf));
    });
    const tracking::TrackerOptions t = options.tracker.with_camera_fps(settings.camera.fps);
    tracker = std::make_unique<tracking::Tracker>(map, *mapper, sensor, t, options.vocabulary, database.get());
    tracker->set_localization_mode(options.localization_only);
    if (dynamic_on()) {
      filter = std::make_unique<dynamic::DynamicFilter>(options.dynamic, sensor, calib);
      overlap_extraction = options.dynamic.overlaps_extraction(std::thread::hardware_concurrency(), sensor);
    }
  }

  // Output pose of the input camera in the world of the first input camera.
  Pose output_pose(const Eigen::Isometry3d& T_cw) const {
    return T_rect_input.inverse() * T_cw.inverse() * T_rect_input;
  }

  void track_features(std::shared_ptr<const map::Features> features, double stamp, TrackResult& r) {
    map::Frame frame(next_frame_id++, stamp, std::move(features));
    r.keypoints = frame.size();
    const auto t0 = Clock::now();
    const tracking::TrackOutcome out = tracker->track(frame);
    r.stage_ms["tracking"] = ms_since(t0);
    r.stage_ms["tracking.map_wait"] = out.map_wait_ms;
    r.method = out.method;
    r.new_keyframe = out.new_keyframe;
    r.map = map_index;
    if (out.relocalization_ms >= 0) r.stage_ms["relocalization"] = out.relocalization_ms;
    if (out.initialized) ++counters.initializations;
    if (out.ok && out.method == "relocalization") ++counters.relocalizations;
    if (out.ok) {
      r.state = TrackingState::kOk;
      r.pose = output_pose(frame.T_cw);
      r.tracked_points = out.initialized ? frame.matched_points() : out.inliers;
      record_frame(frame, stamp, out);
    } else {
      r.state = tracker->initialized() || counters.initializations > 0 ? TrackingState::kLost
                                                                       : TrackingState::kNotInitialized;
      if (r.state == TrackingState::kLost) ++counters.lost;
      r.message = out.method == "init" ? (sensor == Sensor::kMono
                                              ? "monocular initialisation: " + (out.init_status.empty()
                                                    ? std::string("waiting for two views with enough matches and parallax")
                                                    : out.init_status)
                                              : "not enough keypoints with depth to initialise")
                  : frame.size() == 0 ? "tracking lost: no keypoints (textureless or fully masked image)"
                                      : "tracking lost";
    }
    if (out.drop_map) {
      // The next frame starts map map_index + 1; this one's keyframe (none:
      // it was lost) and the old map's queued ones are not mapped.
      drop_map();
      ++map_index;
      ++counters.maps_dropped;
      r.map_dropped = true;
      r.message = "tracking lost for too long: map " + std::to_string(map_index - 1) +
                  " given up, the next frames start map " + std::to_string(map_index);
      return;
    }
    if (filter) {
      filter->frame_tracked(out.ok ? std::optional<Eigen::Isometry3d>(frame.T_cw) : std::nullopt);
      if (out.keyframe) {
        const map::Features& f = frame.f();
        std::vector<cv::Point2f> pts;
        pts.reserve(f.keys.size());
        for (const cv::KeyPoint& k : f.keys) pts.push_back(k.pt);
        filter->keyframe_made(pts, f.depth);
      }
    }
    if (out.keyframe) {
      mapper->insert_keyframe(out.keyframe);
      if (options.synchronous_mapping) {
        mapper->wait_idle();
        if (loop_closer) loop_closer->wait_idle();
      }
    }
    for (const auto& times : mapper->take_stage_times())
      for (const auto& [stage, ms] : times) r.stage_ms[stage] += ms;
  }

  // Refuses a call for another sensor (a programming error, not bad data), then counts the frame.
  void begin_frame(Sensor expected, const char* call) {
    if (sensor != expected)
      throw InputError(std::string(call) + " called on a " + to_string(sensor) + " system");
    ++counters.frames;
  }

  TrackResult reject(TrackResult r, RejectReason reason, const std::string& message) {
    r.rejected = reason;
    r.message = message;
    r.state = state;
    ++counters.rejected;
    ++counters.rejected_by_reason[to_string(reason)];
    return r;
  }

  // Checks the stamp, size and type of the main image; converts it to grey.
  bool accept_image(const cv::Mat& image, double stamp, TrackResult& r, const char* what) {
    if (image.empty()) {
      r = reject(r, RejectReason::kEmptyImage, std::string(what) + " image is empty");
      return false;
    }
    if (!std::isfinite(stamp) || stamp <= last_stamp) {
      r = reject(r, RejectReason::kStampNotIncreasing,
                 "stamp " + std::to_string(stamp) + " does not follow " + std::to_string(last_stamp));
      return false;
    }
    if (expected_size.area() > 0 && image.size() != expected_size) {
      r = reject(r, RejectReason::kWrongSize,
                 std::string(what) + " image is " + size_text(image.size()) + ", settings say " +
                     size_text(expected_size));
      return false;
    }
    if (!to_grey(image, settings.camera.rgb, grey)) {
      r = reject(r, RejectReason::kWrongType, std::string(what) + " image must be 8-bit with 1, 3 or 4 channels");
      return false;
    }
    colour.release();
    labels.release();
    if (dynamic_on()) {
      colour = to_bgr(image, settings.camera.rgb);
      // The filter keeps the frame's images: never the caller's buffer.
      if (grey.data == image.data) grey = grey.clone();
    }
    return true;
  }

  void accept_mask(const cv::Mat& m, const cv::Size& size, TrackResult& r) {
    mask.release();
    if (m.empty()) return;
    if (m.size() != size || m.channels() != 1 || (m.depth() != CV_8U && m.depth() != CV_16U)) {
      ++counters.masks_dropped;
      return;
    }
    m.convertTo(mask, CV_8U);  // label ids above 255 saturate: still "masked"
    r.mask_used = true;
  }

  // Label ids for the dynamic filter, in the tracked image's pixels: 8-bit,
  // 16-bit ids above 255 saturated (still "some class", never a movable VOC /
  // COCO / Cityscapes id). Ignored when the filter is off.
  void accept_labels(const cv::Mat& l, const cv::Size& size, TrackResult& r) {
    labels.release();
    if (l.empty() || !dynamic_on()) return;
    if (l.size() != size || l.channels() != 1 || (l.depth() != CV_8U && l.depth() != CV_16U)) {
      ++counters.labels_dropped;
      return;
    }
    cv::Mat ids;
    if (l.depth() == CV_8U) ids = l.clone();
    else l.convertTo(ids, CV_8U);
    if (!rect_map_l1.empty()) cv::remap(ids, labels, rect_map_l1, rect_map_l2, cv::INTER_NEAREST);
    else labels = ids;
    r.labels_used = true;
  }

  // Extraction exclusion mask in the tracked image (rectified for stereo).
  cv::Mat exclusion() const {
    if (mask.empty() || rect_map_l1.empty()) return mask;
    cv::Mat m;
    cv::remap(mask, m, rect_map_l1, rect_map_l2, cv::INTER_NEAREST);
    return m;
  }

  // Runs the dynamic filter on the preprocessed frame; returns its mask (empty when off).
  cv::Mat run_filter(double stamp, TrackResult& r) {
    if (!filter) return cv::Mat();
    dynamic::FrameData fd;
    fd.id = next_frame_id;
    fd.stamp = stamp;
    fd.grey = grey;
    fd.colour = colour;
    if (sensor == Sensor::kStereo) fd.right = grey_right;
    if (sensor == Sensor::kRGBD) fd.depth = depth_m;
    fd.labels = labels;
    const dynamic::FilterResult res = filter->process(fd, tracker->predicted_T_cw());
    r.stage_ms["dynamic"] = res.total_ms;
    for (const auto& [stage, ms] : res.stage_ms) r.stage_ms["dynamic." + stage] = ms;
    r.dynamic_fraction = res.fraction;
    for (const auto& [stage, rep] : res.reports) {
      r.dynamic_values[stage + ".dynamic_points"] = static_cast<double>(rep.dynamic_points.size());
      r.dynamic_values[stage + ".static_points"] = static_cast<double>(rep.static_points.size());
      r.dynamic_values[stage + ".regions"] = rep.regions;
      for (const auto& [k, v] : rep.values) r.dynamic_values[stage + "." + k] = v;
    }
    if (res.motion_cues) {
      r.dynamic_values["motion_cues.tracked_points"] = res.tracked_points;
      r.dynamic_values["motion_cues.ego_valid"] = res.ego_valid ? 1 : 0;
      r.dynamic_values["motion_cues.ego_inliers"] = res.ego_inliers;
      for (const auto& [part, ms] : res.motion_cue_ms) r.dynamic_values["motion_cues." + part + "_ms"] = ms;
    }
    if (res.all_dynamic) ++counters.dynamic_all_frames;
    counters.dynamic_stage_failures += static_cast<long>(res.failed.size());
    return res.mask;
  }

  // A stereo / RGB-D map starts from one frame. When the filter dropped
  // that frame's movable-class candidates unchecked (SemanticOptions::
  // drop_unchecked_<sensor>: no previous frame to prove their motion with)
  // and what is left cannot start the map (Tracker::can_initialize: a small
  // image, a view full of movers), the candidates are kept for this frame, as
  // DM-SLAM leaves an unchecked frame's candidates, rather than losing it:
  // true, with dynamic_mask narrowed to the other stages' regions outside the
  // candidates (DynamicFilter::keep_candidates), r's semantic.unchecked_kept
  // = 1 and counters.unchecked_kept counted. The later frames check them
  // against this one.
  bool keep_unchecked_candidates(const std::shared_ptr<const map::Features>& f, double stamp,
                                 cv::Mat& dynamic_mask, TrackResult& r) {
    if (sensor == Sensor::kMono || !filter || !f || tracker->initialized() || dynamic_mask.empty()) return false;
    const auto dropped = r.dynamic_values.find("semantic.unchecked_dropped");
    if (dropped == r.dynamic_values.end() || dropped->second == 0) return false;
    const std::shared_ptr<const dynamic::FrameData> last = filter->last_frame();
    if (!last || last->candidates.empty()) return false;
    if (tracker->can_initialize(map::Frame(next_frame_id, stamp, f))) return false;
    filter->keep_candidates();
    dynamic_mask = last->dynamic;  // the same frame, its mask narrowed
    r.dynamic_fraction = static_cast<double>(cv::countNonZero(dynamic_mask)) / static_cast<double>(dynamic_mask.total());
    r.dynamic_values["semantic.unchecked_kept"] = 1;
    ++counters.unchecked_kept;
    return true;
  }

  TrackResult finish(TrackResult r, double stamp, Clock::time_point start) {
    r.stage_ms["preprocess"] = ms_since(start);
    if (expected_size.area() == 0) expected_size = grey.size();
    last_stamp = stamp;
    ensure_core(grey.size());
    tracking::StageTimes t;
    std::shared_ptr<const map::Features> f;
    features::ExcludedCount count;
    // The caller's mask with the filter's: what the extraction leaves out
    // (c.region: the filter's part, whose keypoints it counts).
    const auto with_filter = [this](const cv::Mat& dynamic, features::ExcludedCount& c) {
      cv::Mat m = exclusion();
      if (!dynamic.empty() && cv::countNonZero(dynamic) > 0) {
        m = m.empty() ? dynamic : (m | dynamic);
        c.region = dynamic;
      }
      return m;
    };
    cv::Mat dynamic_mask;
    const auto exclude = [&] {
      dynamic_mask = run_filter(stamp, r);
      return with_filter(dynamic_mask, count);
    };
    const bool init = sensor == Sensor::kMono && tracker->wants_init_features(next_frame_id);
    const auto extract = [&](const cv::Mat& m, tracking::StageTimes& times, features::ExcludedCount& c) {
      switch (sensor) {
        case Sensor::kMono: return builder->mono(grey, m, times, init, &c);
        case Sensor::kStereo: return builder->stereo(grey, grey_right, m, times, &c);
        case Sensor::kRGBD: break;
      }
      return builder->rgbd(grey, depth_m, m, times, &c);
    };
    if (overlap_extraction) {
      // The filter runs here while a worker thread detects the corners.
      const tracking::ExclusionSource source = exclude;
      switch (sensor) {
        case Sensor::kMono: f = builder->mono(grey, source, t, init, &count); break;
        case Sensor::kStereo: f = builder->stereo(grey, grey_right, source, t, &count); break;
        case Sensor::kRGBD: f = builder->rgbd(grey, depth_m, source, t, &count); break;
      }
    } else {
      f = extract(exclude(), t, count);
    }
    if (keep_unchecked_candidates(f, stamp, dynamic_mask, r)) {
      // Extracted again with them, on this thread (the worker is idle).
      features::ExcludedCount kept;
      tracking::StageTimes again;
      f = extract(with_filter(dynamic_mask, kept), again, kept);
      for (const auto& [stage, ms] : again) t[stage] += ms;
      count = kept;
    }
    if (filter) filter->start_corners_ahead();  // the worker's core was the extraction's until now
    r.dynamic_keypoints = count.keypoints;
    r.stage_ms.insert(t.begin(), t.end());
    track_features(std::move(f), stamp, r);
    state = r.state;
    if (r.state == TrackingState::kOk) ++counters.tracked;
    return r;
  }

  void record_frame(const map::Frame& frame, double stamp, const tracking::TrackOutcome& out) {
    const tracking::TrackerOptions& o = options.tracker;
    std::lock_guard<std::mutex> lk(records_mutex);
    records.push_back({stamp, out.reference, out.T_c_ref, map_index, {}, mapped_keyframes});
    // Keyframes are estimated by local BA; a localisation-only map never changes.
    if (o.refine_lag_keyframes <= 0 || out.new_keyframe || out.initialized || options.localization_only) return;
    records.back().obs = tracking::frame_observations(frame);
    pending.push_back(records.size() - 1);
    while (static_cast<int>(pending.size()) > o.refine_max_pending) {
      release_observations(records[pending.front()]);
      pending.pop_front();
    }
  }

  // tracking::refine_pose with this System's camera and options; nullopt:
  // the frame keeps the pose it has.
  std::optional<Eigen::Isometry3d> refine(const Eigen::Isometry3d& T_cw,
                                          const std::vector<optimize::PoseObservation>& obs) const {
    return tracking::refine_pose(refine_K, T_cw, obs, options.tracker.refine_min_points, options.tracker.refine_rounds,
                                 options.tracker.pose_final_huber_for(sensor));
  }

  static void release_observations(FrameRecord& r) { std::vector<tracking::FrameObservation>().swap(r.obs); }

  void forget_pending() {
    std::lock_guard<std::mutex> lk(records_mutex);
    for (size_t i : pending) release_observations(records[i]);
    pending.clear();
  }

  // On the mapper's thread, after each keyframe it finished: the frames
  // tracked refine_lag_keyframes mapped keyframes ago or earlier get their
  // pose solved again against their points' current positions
  // (tracking/frame_refinement.h). The optimisations run without either lock.
  void refine_due_frames() {
    const int lag = options.tracker.refine_lag_keyframes;
    struct Job {
      size_t index;
      std::shared_ptr<map::KeyFrame> reference;
      Eigen::Isometry3d T_c_ref, T_ref_w;
      std::vector<tracking::FrameObservation> obs;
      std::vector<optimize::PoseObservation> current;
    };
    std::vector<Job> jobs;
    unsigned long epoch;
    {
      std::lock_guard<std::mutex> lk(records_mutex);
      ++mapped_keyframes;
      if (lag <= 0) return;
      while (!pending.empty() && mapped_keyframes - records[pending.front()].mapped_at >= lag) {
        FrameRecord& r = records[pending.front()];
        jobs.push_back({pending.front(), r.reference, r.T_c_ref, {}, std::move(r.obs), {}});
        release_observations(r);
        pending.pop_front();
      }
      epoch = records_epoch;
    }
    if (jobs.empty()) return;
    {
      std::lock_guard<std::mutex> lk(map.mutex());
      for (Job& j : jobs) {
        j.T_ref_w = j.reference->current_T_cw();
        j.current = tracking::current_observations(j.obs);
      }
    }
    std::vector<std::pair<size_t, Eigen::Isometry3d>> refined;
    for (const Job& j : jobs)
      if (const auto T_cw = refine(j.T_c_ref * j.T_ref_w, j.current))
        refined.emplace_back(j.index, *T_cw * j.T_ref_w.inverse());
    std::lock_guard<std::mutex> lk(records_mutex);
    if (epoch != records_epoch) return;  // the trajectory was restarted meanwhile
    for (const auto& [index, T_c_ref] : refined) records[index].T_c_ref = T_c_ref;
  }

  // The map, the threads' work on it, the keyframe database (through the
  // map's observer) and the filter's keyframes; the trajectory stays.
  void drop_map() {
    if (mapper) mapper->clear_queue();
    forget_pending();  // their points go with the map
    if (loop_closer) loop_closer->reset();
    {
      std::lock_guard<std::mutex> lk(map.mutex());
      map.clear();
      if (tracker) tracker->reset();
    }
    if (filter) filter->reset();
  }

  // The trajectory, the map count and the stamp order start again (reset, a loaded map).
  void restart_trajectory(TrackingState next) {
    {
      std::lock_guard<std::mutex> lk(records_mutex);
      records.clear();
      pending.clear();
      ++records_epoch;
    }
    map_index = 0;
    state = next;
    last_stamp = -INFINITY;
  }

  void reset() {
    drop_map();
    restart_trajectory(TrackingState::kNoImagesYet);
  }

  // Input pixel -> rectified pixel of the left camera (stereo with rectification).
  const cv::Mat& unrectify() {
    if (!unrectify_map.empty() || rect_map_l1.empty()) return unrectify_map;
    const StereoRectification& q = settings.rectification;
    std::vector<cv::Point2f> px, out;
    px.reserve(static_cast<size_t>(q.width) * q.height);
    for (int v = 0; v < q.height; ++v)
      for (int u = 0; u < q.width; ++u) px.emplace_back(static_cast<float>(u), static_cast<float>(v));
    cv::undistortPoints(px, out, q.K_l, q.D_l, q.R_l, q.P_l);
    unrectify_map = cv::Mat(q.height, q.width, CV_32FC2, out.data()).clone();
    return unrectify_map;
  }
};

System::System(const Settings& settings, Sensor sensor, const SystemOptions& options)
    : impl_(std::make_unique<Impl>(settings, sensor, options)) {}
System::~System() = default;

TrackResult System::track_mono(const cv::Mat& image, double stamp, const cv::Mat& mask, const cv::Mat& labels) {
  Impl& s = *impl_;
  s.begin_frame(Sensor::kMono, "track_mono");
  const auto start = Clock::now();
  TrackResult r;
  if (!s.accept_image(image, stamp, r, "mono")) return r;
  s.accept_mask(mask, image.size(), r);
  s.accept_labels(labels, image.size(), r);
  return s.finish(r, stamp, start);
}

TrackResult System::track_stereo(const cv::Mat& left, const cv::Mat& right, double stamp, const cv::Mat& mask,
                                 const cv::Mat& labels) {
  Impl& s = *impl_;
  s.begin_frame(Sensor::kStereo, "track_stereo");
  const auto start = Clock::now();
  TrackResult r;
  if (right.empty()) return s.reject(r, RejectReason::kEmptyImage, "right image is empty");
  if (!s.accept_image(left, stamp, r, "left")) return r;
  if (right.size() != left.size())
    return s.reject(r, RejectReason::kWrongSize,
                    "right image is " + size_text(right.size()) + ", left is " + size_text(left.size()));
  cv::Mat left_grey = s.grey.clone();
  if (!to_grey(right, s.settings.camera.rgb, s.grey_right))
    return s.reject(r, RejectReason::kWrongType, "right image must be 8-bit with 1, 3 or 4 channels");
  if (!s.rect_map_l1.empty()) {
    // Into a new image: s.grey may still share the caller's left image.
    cv::Mat rectified_left, rectified_right;
    cv::remap(left_grey, rectified_left, s.rect_map_l1, s.rect_map_l2, cv::INTER_LINEAR);
    s.grey = rectified_left;
    cv::remap(s.grey_right, rectified_right, s.rect_map_r1, s.rect_map_r2, cv::INTER_LINEAR);
    s.grey_right = rectified_right;
    if (!s.colour.empty()) {
      cv::Mat rectified_colour;
      cv::remap(s.colour, rectified_colour, s.rect_map_l1, s.rect_map_l2, cv::INTER_LINEAR);
      s.colour = rectified_colour;
    }
  } else {
    s.grey = left_grey;
    if (s.dynamic_on() && s.grey_right.data == right.data) s.grey_right = s.grey_right.clone();
  }
  s.accept_mask(mask, left.size(), r);
  s.accept_labels(labels, left.size(), r);
  return s.finish(r, stamp, start);
}

TrackResult System::track_rgbd(const cv::Mat& image, const cv::Mat& depth, double stamp, const cv::Mat& mask,
                               const cv::Mat& labels) {
  Impl& s = *impl_;
  s.begin_frame(Sensor::kRGBD, "track_rgbd");
  const auto start = Clock::now();
  TrackResult r;
  if (depth.empty()) return s.reject(r, RejectReason::kEmptyImage, "depth image is empty");
  if (!s.accept_image(image, stamp, r, "colour")) return r;
  if (depth.size() != image.size())
    return s.reject(r, RejectReason::kWrongSize,
                    "depth image is " + size_text(depth.size()) + ", colour is " + size_text(image.size()));
  if (depth.channels() != 1 || (depth.depth() != CV_16U && depth.depth() != CV_32F))
    return s.reject(r, RejectReason::kWrongType, "depth image must be 16UC1 or 32FC1");
  const double factor = *s.settings.camera.depth_map_factor;
  s.depth_m.release();  // a new buffer every frame: the dynamic filter keeps the last ones
  depth.convertTo(s.depth_m, CV_32F, 1.0 / factor);
  // NaN, infinite, zero and negative depths are "no measurement": set to 0
  // and counted. 16-bit depth with a positive factor has only zeros of
  // those, which convert to 0.
  if (depth.depth() == CV_16U && factor > 0) {
    r.invalid_depth_pixels = static_cast<int>(depth.total()) - cv::countNonZero(depth);
  } else {
    cv::Mat valid = (s.depth_m > 0.0f) & (s.depth_m < std::numeric_limits<float>::infinity());
    r.invalid_depth_pixels = static_cast<int>(s.depth_m.total()) - cv::countNonZero(valid);
    s.depth_m.setTo(0.0f, ~valid);
  }
  s.accept_mask(mask, image.size(), r);
  s.accept_labels(labels, image.size(), r);
  return s.finish(r, stamp, start);
}

Sensor System::sensor() const { return impl_->sensor; }
const Settings& System::settings() const { return impl_->settings; }
const SystemCounters& System::counters() const {
  SystemCounters& c = impl_->counters;
  if (impl_->loop_closer) {
    const loop::LoopCloserCounters l = impl_->loop_closer->counters();
    c.loops_closed = l.loops_closed;
    c.global_ba_runs = l.global_ba_runs;
  }
  return c;
}
std::vector<TrajectorySegment> System::trajectory_segments() const {
  const Impl& s = *impl_;
  // Frames still waiting for their refinement are solved against the map as
  // it is now (not stored: later keyframes may refine them further), after
  // both locks are released, so that tracking and mapping go on meanwhile.
  struct Pose {
    double stamp;
    int map;
    Eigen::Isometry3d T_cw;
    std::vector<optimize::PoseObservation> pending;
  };
  std::vector<Pose> poses;
  {
    std::lock_guard<std::mutex> records_lock(s.records_mutex);
    std::lock_guard<std::mutex> lk(s.map.mutex());
    poses.reserve(s.records.size());
    for (const FrameRecord& r : s.records)
      poses.push_back({r.stamp, r.map, r.T_c_ref * r.reference->current_T_cw(), tracking::current_observations(r.obs)});
  }
  std::vector<TrajectorySegment> out;
  for (const Pose& p : poses) {
    if (out.empty() || out.back().map != p.map) out.push_back({p.map, {}});
    const std::optional<Eigen::Isometry3d> refined = s.refine(p.T_cw, p.pending);  // none: nothing pending, or too few points
    out.back().poses.push_back({p.stamp, s.output_pose(refined ? *refined : p.T_cw)});
  }
  return out;
}

Trajectory System::trajectory() const {
  std::vector<TrajectorySegment> segments = trajectory_segments();
  if (segments.empty()) return {};
  size_t best = 0;
  for (size_t i = 1; i < segments.size(); ++i)
    if (segments[i].poses.size() >= segments[best].poses.size()) best = i;
  return std::move(segments[best].poses);
}

std::vector<Eigen::Vector3d> System::map_points() const {
  const Impl& s = *impl_;
  std::vector<Eigen::Vector3d> out;
  std::lock_guard<std::mutex> lk(s.map.mutex());
  const Eigen::Isometry3d T_input_rect = s.T_rect_input.inverse();
  for (const auto& p : s.map.points()) out.push_back(T_input_rect * p->position());
  return out;
}

MapSummary System::map_summary() const {
  const Impl& s = *impl_;
  MapSummary m;
  {
    std::lock_guard<std::mutex> lk(s.map.mutex());
    m.keyframes = static_cast<long>(s.map.keyframe_count());
    m.points = static_cast<long>(s.map.point_count());
  }
  if (s.mapper) m.mapping = s.mapper->counters();
  if (s.loop_closer) m.loop = s.loop_closer->counters();
  return m;
}

void System::reset() { impl_->reset(); }

void System::wait_for_mapping() {
  Impl& s = *impl_;
  if (s.mapper) s.mapper->wait_idle();
  if (s.loop_closer) s.loop_closer->wait_idle();
}

// Map files and localisation only (map/map_io.h).
void System::save_map(const std::string& path) {
  Impl& s = *impl_;
  if (s.mapper) s.mapper->wait_idle();  // keyframes still queued are not yet in the graph
  std::lock_guard<std::mutex> lk(s.map.mutex());
  if (!s.builder) throw InputError(path, 0, "nothing to save: the system has no map yet");
  map::save_map(path, s.map, *s.builder->calib(), s.sensor,
                s.loop_closer ? s.loop_closer->loop_edges() : map::LoopEdges{});
}

void System::load_map(const std::string& path) {
  Impl& s = *impl_;
  if (!s.options.vocabulary)
    throw InputError(path, 0, "cannot use a loaded map without a vocabulary (frames are relocalised in it): "
                              "create the System with one");
  const map::MapFileInfo info = map::read_map_info(path);
  if (!s.builder) {  // no frame yet: the calibration for the file's image size, if the settings allow it
    const cv::Size size = s.expected_size.area() > 0 ? s.expected_size : cv::Size(info.width, info.height);
    const std::string why =
        map::calibration_mismatch(info, *map::Calibration::make(s.settings, s.sensor, size.width, size.height), s.sensor);
    if (!why.empty()) throw InputError(path, 0, "map refused: " + why);
    s.expected_size = size;
    s.ensure_core(size);
  }
  s.mapper->wait_idle();  // queued keyframes mapped: a refused file leaves a consistent map
  // The loop closer's queue, candidate groups and loop edges name the old
  // map's keyframes by id, and ids repeat across maps: they go, and a global
  // BA on the old map is aborted. Done before the file is read, so that no
  // old keyframe is checked against the new map; a refused file therefore
  // leaves the old map without its loop history (its poses are unchanged).
  if (s.loop_closer) s.loop_closer->reset();
  {
    std::lock_guard<std::mutex> lk(s.map.mutex());
    map::LoadOptions o;
    o.vocabulary = s.options.vocabulary.get();
    o.database = s.database.get();
    map::LoopEdges loop_edges;
    o.loop_edges = &loop_edges;
    map::load_map(path, s.map, s.builder->calib(), s.sensor, o);
    if (s.loop_closer) s.loop_closer->restore_loop_edges(std::move(loop_edges));
    s.tracker->map_replaced();
  }
  s.mapper->clear_queue();  // forgets the old map's recent points
  if (s.filter) s.filter->reset();  // its keyframes' poses belong to the old map
  s.restart_trajectory(TrackingState::kLost);
}

void System::set_localization_mode(bool on) {
  Impl& s = *impl_;
  s.options.localization_only = on;
  if (!s.tracker) return;
  if (on) s.mapper->wait_idle();  // the keyframes already queued are mapped, then no more
  std::lock_guard<std::mutex> lk(s.map.mutex());
  s.tracker->set_localization_mode(on);
}

bool System::localization_mode() const { return impl_->options.localization_only; }

bool System::dynamic_filter_enabled() const { return impl_->dynamic_on(); }

std::vector<int> System::movable_classes() const {
  return impl_->filter ? impl_->filter->movable_classes() : std::vector<int>();
}

void System::set_movable_classes(const std::vector<int>& ids) {
  if (impl_->filter) impl_->filter->set_movable_classes(ids);
}

cv::Mat System::last_dynamic_mask() const {
  Impl& s = *impl_;
  if (!s.filter || !s.filter->last_frame()) return cv::Mat();
  const cv::Mat& m = s.filter->last_frame()->dynamic;
  if (m.empty() || s.rect_map_l1.empty()) return m.clone();
  cv::Mat out;
  cv::remap(m, out, s.unrectify(), cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

DenseFrame System::dense_frame(bool inpaint) const {
  Impl& s = *impl_;
  DenseFrame d;
  if (!s.filter || !s.filter->last_frame() || !s.builder) return d;
  const dynamic::FrameData& f = *s.filter->last_frame();
  const map::Calibration& calib = *s.builder->calib();
  d.stamp = f.stamp;
  d.fx = calib.fx;
  d.fy = calib.fy;
  d.cx = calib.cx;
  d.cy = calib.cy;
  d.dist = calib.dist.empty() ? cv::Mat() : calib.dist.clone();
  d.dynamic = f.dynamic.clone();
  d.candidates = f.candidates.empty() ? cv::Mat() : f.candidates.clone();
  d.motion_checked = f.motion_checked;
  // The camera of the tracked pixels in the output world (the first input
  // camera): T_rect_input^-1 * T_cw^-1 (for mono / RGB-D T_rect_input = I).
  if (f.T_cw) d.T_wc = s.T_rect_input.inverse() * f.T_cw->inverse();
  s.prune_stereo_depth(f);
  const cv::Mat depth = s.stereo_depth_of(f);  // RGB-D: the sensor's; stereo: a stage's, else SGBM
  if (inpaint && f.T_cw && cv::countNonZero(f.dynamic) > 0) {
    // Stereo frames get their depth here, not in the tracking thread: only
    // the frames a dense map asks for pay for block matching.
    dynamic::FrameData current = f;  // cv::Mat headers: no pixels copied
    current.depth = depth;
    std::vector<dynamic::KeyFrameData> keyframes = s.filter->keyframes();
    for (dynamic::KeyFrameData& kf : keyframes) {
      if (!kf.frame || !kf.frame->depth.empty()) continue;
      auto with_depth = std::make_shared<dynamic::FrameData>(*kf.frame);
      with_depth->depth = s.stereo_depth_of(*kf.frame);
      kf.frame = std::move(with_depth);
    }
    const dynamic::InpaintResult in =
        dynamic::inpaint_background(current, keyframes, calib, s.options.dynamic.inpainting);
    if (!in.colour.empty()) d.colour = in.colour;
    else if (!in.grey.empty()) cv::cvtColor(in.grey, d.colour, cv::COLOR_GRAY2BGR);
    if (!depth.empty()) d.depth = in.depth;
    d.inpainted = true;
    d.inpainted_pixels = in.filled_pixels;
  }
  if (d.colour.empty()) {
    if (!f.colour.empty()) d.colour = f.colour.clone();
    else cv::cvtColor(f.grey, d.colour, cv::COLOR_GRAY2BGR);
  }
  if (d.depth.empty() && !depth.empty()) d.depth = depth.clone();
  return d;
}

}  // namespace dynaorb
