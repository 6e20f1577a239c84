// The dynamic-object front end: presets, the stage registry, and the per-frame
// run of the stages with the shared motion cues and the remembered frames.
#include "dynaorb/dynamic/dynamic_filter.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <mutex>
#include <optional>

#include "dynaorb/core/helper_thread.h"
#include "dynaorb/core/stopwatch.h"
#include "dynaorb/dynamic/semantic_stage.h"
#include "dynaorb/io/errors.h"
#include "stage_registry.h"

namespace dynaorb::dynamic {

namespace {

std::mutex& registry_mutex() {
  static std::mutex m;
  return m;
}

std::map<std::string, StageFactory>& registry() {
  static std::map<std::string, StageFactory> r = builtin_stages();
  return r;
}

StageFactory factory_of(const std::string& name) {
  std::lock_guard<std::mutex> lk(registry_mutex());
  auto it = registry().find(name);
  return it == registry().end() ? StageFactory() : it->second;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

const char* const kStagesKey = "Dynamic.stages";
const char* const kKeyframesKey = "Dynamic.keyframes";
const char* const kAllDynamicKey = "Dynamic.all_dynamic_fraction";
const char* const kOverlapKey = "Dynamic.overlap_extraction";
const char* const kMotionCuesKey = "Dynamic.motion_cues";
const char* const kInpaintingKey = "Dynamic.inpainting";
const std::string kPrefix = "Dynamic.";

// Whether `read` knows `key`: it is handed the key with a value no option
// accepts (a map); reading a known key then fails on the type, an unknown
// key is silently ignored. Works for every options struct read with
// file_node_options.h (missing keys keep defaults, wrong types throw), so
// the stages need not list their keys twice.
bool reads_key(const std::function<void(const cv::FileNode&)>& read, const std::string& key) {
  cv::FileStorage probe("%YAML:1.0\nprobe:\n  " + key + ": {dynaorb_probe: 0}\n",
                        cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  try {
    read(probe["probe"]);
  } catch (const std::exception&) {
    return true;
  }
  return false;
}

// Checks the keys of one options node and reads it with `read`.
void read_options(const cv::FileNode& node, const std::string& key, const std::string& source,
                  const std::function<void(const cv::FileNode&)>& read) {
  if (node.empty() || node.isNone()) return;
  if (!node.isMap()) throw InputError(source, 0, "'" + key + "' must be a map of options ({name: value, ...})");
  for (const std::string& k : node.keys())
    if (!reads_key(read, k)) throw InputError(source, 0, "unknown option '" + key + "." + k + "'");
  try {
    read(node);
  } catch (const InputError& e) {
    throw InputError(source, 0, e.what());
  } catch (const std::exception& e) {
    throw InputError(source, 0, "'" + key + "': " + e.what());
  }
}

// Reads motion-cue options `node` (the key `key`) over `cues`. Checked here,
// at load time, as the stages' options are (validate() checks them again for
// options built in code).
void read_motion_cues(const cv::FileNode& node, const std::string& key, const std::string& source,
                      MotionCueOptions& cues) {
  read_options(node, key, source, [&cues](const cv::FileNode& n) {
    MotionCueOptions probe = cues;
    probe.read(n);
    probe.validate();
  });
  if (!node.empty() && !node.isNone()) cues.read(node);
}

std::vector<std::string> stage_list(const cv::FileNode& n, const std::string& key, const std::string& source) {
  if (!n.isSeq()) throw InputError(source, 0, "'" + key + "' must be a list of stage names ([semantic, dm])");
  std::vector<std::string> out;
  for (const cv::FileNode& item : n) {
    if (!item.isString()) throw InputError(source, 0, "'" + key + "' must be a list of stage names");
    const std::string name = static_cast<std::string>(item);
    if (!is_registered(name))
      throw InputError(source, 0, "unknown stage '" + name + "' in '" + key + "' (known: " +
                                      joined(registered_stages()) + ")");
    if (std::find(out.begin(), out.end(), name) != out.end())
      throw InputError(source, 0, "stage '" + name + "' is listed twice in '" + key + "'");
    out.push_back(name);
  }
  // The shared motion cues and the later stages read the current frame's
  // candidates, which the semantic stage sets.
  auto sem = std::find(out.begin(), out.end(), "semantic");
  if (sem != out.end() && sem != out.begin())
    throw InputError(source, 0, "'" + key + "': the semantic stage must come first (later stages read its regions)");
  return out;
}

std::unique_ptr<Stage> make_stage(const DynamicFilterOptions& o, const std::string& name) {
  StageFactory make = factory_of(name);
  if (!make) throw InputError(o.source.empty() ? "<dynamic options>" : o.source, 0, "unknown stage '" + name + "'");
  try {
    return make(o.stage_node(name));
  } catch (const InputError& e) {
    throw InputError(o.source.empty() ? "<dynamic options>" : o.source, 0, e.what());
  }
}

DynamicFilterOptions from_storage(std::shared_ptr<cv::FileStorage> fs, const std::string& source) {
  DynamicFilterOptions o;
  o.source = source;
  o.file = fs;
  const cv::FileNode root = fs->root();
  const cv::FileNode stages = root[kStagesKey];
  if (stages.empty() || stages.isNone())
    throw InputError(source, 0, std::string("missing key '") + kStagesKey + "' (the stages to run, [] for none)");
  if (stages.isMap()) {
    for (const std::string& k : stages.keys()) {
      Sensor s;
      try {
        s = parse_sensor(k);
      } catch (const std::exception&) {
        throw InputError(source, 0, "unknown sensor '" + std::string(kStagesKey) + "." + k + "' (mono, stereo, rgbd)");
      }
      o.sensor_stages[s] = stage_list(stages[k], std::string(kStagesKey) + "." + k, source);
    }
  } else {
    o.stages = stage_list(stages, kStagesKey, source);
  }
  std::vector<std::pair<Sensor, std::string>> sensor_cue_nodes;  // read over the common cues below
  for (const std::string& key : root.keys()) {
    if (key.rfind(kPrefix, 0) != 0 || key == kStagesKey) continue;
    const cv::FileNode n = root[key];
    if (key == kKeyframesKey) {
      if (!n.isInt() || static_cast<int>(n) < 0)
        throw InputError(source, 0, "'" + key + "' must be an integer >= 0");
      o.keyframes = static_cast<int>(n);
    } else if (key == kAllDynamicKey) {
      if ((!n.isReal() && !n.isInt()) || !(static_cast<double>(n) > 0 && static_cast<double>(n) <= 1))  // NaN too
        throw InputError(source, 0, "'" + key + "' must be a number in (0, 1]");
      o.all_dynamic_fraction = static_cast<double>(n);
    } else if (key == kOverlapKey) {
      if (!n.isInt() || static_cast<int>(n) < -1 || static_cast<int>(n) > 1)
        throw InputError(source, 0, "'" + key + "' must be -1 (auto), 0 (never) or 1 (always)");
      o.overlap_extraction = static_cast<int>(n);
    } else if (key == kMotionCuesKey) {
      read_motion_cues(n, key, source, o.motion_cues);
    } else if (key.rfind(kMotionCuesKey + std::string("."), 0) == 0) {
      const std::string sensor = key.substr(std::strlen(kMotionCuesKey) + 1);
      Sensor s;
      try {
        s = parse_sensor(sensor);
      } catch (const std::exception&) {
        throw InputError(source, 0, "unknown sensor in '" + key + "' (" + kMotionCuesKey + ".mono, .stereo, .rgbd)");
      }
      sensor_cue_nodes.emplace_back(s, key);
    } else if (key == kInpaintingKey) {
      read_options(n, key, source, [](const cv::FileNode& node) { InpaintOptions().read(node); });
      if (!n.empty() && !n.isNone()) o.inpainting.read(n);
    } else {
      const std::string stage = key.substr(kPrefix.size());
      StageFactory make = factory_of(stage);
      if (!make)
        throw InputError(source, 0, "unknown key '" + key + "' (stages: " + joined(registered_stages()) +
                                        "; other keys: stages, keyframes, all_dynamic_fraction, overlap_extraction, "
                                        "motion_cues, motion_cues.<sensor>, inpainting)");
      // Builds the stage once: its options are checked here, at load time.
      read_options(n, key, source, [&make](const cv::FileNode& node) { make(node); });
    }
  }
  for (const auto& [sensor, key] : sensor_cue_nodes) {
    MotionCueOptions m = o.motion_cues;
    read_motion_cues(root[key], key, source, m);
    o.sensor_motion_cues[sensor] = m;
  }
  // A stage listed for one sensor must run on it.
  for (const auto& [sensor, list] : o.sensor_stages) o.validate(sensor);
  return o;
}

}  // namespace

void register_stage(const std::string& name, StageFactory factory) {
  std::lock_guard<std::mutex> lk(registry_mutex());
  registry()[name] = std::move(factory);
}

std::vector<std::string> registered_stages() {
  std::lock_guard<std::mutex> lk(registry_mutex());
  std::vector<std::string> names;
  for (const auto& [name, f] : registry()) names.push_back(name);
  return names;
}

bool is_registered(const std::string& name) { return static_cast<bool>(factory_of(name)); }

DynamicFilterOptions DynamicFilterOptions::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "dynamic preset not found or not readable");
  // Read as text so that a preset without the `%YAML:1.0` line loads too (parse adds it).
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return parse(text, path);
}

DynamicFilterOptions DynamicFilterOptions::parse(const std::string& yaml, const std::string& source) {
  std::string text = yaml;
  if (text.rfind("%YAML", 0) != 0) text = "%YAML:1.0\n" + text;
  auto fs = std::make_shared<cv::FileStorage>();
  try {
    fs->open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    throw InputError(source, 0, "not valid OpenCV YAML (" + e.msg + ")");
  }
  if (!fs->isOpened()) throw InputError(source, 0, "not valid OpenCV YAML");
  return from_storage(fs, source);
}

bool DynamicFilterOptions::overlaps_extraction(unsigned hardware_threads, Sensor sensor) const {
  if (overlap_extraction >= 0) return overlap_extraction == 1;
  return sensor == Sensor::kStereo || hardware_threads >= 4u;
}

const std::vector<std::string>& DynamicFilterOptions::stages_for(Sensor sensor) const {
  auto it = sensor_stages.find(sensor);
  return it != sensor_stages.end() ? it->second : stages;
}

const MotionCueOptions& DynamicFilterOptions::motion_cues_for(Sensor sensor) const {
  auto it = sensor_motion_cues.find(sensor);
  return it != sensor_motion_cues.end() ? it->second : motion_cues;
}

cv::FileNode DynamicFilterOptions::stage_node(const std::string& stage) const {
  if (!file) return cv::FileNode();
  return (*file)[kPrefix + stage];
}

void DynamicFilterOptions::validate(Sensor sensor) const {
  const std::string src = source.empty() ? "<dynamic options>" : source;
  if (stages.empty() && !sensor_stages.empty() && !sensor_stages.count(sensor)) {
    std::vector<std::string> have;
    for (const auto& [s, list] : sensor_stages) have.push_back(to_string(s));
    throw InputError(src, 0, "the preset has no stage list for the " + to_string(sensor) + " sensor (it has: " +
                                 joined(have) + ")");
  }
  // The options' own checks (the motion cues', and each stage's as it is made,
  // e.g. li's) name the key; the preset file is added here.
  try {
    if (!stages_for(sensor).empty()) motion_cues_for(sensor).validate();
    for (const std::string& name : stages_for(sensor)) {
      if (!is_registered(name))
        throw InputError(src, 0, "unknown stage '" + name + "' (known: " + joined(registered_stages()) + ")");
      if (!make_stage(*this, name)->supports(sensor))
        throw InputError(src, 0, "stage '" + name + "' does not support the " + to_string(sensor) + " sensor");
    }
  } catch (const InputError& e) {
    if (!e.file().empty()) throw;
    throw InputError(src, 0, e.what());
  }
}

// ---------------------------------------------------------------- the filter

DynamicFilter::DynamicFilter(const DynamicFilterOptions& options, Sensor sensor,
                             std::shared_ptr<const map::Calibration> calib)
    : o_(options), sensor_(sensor), calib_(std::move(calib)) {
  o_.validate(sensor_);
  for (const std::string& name : o_.stages_for(sensor_)) stages_.push_back(make_stage(o_, name));
  set_movable_classes(o_.movable_classes);  // the label source's own set, when given
}

std::vector<int> DynamicFilter::movable_classes() const {
  for (const auto& stage : stages_)
    if (const auto* sem = dynamic_cast<const SemanticStage*>(stage.get())) return sem->options().ids;
  return {};
}

void DynamicFilter::set_movable_classes(const std::vector<int>& ids) {
  if (ids.empty()) return;  // no set announced: the one in use stays
  o_.movable_classes = ids;
  for (const auto& stage : stages_)
    if (auto* sem = dynamic_cast<SemanticStage*>(stage.get())) sem->set_movable_classes(ids);
}

std::vector<std::string> DynamicFilter::stage_names() const {
  std::vector<std::string> names;
  for (const auto& s : stages_) names.push_back(s->name());
  return names;
}

void DynamicFilter::settle_pending() {
  if (pending_) previous_ = std::move(pending_);
  pending_.reset();
}

namespace {

// Cuts on `worker` the candidate regions that stages[from..] will ask for
// (Stage::regions_wanted) into ctx.regions; `ms` gets the job's own time.
// None when no stage names any. The caller waits for the job before a
// stage runs.
std::optional<HelperThread::Job> cut_regions_ahead(const std::vector<std::unique_ptr<Stage>>& stages, size_t from,
                                                   Context& ctx, HelperThread& worker, double& ms) {
  std::vector<RegionsRequest> wanted;
  for (size_t i = from; i < stages.size(); ++i) {
    if (!stages[i]->needs_motion_cues()) continue;
    try {
      if (auto r = stages[i]->regions_wanted(ctx)) wanted.push_back(std::move(*r));
    } catch (const std::exception&) {
      // A stage bug: nothing is cut ahead for it; its process() meets it.
    }
  }
  if (wanted.empty()) return std::nullopt;
  return worker.submit([&ctx, &ms, wanted = std::move(wanted)] {
    const auto t = Clock::now();
    for (const RegionsRequest& r : wanted) ctx.regions.get(r);
    ms = ms_since(t);
  });
}

}  // namespace

FilterResult DynamicFilter::process(FrameData& current, const std::optional<Eigen::Isometry3d>& T_cw_predicted) {
  const auto t_start = Clock::now();
  settle_pending();
  start_corners_ahead();  // the last frame's, when its caller did not start them
  FilterResult res;
  current.dynamic.release();
  current.candidates.release();
  if (current.grey.empty() || current.grey.type() != CV_8UC1) {
    // Nothing to look at: marks nothing, and is not remembered.
    res.failed.push_back("no_image");
    res.total_ms = ms_since(t_start);
    return res;
  }
  const cv::Size size = current.grey.size();
  // A previous frame of another size (a new camera after a reset) is no previous frame.
  std::shared_ptr<const FrameData> previous =
      previous_ && previous_->grey.size() == size ? previous_ : std::shared_ptr<const FrameData>();

  current.motion_checked = previous != nullptr;
  Context ctx{sensor_, calib_, current, previous, cv::Mat::zeros(size, CV_8UC1), nullptr, nullptr,
              T_cw_predicted, &keyframes_, {}};
  // This frame is the next one's previous frame: its corners are detected
  // ahead, on the cache's worker thread, from its image and the candidates
  // the stages before the first one using the cues (the semantic prior) set,
  // which the corner budget reads. Only while the frames need the cues (a
  // stage may decline them, e.g. DM without candidate regions): when
  // neither this frame nor the one before used them, the detection would
  // take a core for nothing, and the next frame that needs them detects its
  // previous frame's corners itself (the same corners). The detection is
  // only prepared here and started by start_corners_ahead(), once the
  // frame's ORB features are extracted (dynamic_filter.h says why).
  bool ahead_started = false;
  const MotionCueOptions& cues = o_.motion_cues_for(sensor_);
  std::vector<TrackedPoint> tracked;
  EgoMotion ego;
  for (size_t si = 0; si < stages_.size(); ++si) {
    const std::unique_ptr<Stage>& stage = stages_[si];
    const std::string name = stage->name();
    if (!ahead_started && stage->needs_motion_cues()) {
      ahead_started = true;
      ahead_pending_ = std::make_shared<const FrameData>(current);
    }
    if (!res.motion_cues && stage->needs_motion_cues() && stage->needs_motion_cues_for(ctx)) {
      const auto t0 = Clock::now();
      if (previous && calib_) {
        // Meanwhile on the worker, after the corners it may still be
        // detecting (which the cues wait for anyway).
        double regions_ms = -1;
        std::optional<HelperThread::Job> cut = cut_regions_ahead(stages_, si, ctx, *motion_cue_cache_.ahead, regions_ms);
        try {
          tracked = track_points(*previous, current, *calib_, sensor_, cues, &motion_cue_cache_);
          res.motion_cue_ms = motion_cue_cache_.ms;
          const auto t_ego = Clock::now();
          // F only where a stage reads it, DM-SLAM's monocular epipolar
          // check (eq. 9-10), which monocular estimates anyway: for stereo /
          // RGB-D the stages read T_cur_prev, and STDyn fits its own F.
          ego = estimate_ego_motion(tracked, *calib_, sensor_, cues, /*with_F=*/false);
          res.motion_cue_ms["ego"] = ms_since(t_ego);
        } catch (const std::exception& e) {  // documented never to throw: a bug, the stages see no cues
          tracked.clear();
          ego = EgoMotion();
          res.failed.push_back("motion_cues");
          res.failure_messages.push_back(std::string("motion_cues: ") + e.what());
        }
        if (cut) {
          // The stages may use ctx.regions once the job is done. What it
          // threw, the stage meets again when it cuts the regions itself.
          const auto t_wait = Clock::now();
          try {
            cut->get();
          } catch (const std::exception&) {
          }
          res.motion_cue_ms["regions_wait"] = ms_since(t_wait);
          if (regions_ms >= 0) res.motion_cue_ms["regions_ahead"] = regions_ms;
        }
      }
      ctx.tracked = &tracked;
      ctx.ego = &ego;
      res.motion_cues = true;
      res.tracked_points = static_cast<int>(tracked.size());
      res.ego_valid = ego.valid;
      res.ego_inliers = ego.inliers;
      res.stage_ms["motion_cues"] = ms_since(t0);
    }
    StageReport& report = res.reports[name];
    const auto t0 = Clock::now();
    const cv::Mat before = ctx.dynamic.clone();
    try {
      stage->process(ctx, report);
    } catch (const std::exception& e) {
      // A stage bug must not take SLAM down: its regions are dropped.
      res.failed.push_back(name);
      res.failure_messages.push_back(name + ": " + e.what());
      report.values["failed"] = 1;
      ctx.dynamic = before;
    }
    if (ctx.dynamic.size() != size || ctx.dynamic.type() != CV_8UC1) {
      res.failed.push_back(name);
      res.failure_messages.push_back(name + ": left a dynamic mask of another size or type");
      report.values["failed"] = 1;
      ctx.dynamic = before;
    }
    res.stage_ms[name] = ms_since(t0);
  }
  if (!res.motion_cues && !cues_last_frame_) ahead_pending_.reset();
  cues_last_frame_ = res.motion_cues;
  res.mask = ctx.dynamic;
  res.fraction = cv::countNonZero(res.mask) / static_cast<double>(res.mask.total());
  res.all_dynamic = res.fraction >= o_.all_dynamic_fraction;
  current.dynamic = res.mask;
  current.T_cw.reset();
  pending_ = std::make_shared<FrameData>(current);
  last_ = pending_;
  res.total_ms = ms_since(t_start);
  return res;
}

void DynamicFilter::start_corners_ahead() {
  if (!ahead_pending_) return;
  const std::shared_ptr<const FrameData> frame = std::move(ahead_pending_);  // leaves it empty
  if (calib_) detect_corners_ahead(*frame, *calib_, sensor_, o_.motion_cues_for(sensor_), motion_cue_cache_);
}

void DynamicFilter::frame_tracked(const std::optional<Eigen::Isometry3d>& T_cw) {
  if (!pending_) return;
  pending_->T_cw = T_cw;
  settle_pending();
}

void DynamicFilter::keyframe_made(const std::vector<cv::Point2f>& keypoints, const std::vector<float>& depth) {
  if (!last_ || o_.keyframes <= 0) return;
  KeyFrameData kf;
  kf.frame = last_;
  kf.keypoints = keypoints;
  kf.depth.resize(keypoints.size(), 0.0f);
  for (size_t i = 0; i < keypoints.size() && i < depth.size(); ++i)
    kf.depth[i] = std::isfinite(depth[i]) && depth[i] > 0 ? depth[i] : 0.0f;
  keyframes_.push_back(std::move(kf));
  if (static_cast<int>(keyframes_.size()) > o_.keyframes)
    keyframes_.erase(keyframes_.begin(), keyframes_.end() - o_.keyframes);
}

void DynamicFilter::keep_candidates() {
  if (!last_ || last_->candidates.empty() || last_->dynamic.size() != last_->candidates.size()) return;
  cv::Mat rest;  // a new buffer: the old one may be shared
  cv::bitwise_and(last_->dynamic, ~last_->candidates, rest);
  last_->dynamic = rest;
}

void DynamicFilter::reset() {
  pending_.reset();
  ahead_pending_.reset();
  previous_.reset();
  last_.reset();
  keyframes_.clear();
  motion_cue_cache_ = MotionCueCache();
  cues_last_frame_ = true;
  for (auto& s : stages_) s->reset();
}

std::shared_ptr<const FrameData> DynamicFilter::last_frame() const { return last_; }

}  // namespace dynaorb::dynamic
