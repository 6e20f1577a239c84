#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <random>

#include "dynaorb/dynamic/dm_stage.h"
#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/dynamic/semantic_stage.h"
#include "dynaorb/features/orb_extractor.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/system.h"
#include "../test_util.h"

namespace dynaorb::dynamic {
namespace {

// A stage for the tests: logs its calls, marks a configured box, may throw.
struct Probe {
  std::vector<std::string> calls;
  std::vector<const std::vector<TrackedPoint>*> cues;
  std::vector<bool> had_previous;
  std::vector<bool> previous_had_pose;
};
Probe g_probe;

class ProbeStage : public Stage {
 public:
  ProbeStage(std::string name, bool cues, cv::Rect box, bool throws, bool mono_ok)
      : name_(std::move(name)), cues_(cues), box_(box), throws_(throws), mono_ok_(mono_ok) {}
  std::string name() const override { return name_; }
  bool supports(Sensor s) const override { return mono_ok_ || s != Sensor::kMono; }
  bool needs_motion_cues() const override { return cues_; }
  void process(Context& ctx, StageReport& report) override {
    g_probe.calls.push_back(name_);
    g_probe.cues.push_back(ctx.tracked);
    g_probe.had_previous.push_back(ctx.previous != nullptr);
    g_probe.previous_had_pose.push_back(ctx.previous && ctx.previous->T_cw.has_value());
    if (throws_) {
      ctx.dynamic.setTo(255);  // half-done work that must not survive
      throw std::runtime_error("probe failure");
    }
    if (box_.area() > 0) ctx.dynamic(box_).setTo(255);
    report.values["box"] = box_.area();
    report.dynamic_points.push_back({1, 2});
  }

 private:
  std::string name_;
  bool cues_;
  cv::Rect box_;
  bool throws_, mono_ok_;
};

// Registers the probe stages once: probe_a (motion cues, box), probe_b (motion
// cues), probe_c (no cues), probe_throw, probe_no_mono. Options: {box: [x, y, w, h]}.
void register_probes() {
  static bool done = false;
  if (done) return;
  done = true;
  auto add = [](const std::string& name, bool cues, bool throws, bool mono_ok) {
    register_stage(name, [=](const cv::FileNode& node) -> std::unique_ptr<Stage> {
      cv::Rect box;
      if (!node.empty() && node.isMap()) {
        for (const std::string& k : node.keys())
          if (k != "box") throw InputError("option '" + node.name() + "." + k + "' is unknown to the probe");
        const cv::FileNode b = node["box"];
        if (!b.isSeq() || b.size() != 4) throw InputError("option '" + node.name() + ".box' must be [x, y, w, h]");
        box = cv::Rect(static_cast<int>(b[0]), static_cast<int>(b[1]), static_cast<int>(b[2]),
                       static_cast<int>(b[3]));
      }
      return std::make_unique<ProbeStage>(name, cues, box, throws, mono_ok);
    });
  };
  add("probe_a", true, false, true);
  add("probe_b", true, false, true);
  add("probe_c", false, false, true);
  add("probe_throw", false, true, true);
  add("probe_no_mono", false, false, false);
}

std::string error_of(const std::string& yaml, const std::string& source = "preset.yaml") {
  register_probes();
  try {
    DynamicFilterOptions::parse(yaml, source);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

std::shared_ptr<const map::Calibration> calibration(Sensor sensor) {
  Settings s;
  s.camera.fx = s.camera.fy = 300;
  s.camera.cx = 160;
  s.camera.cy = 120;
  s.camera.bf = 30;
  s.camera.th_depth = 40;
  s.camera.depth_map_factor = 1.0;
  return map::Calibration::make(s, sensor, 320, 240);
}

// A textured frame (the motion cues need corners), shifted by `dx` px.
FrameData frame(long id, int dx = 0) {
  cv::Mat tex(240, 400, CV_8UC1);
  cv::RNG rng(5);
  rng.fill(tex, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(tex, tex, cv::Size(5, 5), 1.5);
  FrameData f;
  f.id = id;
  f.stamp = id * 0.1;
  f.grey = tex(cv::Rect(40 + dx, 0, 320, 240)).clone();
  f.depth = cv::Mat(240, 320, CV_32FC1, cv::Scalar(2.0f));
  return f;
}

TEST(DynamicFilterOptions, LoadErrorsNameFileAndKey) {
  EXPECT_TRUE(contains(error_of("Camera.fx: 1\n"), "preset.yaml"));
  EXPECT_TRUE(contains(error_of("Camera.fx: 1\n"), "Dynamic.stages"));
  const std::string unknown_stage = error_of("Dynamic.stages: [semantic, magic]\n");
  EXPECT_TRUE(contains(unknown_stage, "preset.yaml") && contains(unknown_stage, "'magic'")) << unknown_stage;
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.stgaes: [li]\n"), "Dynamic.stgaes"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.magic: {a: 1}\n"), "Dynamic.magic"));
  // Options of a stage: unknown keys and wrong types, whether the stage runs or not.
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [semantic]\nDynamic.semantic: {margni: 3}\n"),
                       "Dynamic.semantic.margni"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: []\nDynamic.semantic: {margin: wide}\n"), "Dynamic.semantic.margin"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: []\nDynamic.dm: {epipolar_threshold: 1}\n"),
                       "Dynamic.dm.epipolar_threshold"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: []\nDynamic.motion_cues: {max_corners: many}\n"),
                       "Dynamic.motion_cues.max_corners"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: []\nDynamic.motion_cues: {corners: 5}\n"),
                       "Dynamic.motion_cues.corners"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.keyframes: -2\n"), "Dynamic.keyframes"));
  for (const char* v : {"0", "1.5", ".nan"})
    EXPECT_TRUE(contains(error_of(std::string("Dynamic.stages: [dm]\nDynamic.all_dynamic_fraction: ") + v + "\n"),
                         "Dynamic.all_dynamic_fraction"))
        << v;
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm, dm]\n"), "twice"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm, semantic]\n"), "first"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: semantic\n"), "list"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: {lidar: [dm]}\n"), "Dynamic.stages.lidar"));
  // A per-sensor list with a stage the sensor cannot run names both.
  const std::string li_rgbd = error_of("Dynamic.stages: {rgbd: [li]}\n");
  EXPECT_TRUE(contains(li_rgbd, "'li'") && contains(li_rgbd, "rgbd")) << li_rgbd;
  EXPECT_EQ(error_of("Dynamic.stages: [semantic, dm]\nDynamic.semantic: {classes: coco, margin: 5}\n"), "no error");
}

// Dynamic.motion_cues.<sensor>: that sensor's changes over Dynamic.motion_cues,
// wherever the common key stands in the file; other sensors keep the common ones.
TEST(DynamicFilterOptions, MotionCuesPerSensor) {
  for (const char* text : {"Dynamic.stages: [semantic, dm]\nDynamic.motion_cues: {lk_window: 20, lk_levels: 4}\n"
                           "Dynamic.motion_cues.rgbd: {lk_window: 15}\n",
                           "Dynamic.stages: [semantic, dm]\nDynamic.motion_cues.rgbd: {lk_window: 15}\n"
                           "Dynamic.motion_cues: {lk_window: 20, lk_levels: 4}\n"}) {
    const DynamicFilterOptions o = DynamicFilterOptions::parse(text, "preset.yaml");
    EXPECT_EQ(o.motion_cues_for(Sensor::kRGBD).lk_window, 15) << text;
    EXPECT_EQ(o.motion_cues_for(Sensor::kRGBD).lk_levels, 4) << text;
    EXPECT_EQ(o.motion_cues_for(Sensor::kStereo).lk_window, 20) << text;
    EXPECT_EQ(o.motion_cues_for(Sensor::kMono).lk_window, 20) << text;
  }
  EXPECT_EQ(DynamicFilterOptions::parse("Dynamic.stages: [dm]\n", "p").motion_cues_for(Sensor::kMono).lk_window,
            MotionCueOptions().lk_window);
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.motion_cues.lidar: {lk_window: 15}\n"),
                       "Dynamic.motion_cues.lidar"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.motion_cues.rgbd: {lk_windw: 15}\n"),
                       "Dynamic.motion_cues.rgbd.lk_windw"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.motion_cues.mono: {lk_window: 1}\n"), "lk_window"));
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.motion_cues.mono: 3\n"), "map"));
  // The one-option per-sensor keys these sections replaced are unknown.
  EXPECT_TRUE(contains(error_of("Dynamic.stages: [dm]\nDynamic.motion_cues: {forward_backward_max_rgbd: 0}\n"),
                       "unknown option 'Dynamic.motion_cues.forward_backward_max_rgbd'"));
}

// Dynamic.overlap_extraction: -1 (auto, the default) always for stereo, by
// hardware threads for mono and RGB-D; 0 never, 1 always; anything else is
// refused by name.
TEST(DynamicFilterOptions, OverlapExtraction) {
  const DynamicFilterOptions o = DynamicFilterOptions::parse("Dynamic.stages: [semantic]\n", "k");
  EXPECT_EQ(o.overlap_extraction, -1);
  for (Sensor s : {Sensor::kMono, Sensor::kRGBD}) {
    EXPECT_FALSE(o.overlaps_extraction(1, s));
    EXPECT_FALSE(o.overlaps_extraction(2, s));
    EXPECT_FALSE(o.overlaps_extraction(3, s));
    EXPECT_TRUE(o.overlaps_extraction(4, s));
  }
  EXPECT_TRUE(o.overlaps_extraction(2, Sensor::kStereo));
  EXPECT_TRUE(o.overlaps_extraction(1, Sensor::kStereo));
  const DynamicFilterOptions on =
      DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.overlap_extraction: 1\n", "k");
  EXPECT_TRUE(on.overlaps_extraction(1, Sensor::kMono));
  const DynamicFilterOptions off =
      DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.overlap_extraction: 0\n", "k");
  EXPECT_FALSE(off.overlaps_extraction(16, Sensor::kRGBD));
  EXPECT_FALSE(off.overlaps_extraction(2, Sensor::kStereo));
  for (const char* bad : {"2", "-2", "yes", "0.5"})
    EXPECT_TRUE(contains(error_of(std::string("Dynamic.stages: []\nDynamic.overlap_extraction: ") + bad + "\n"),
                         "Dynamic.overlap_extraction"))
        << bad;
}

TEST(DynamicFilterOptions, UnsupportedSensorIsRefused) {
  const DynamicFilterOptions o = DynamicFilterOptions::parse("Dynamic.stages: [li]\n", "li_everywhere.yaml");
  EXPECT_NO_THROW(o.validate(Sensor::kStereo));
  try {
    DynamicFilter f(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
    FAIL() << "li accepted on RGB-D";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "li_everywhere.yaml") && contains(e.what(), "'li'") && contains(e.what(), "rgbd"))
        << e.what();
  }
  // The System refuses it at construction, before any frame.
  Settings s;
  s.camera.fx = s.camera.fy = 300;
  s.camera.cx = 160;
  s.camera.cy = 120;
  s.camera.bf = 30;
  s.camera.th_depth = 40;
  s.camera.depth_map_factor = 1.0;
  SystemOptions so;
  so.dynamic = o;
  EXPECT_THROW(System(s, Sensor::kRGBD, so), InputError);
  // A per-sensor preset without a list for the sensor is refused too.
  so.dynamic = DynamicFilterOptions::parse("Dynamic.stages: {stereo: [li]}\n", "stereo_only.yaml");
  EXPECT_THROW(System(s, Sensor::kMono, so), InputError);
  EXPECT_NO_THROW(System(s, Sensor::kStereo, so));
}

TEST(DynamicFilterOptions, ShippedPresetsLoad) {
  const std::filesystem::path dir = std::filesystem::path(DYNAORB_SOURCE_DIR) / "config" / "dynamic";
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".yaml") names.push_back(e.path().stem().string());
  for (const std::string n : {"off", "stdyn", "dm", "ddl", "li", "full"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  for (const std::string& n : names) {
    SCOPED_TRACE(n);
    const DynamicFilterOptions o = DynamicFilterOptions::load((dir / (n + ".yaml")).string());
    for (Sensor s : {Sensor::kMono, Sensor::kStereo, Sensor::kRGBD}) {
      if (!o.stages.empty() || o.sensor_stages.count(s)) {
        EXPECT_NO_THROW(o.validate(s));
      }
    }
  }
  const DynamicFilterOptions full = DynamicFilterOptions::load((dir / "full.yaml").string());
  EXPECT_EQ(full.stages_for(Sensor::kRGBD), (std::vector<std::string>{"semantic", "dm"}));
  // full's per-sensor motion cues: RGB-D and mono track forward only, RGB-D
  // tracks FAST corners (one threshold, no sub-pixel refinement, at most 300
  // inside the candidates); stereo and mono keep Harris corners and the
  // common cues.
  const MotionCueOptions& rgbd = full.motion_cues_for(Sensor::kRGBD);
  EXPECT_EQ(rgbd.forward_backward_max, 0);
  EXPECT_EQ(full.motion_cues_for(Sensor::kMono).forward_backward_max, 0);
  EXPECT_EQ(full.motion_cues_for(Sensor::kStereo).forward_backward_max, MotionCueOptions().forward_backward_max);
  EXPECT_EQ(rgbd.detector, "fast");
  EXPECT_EQ(rgbd.fast_threshold, 20);
  EXPECT_EQ(rgbd.candidate_fast_threshold, 20);
  EXPECT_EQ(rgbd.subpix_window, 0);
  EXPECT_EQ(rgbd.max_candidate_corners, 300);
  for (Sensor s : {Sensor::kStereo, Sensor::kMono}) {
    EXPECT_EQ(full.motion_cues_for(s).detector, "harris");
    EXPECT_EQ(full.motion_cues_for(s).max_candidate_corners, 0);
    EXPECT_LE(full.motion_cues_for(s).candidate_quality_level, 0);
  }
  EXPECT_FALSE(DynamicFilterOptions::load((dir / "off.yaml").string()).enabled(Sensor::kRGBD));
  EXPECT_EQ(DynamicFilterOptions::load((dir / "ddl.yaml").string()).keyframes, 15);
}

TEST(DynamicFilter, RunsStagesInOrderAndTimesEach) {
  register_probes();
  const DynamicFilterOptions o = DynamicFilterOptions::parse(
      "Dynamic.stages: [probe_c, probe_a, probe_b]\nDynamic.probe_a: {box: [10, 20, 30, 40]}\n", "order.yaml");
  DynamicFilter filter(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
  EXPECT_EQ(filter.stage_names(), (std::vector<std::string>{"probe_c", "probe_a", "probe_b"}));
  g_probe = {};
  FrameData f0 = frame(0);
  FilterResult r0 = filter.process(f0, std::nullopt);
  EXPECT_EQ(g_probe.calls, (std::vector<std::string>{"probe_c", "probe_a", "probe_b"}));
  for (const char* k : {"probe_a", "probe_b", "probe_c", "motion_cues"}) EXPECT_TRUE(r0.stage_ms.count(k)) << k;
  EXPECT_EQ(r0.stage_ms.size(), 4u);
  double sum = 0;
  for (const auto& [k, ms] : r0.stage_ms) sum += ms;
  EXPECT_GE(r0.total_ms, sum);
  // Motion cues: none for the stage that does not ask, the same for the two that do.
  EXPECT_EQ(g_probe.cues[0], nullptr);
  EXPECT_NE(g_probe.cues[1], nullptr);
  EXPECT_EQ(g_probe.cues[1], g_probe.cues[2]);
  EXPECT_FALSE(g_probe.had_previous[0]);
  EXPECT_EQ(r0.tracked_points, 0);  // no previous frame
  EXPECT_EQ(cv::countNonZero(r0.mask), 30 * 40);
  EXPECT_EQ(cv::countNonZero(f0.dynamic), 30 * 40);
  EXPECT_NEAR(r0.fraction, 1200.0 / (320 * 240), 1e-12);
  EXPECT_EQ(r0.reports.at("probe_a").values.at("box"), 1200);

  filter.frame_tracked(Eigen::Isometry3d::Identity());
  g_probe = {};
  FrameData f1 = frame(1, 3);
  const FilterResult r1 = filter.process(f1, std::nullopt);
  EXPECT_TRUE(g_probe.had_previous[0] && g_probe.previous_had_pose[0]);
  EXPECT_GT(r1.tracked_points, 100);  // the 3 px shift is followed
  EXPECT_TRUE(r1.ego_valid);
  // Untracked (lost) frame: the next one still has it as previous, without a pose.
  filter.frame_tracked(std::nullopt);
  g_probe = {};
  FrameData f2 = frame(2, 6);
  filter.process(f2, std::nullopt);
  EXPECT_TRUE(g_probe.had_previous[0]);
  EXPECT_FALSE(g_probe.previous_had_pose[0]);
  filter.reset();
  g_probe = {};
  FrameData f3 = frame(3);
  filter.process(f3, std::nullopt);
  EXPECT_FALSE(g_probe.had_previous[0]);
}

TEST(DynamicFilter, AFailingStageLeavesNoTrace) {
  register_probes();
  const DynamicFilterOptions o = DynamicFilterOptions::parse(
      "Dynamic.stages: [probe_a, probe_throw, probe_c]\nDynamic.probe_a: {box: [0, 0, 10, 10]}\n", "t.yaml");
  DynamicFilter filter(o, Sensor::kMono, calibration(Sensor::kMono));
  g_probe = {};
  FrameData f = frame(0);
  const FilterResult r = filter.process(f, std::nullopt);
  EXPECT_EQ(r.failed, (std::vector<std::string>{"probe_throw"}));
  EXPECT_EQ(r.failure_messages, (std::vector<std::string>{"probe_throw: probe failure"}));
  EXPECT_EQ(g_probe.calls.back(), "probe_c");  // the stages after it still run
  EXPECT_EQ(cv::countNonZero(r.mask), 100);
  EXPECT_EQ(r.reports.at("probe_throw").values.at("failed"), 1);
}

// DM-SLAM judges only points in candidate regions: on a frame without any
// (no movable class in the labels) the filter computes no motion cues for
// it; on one with a candidate region it does, and the parts are timed.
TEST(DynamicFilter, MotionCuesOnlyForAFrameThatNeedsThem) {
  const DynamicFilterOptions o = DynamicFilterOptions::parse(
      "Dynamic.stages: [semantic, dm]\nDynamic.semantic: {classes: voc}\n", "dm.yaml");
  DynamicFilter filter(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
  FrameData f0 = frame(0), f1 = frame(1, 2), f2 = frame(2, 4);
  f0.labels = f1.labels = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
  f2.labels = f1.labels.clone();
  f2.labels(cv::Rect(100, 80, 60, 80)).setTo(15);  // a person
  filter.process(f0, std::nullopt);
  const FilterResult r1 = filter.process(f1, std::nullopt);
  EXPECT_FALSE(r1.motion_cues);
  EXPECT_FALSE(r1.stage_ms.count("motion_cues"));
  EXPECT_EQ(r1.reports.at("dm").values.count("skipped_no_candidates"), 1u);
  const FilterResult r2 = filter.process(f2, std::nullopt);
  EXPECT_TRUE(r2.motion_cues);
  EXPECT_GT(r2.tracked_points, 100);
  for (const char* k : {"corners", "pyramids", "flow", "ego"}) EXPECT_TRUE(r2.motion_cue_ms.count(k)) << k;
}

// The next frame's corners are detected ahead, on the worker, when the frame
// or the one before it used the motion cues: a frame that uses them finds
// its previous frame's corners there unless the two frames before it used
// none. Started by start_corners_ahead() (System: after the extraction) or,
// when the caller does not, by the next process().
TEST(DynamicFilter, CornersAheadFollowTheFramesThatUseTheCues) {
  const DynamicFilterOptions o = DynamicFilterOptions::parse(
      "Dynamic.stages: [semantic, dm]\nDynamic.semantic: {classes: voc}\n", "dm.yaml");
  DynamicFilter filter(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
  const bool person[] = {true, true, false, true, false, false, true, true, true};
  std::vector<FrameData> frames;
  for (int k = 0; k < 9; ++k) {
    frames.push_back(frame(k, 2 * k));
    frames.back().labels = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
    if (person[k]) frames.back().labels(cv::Rect(100, 80, 60, 80)).setTo(15);
  }
  std::vector<bool> ahead;
  for (int k = 0; k < 9; ++k) {
    const FilterResult r = filter.process(frames[k], std::nullopt);
    EXPECT_EQ(r.motion_cues, person[k]) << k;
    if (k > 0 && person[k]) { EXPECT_GT(r.tracked_points, 100) << k; }
    ahead.push_back(r.motion_cue_ms.count("corners_ahead") > 0);
    filter.frame_tracked(Eigen::Isometry3d::Identity());
    if (k != 7) filter.start_corners_ahead();  // after 7: left to the next process()
  }
  // 0 has no previous frame; 6 follows two frames without the cues.
  EXPECT_EQ(ahead, (std::vector<bool>{false, true, false, true, false, false, false, true, true}));
}

// DM-SLAM's stage cutting its regions itself, as before the filter cut them
// on its worker beside the motion cues.
class DmCuttingItsOwnRegions : public DmStage {
 public:
  using DmStage::DmStage;
  std::optional<RegionsRequest> regions_wanted(const Context&) const override { return std::nullopt; }
};

TEST(DynamicFilter, RegionsCutBesideTheCuesAreTheStagesOwn) {
  register_stage("dm_own_regions", [](const cv::FileNode& node) -> std::unique_ptr<Stage> {
    DmOptions o;
    o.read(node);
    return std::make_unique<DmCuttingItsOwnRegions>(o);
  });
  const std::string preset = "Dynamic.semantic: {classes: voc, margin: 4}\n";
  DynamicFilter ahead(DynamicFilterOptions::parse("Dynamic.stages: [semantic, dm]\n" + preset, "a.yaml"),
                      Sensor::kRGBD, calibration(Sensor::kRGBD));
  DynamicFilter own(DynamicFilterOptions::parse("Dynamic.stages: [semantic, dm_own_regions]\n" + preset, "o.yaml"),
                    Sensor::kRGBD, calibration(Sensor::kRGBD));
  // The background moves 2 px a frame; a person (15) and the car (7) they
  // stand against move 8 px: one blob of two classes, split into two regions.
  cv::Mat mover(100, 120, CV_8UC1);
  cv::RNG rng(11);
  rng.fill(mover, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(mover, mover, cv::Size(5, 5), 1.5);
  int dynamic_frames = 0;
  for (int k = 0; k < 6; ++k) {
    FrameData a = frame(k, 2 * k);
    const cv::Rect box(60 + 8 * k, 70, 120, 100);
    mover.copyTo(a.grey(box));
    a.labels = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
    a.labels(cv::Rect(box.x, box.y, 50, box.height)).setTo(15);
    a.labels(cv::Rect(box.x + 50, box.y, 70, box.height)).setTo(7);
    FrameData o = a;
    const FilterResult ra = ahead.process(a, std::nullopt);
    const FilterResult ro = own.process(o, std::nullopt);
    ASSERT_TRUE(ra.failed.empty() && ro.failed.empty()) << k;
    EXPECT_EQ(ra.motion_cue_ms.count("regions_ahead"), k > 0 ? 1u : 0u) << k;
    EXPECT_EQ(ro.motion_cue_ms.count("regions_ahead"), 0u) << k;
    EXPECT_EQ(cv::countNonZero(ra.mask != ro.mask), 0) << k;
    std::map<std::string, double> va = ra.reports.at("dm").values, vo = ro.reports.at("dm").values;
    va.erase("regions_ms");
    vo.erase("regions_ms");
    EXPECT_EQ(va, vo) << k;
    if (k > 0) { EXPECT_EQ(va["regions"], 2) << k; }
    if (ra.reports.at("dm").regions > 0) ++dynamic_frames;
    for (DynamicFilter* f : {&ahead, &own}) {
      f->frame_tracked(Eigen::Isometry3d::Identity());
      f->start_corners_ahead();
    }
  }
  EXPECT_GE(dynamic_frames, 4);  // the movers were judged, not skipped
}

// A stage whose regions_wanted has a bug: the filter cuts nothing ahead for
// it, and the frame goes on.
class RegionsWantedThrows : public DmStage {
 public:
  std::optional<RegionsRequest> regions_wanted(const Context&) const override {
    throw std::runtime_error("regions_wanted bug");
  }
};

TEST(DynamicFilter, AStageFailingToNameItsRegionsStillRuns) {
  register_stage("dm_regions_wanted_throws",
                 [](const cv::FileNode&) -> std::unique_ptr<Stage> { return std::make_unique<RegionsWantedThrows>(); });
  DynamicFilter filter(DynamicFilterOptions::parse("Dynamic.stages: [semantic, dm_regions_wanted_throws]\n", "t.yaml"),
                       Sensor::kRGBD, calibration(Sensor::kRGBD));
  for (int k = 0; k < 3; ++k) {
    FrameData f = frame(k, 2 * k);
    f.labels = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
    f.labels(cv::Rect(100, 80, 60, 80)).setTo(15);
    FilterResult r;
    ASSERT_NO_THROW(r = filter.process(f, std::nullopt)) << k;
    EXPECT_TRUE(r.failed.empty()) << k;
    EXPECT_EQ(r.motion_cue_ms.count("regions_ahead"), 0u) << k;
    if (k > 0) { EXPECT_GT(r.reports.at("dm").values.at("regions"), 0) << k; }  // cut by the stage itself
    filter.frame_tracked(Eigen::Isometry3d::Identity());
  }
}

TEST(DynamicFilter, AllDynamicFrameIsKeptAndFlagged) {
  const DynamicFilterOptions o =
      DynamicFilterOptions::parse("Dynamic.stages: [semantic, dm]\nDynamic.semantic: {policy: drop}\n", "all.yaml");
  DynamicFilter filter(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
  for (long i = 0; i < 3; ++i) {
    FrameData f = frame(i, static_cast<int>(i));
    f.labels = cv::Mat(240, 320, CV_8UC1, cv::Scalar(15));  // a person fills the view
    const FilterResult r = filter.process(f, std::nullopt);
    EXPECT_TRUE(r.failed.empty());
    EXPECT_EQ(r.fraction, 1.0);
    EXPECT_TRUE(r.all_dynamic);
    EXPECT_EQ(cv::countNonZero(f.dynamic), 320 * 240);
    filter.frame_tracked(std::nullopt);
  }
}

// A label set announced after start-up (a segmentation server's ~movable_ids)
// replaces the preset's: its ids are the ones marked from then on.
TEST(DynamicFilter, MovableClassesReplacedAfterStartUp) {
  const DynamicFilterOptions o =
      DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n", "s.yaml");
  DynamicFilter filter(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
  EXPECT_EQ(filter.movable_classes(), voc_movable_classes());
  auto marked = [&filter](long id) {
    FrameData f = frame(id);
    f.labels = cv::Mat(240, 320, CV_8UC1, cv::Scalar(0));
    f.labels(cv::Rect(0, 0, 100, 240)).setTo(15);    // a VOC person
    f.labels(cv::Rect(200, 0, 120, 240)).setTo(24);  // another set's id for a person
    filter.process(f, std::nullopt);
    filter.frame_tracked(std::nullopt);
    return std::pair{cv::countNonZero(f.dynamic(cv::Rect(0, 0, 100, 240))),
                     cv::countNonZero(f.dynamic(cv::Rect(200, 0, 120, 240)))};
  };
  EXPECT_EQ(marked(0), std::pair(100 * 240, 0));
  filter.set_movable_classes({24});
  EXPECT_EQ(filter.movable_classes(), std::vector<int>{24});
  EXPECT_EQ(marked(1), std::pair(0, 120 * 240));
  // No semantic stage: no ids, and none to set.
  DynamicFilter dm(DynamicFilterOptions::parse("Dynamic.stages: [dm]\n", "d.yaml"), Sensor::kRGBD,
                   calibration(Sensor::kRGBD));
  dm.set_movable_classes({24});
  EXPECT_TRUE(dm.movable_classes().empty());
}

TEST(DynamicFilter, RemembersTheLastKeyframes) {
  const DynamicFilterOptions o = DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.keyframes: 3\n", "k");
  DynamicFilter filter(o, Sensor::kRGBD, calibration(Sensor::kRGBD));
  filter.keyframe_made({{1, 1}}, {1});  // before any frame: nothing to remember
  EXPECT_TRUE(filter.keyframes().empty());
  for (long i = 0; i < 5; ++i) {
    FrameData f = frame(i);
    filter.process(f, std::nullopt);
    filter.frame_tracked(Eigen::Isometry3d::Identity());
    filter.keyframe_made({{1, 1}, {2, 2}}, {1.5f, std::numeric_limits<float>::quiet_NaN()});
  }
  ASSERT_EQ(filter.keyframes().size(), 3u);
  EXPECT_EQ(filter.keyframes().front().frame->id, 2);
  EXPECT_EQ(filter.keyframes().back().frame->id, 4);
  EXPECT_TRUE(filter.keyframes().back().frame->T_cw.has_value());
  EXPECT_EQ(filter.keyframes().back().depth, (std::vector<float>{1.5f, 0.0f}));
  filter.reset();
  EXPECT_TRUE(filter.keyframes().empty());
  EXPECT_EQ(filter.last_frame(), nullptr);
}

// ---------------------------------------------------------------- through the System

using test::rgbd_settings;

cv::Mat texture(int seed) {
  cv::Mat t(480, 640, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(t, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(t, t, cv::Size(5, 5), 1.2);
  return t;
}

TEST(SystemDynamic, LabelsDriveTheExclusionAndAreCounted) {
  SystemOptions o;
  o.synchronous_mapping = true;
  o.dynamic = DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n",
                                          "drop.yaml");
  System sys(rgbd_settings(), Sensor::kRGBD, o);
  EXPECT_TRUE(sys.dynamic_filter_enabled());
  const cv::Mat rgb = texture(1);
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(10000));
  cv::Mat labels = cv::Mat::zeros(480, 640, CV_8UC1);
  labels(cv::Rect(200, 100, 200, 250)).setTo(15);
  System plain(rgbd_settings(), Sensor::kRGBD);
  const TrackResult base = plain.track_rgbd(rgb, depth, 1.0);
  const TrackResult r = sys.track_rgbd(rgb, depth, 1.0, cv::Mat(), labels);
  EXPECT_TRUE(r.labels_used);
  EXPECT_NEAR(r.dynamic_fraction, 200.0 * 250 / (640 * 480), 1e-9);
  // dynamic_keypoints: exactly the keypoints an extraction without the mask keeps inside it.
  cv::Mat grey;
  cv::cvtColor(rgb, grey, rgbd_settings().camera.rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
  std::vector<cv::KeyPoint> keys;
  cv::Mat desc;
  features::OrbExtractor(rgbd_settings().extractor).extract(grey, cv::Mat(), keys, desc);
  int inside = 0;
  for (const cv::KeyPoint& k : keys) inside += labels.at<uchar>(cvRound(k.pt.y), cvRound(k.pt.x)) == 15;
  EXPECT_GT(inside, 50);
  EXPECT_EQ(r.dynamic_keypoints, inside);
  EXPECT_EQ(base.keypoints, static_cast<int>(keys.size()));
  for (const char* k : {"dynamic", "dynamic.semantic"}) EXPECT_TRUE(r.stage_ms.count(k)) << k;
  EXPECT_EQ(r.dynamic_values.at("semantic.regions"), 1);
  EXPECT_EQ(base.dynamic_keypoints, 0);
  EXPECT_FALSE(base.stage_ms.count("dynamic"));
  const cv::Mat m = sys.last_dynamic_mask();
  ASSERT_EQ(m.size(), labels.size());
  EXPECT_EQ(cv::countNonZero(m != (labels == 15)), 0);
  // Labels of a wrong size are counted and dropped.
  const TrackResult bad = sys.track_rgbd(rgb, depth, 2.0, cv::Mat(), cv::Mat::zeros(10, 10, CV_8UC1));
  EXPECT_FALSE(bad.labels_used);
  EXPECT_EQ(sys.counters().labels_dropped, 1);
  EXPECT_EQ(bad.dynamic_fraction, 0.0);
  // The dense frame: colour (BGR), depth in metres, the mask.
  const DenseFrame d = sys.dense_frame(false);
  EXPECT_EQ(d.colour.type(), CV_8UC3);
  EXPECT_EQ(d.depth.type(), CV_32FC1);
  EXPECT_FLOAT_EQ(d.depth.at<float>(0, 0), 2.0f);
  EXPECT_EQ(d.fx, 500);
}

// drop_unchecked_rgbd drops the first frame's candidates, unless what is
// left cannot start the map: then they are kept for that frame, and counted.
TEST(SystemDynamic, TheFirstFrameKeepsItsUncheckedCandidatesWhenTheMapNeedsThem) {
  SystemOptions o;
  o.synchronous_mapping = true;
  o.dynamic = DynamicFilterOptions::parse(
      "Dynamic.stages: [semantic]\n"
      "Dynamic.semantic: {policy: static_until_proven, margin: 0, drop_unchecked_rgbd: 1}\n", "du.yaml");
  const cv::Mat rgb = texture(1);
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(10000));
  System plain(rgbd_settings(), Sensor::kRGBD);
  const TrackResult base = plain.track_rgbd(rgb, depth, 1.0);
  ASSERT_GT(base.keypoints, 500);
  // A person over a quarter of the image: the rest starts the map without it.
  cv::Mat some = cv::Mat::zeros(480, 640, CV_8UC1);
  some(cv::Rect(200, 100, 200, 250)).setTo(15);
  System sys(rgbd_settings(), Sensor::kRGBD, o);
  const TrackResult r = sys.track_rgbd(rgb, depth, 1.0, cv::Mat(), some);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_EQ(r.dynamic_values.at("semantic.unchecked_dropped"), 1);
  EXPECT_FALSE(r.dynamic_values.count("semantic.unchecked_kept"));
  EXPECT_GT(r.dynamic_keypoints, 50);
  EXPECT_EQ(sys.counters().unchecked_kept, 0);
  // A view all movers but a strip: without them, too few keypoints for a map.
  cv::Mat most(480, 640, CV_8UC1, cv::Scalar(15));
  most(cv::Rect(0, 0, 640, 24)).setTo(0);
  System full(rgbd_settings(), Sensor::kRGBD, o);
  const TrackResult k = full.track_rgbd(rgb, depth, 1.0, cv::Mat(), most);
  EXPECT_EQ(k.state, TrackingState::kOk);
  EXPECT_EQ(k.dynamic_values.at("semantic.unchecked_dropped"), 1);
  EXPECT_EQ(k.dynamic_values.at("semantic.unchecked_kept"), 1);
  EXPECT_EQ(k.dynamic_keypoints, 0);
  EXPECT_EQ(k.dynamic_fraction, 0.0);
  EXPECT_EQ(k.keypoints, base.keypoints);  // the same extraction as without the filter
  EXPECT_EQ(full.counters().unchecked_kept, 1);
  EXPECT_EQ(full.counters().initializations, 1);
  EXPECT_EQ(cv::countNonZero(full.last_dynamic_mask()), 0);  // the mask says what tracking left out
  // The next frame has a previous one: its candidates stay static until proven, nothing is kept again.
  const TrackResult next = full.track_rgbd(rgb, depth, 2.0, cv::Mat(), most);
  EXPECT_EQ(next.state, TrackingState::kOk);
  EXPECT_FALSE(next.dynamic_values.count("semantic.unchecked_dropped"));
  EXPECT_EQ(full.counters().unchecked_kept, 1);
}

TEST(SystemDynamic, AFrameOfOnlyMovingObjectsDegrades) {
  SystemOptions o;
  o.synchronous_mapping = true;
  o.dynamic = DynamicFilterOptions::parse("Dynamic.stages: [semantic, dm]\nDynamic.semantic: {policy: drop}\n", "a");
  System sys(rgbd_settings(), Sensor::kRGBD, o);
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(10000));
  const cv::Mat person(480, 640, CV_8UC1, cv::Scalar(15));
  EXPECT_EQ(sys.track_rgbd(texture(1), depth, 1.0).state, TrackingState::kOk);
  const TrackResult r = sys.track_rgbd(texture(1), depth, 2.0, cv::Mat(), person);
  EXPECT_EQ(r.rejected, RejectReason::kNone);
  EXPECT_EQ(r.keypoints, 0);
  EXPECT_EQ(r.dynamic_fraction, 1.0);
  EXPECT_NE(r.state, TrackingState::kOk);
  EXPECT_EQ(sys.counters().dynamic_all_frames, 1);
  EXPECT_EQ(cv::countNonZero(sys.last_dynamic_mask()), 640 * 480);
  // And it recovers once the view clears.
  TrackResult after;
  for (int i = 3; i < 6; ++i) after = sys.track_rgbd(texture(1), depth, i);
  EXPECT_EQ(after.dynamic_fraction, 0.0);
  EXPECT_GT(after.keypoints, 100);
}

TEST(SystemDynamic, DenseFrameInpaintsFromKeyframes) {
  SystemOptions o;
  o.synchronous_mapping = true;
  o.dynamic = DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n",
                                          "inpaint.yaml");
  Settings settings = rgbd_settings();
  settings.camera.rgb = false;  // BGR input, kept as it is
  System sys(settings, Sensor::kRGBD, o);
  const cv::Mat rgb = texture(2);
  const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(10000));  // 2 m
  ASSERT_EQ(sys.track_rgbd(rgb, depth, 1.0).state, TrackingState::kOk);  // the first keyframe
  ASSERT_EQ(sys.track_rgbd(rgb, depth, 2.0).state, TrackingState::kOk);
  // A dark "person" 1 m from the camera covers a box.
  const cv::Rect box(250, 150, 120, 160);
  cv::Mat occluded = rgb.clone(), near = depth.clone(), labels = cv::Mat::zeros(480, 640, CV_8UC1);
  occluded(box).setTo(cv::Scalar(0, 0, 0));
  near(box).setTo(5000);
  labels(box).setTo(15);
  const TrackResult r = sys.track_rgbd(occluded, near, 3.0, cv::Mat(), labels);
  ASSERT_EQ(r.state, TrackingState::kOk);
  const DenseFrame raw = sys.dense_frame(false);
  EXPECT_FALSE(raw.inpainted);
  EXPECT_EQ(cv::countNonZero(raw.dynamic), box.area());
  ASSERT_TRUE(raw.T_wc.has_value());
  EXPECT_LT(raw.T_wc->translation().norm(), 0.01);  // the camera did not move
  EXPECT_FLOAT_EQ(raw.depth.at<float>(box.y + 10, box.x + 10), 1.0f);
  const DenseFrame d = sys.dense_frame(true);
  EXPECT_TRUE(d.inpainted);
  EXPECT_GT(d.inpainted_pixels, box.area() * 9 / 10);
  // The background the keyframe saw, not the person.
  cv::Mat diff;
  cv::absdiff(d.colour(box), rgb(box), diff);
  EXPECT_LT(cv::mean(diff)[0], 10.0);
  EXPECT_NEAR(d.depth.at<float>(box.y + 80, box.x + 60), 2.0f, 0.05f);
}

TEST(SystemDynamic, StereoMaskComesBackInInputPixels) {
  const std::filesystem::path cfg = std::filesystem::path(DYNAORB_SOURCE_DIR) / "config" / "EuRoC_stereo.yaml";
  const Settings settings = Settings::load(cfg.string());
  ASSERT_TRUE(settings.rectification.enabled());
  SystemOptions o;
  o.synchronous_mapping = true;
  o.dynamic = DynamicFilterOptions::parse("Dynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n",
                                          "s");
  System sys(settings, Sensor::kStereo, o);
  const cv::Size size(settings.rectification.width, settings.rectification.height);
  cv::Mat left(size, CV_8UC1), right(size, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(left, cv::RNG::UNIFORM, 0, 255);
  rng.fill(right, cv::RNG::UNIFORM, 0, 255);
  cv::Mat labels = cv::Mat::zeros(size, CV_8UC1);
  const cv::Rect box(300, 200, 120, 100);
  labels(box).setTo(7);
  const TrackResult r = sys.track_stereo(left, right, 1.0, cv::Mat(), labels);
  EXPECT_TRUE(r.labels_used);
  EXPECT_GT(r.dynamic_fraction, 0.0);
  const cv::Mat m = sys.last_dynamic_mask();
  ASSERT_EQ(m.size(), size);
  // Rectified and back: the box again, up to the resampling at its border.
  const cv::Mat in_box = labels == 7;
  const double overlap = cv::countNonZero(m & in_box) / static_cast<double>(cv::countNonZero(m | in_box));
  EXPECT_GT(overlap, 0.9);
  const DenseFrame d = sys.dense_frame(false);
  EXPECT_EQ(d.colour.size(), size);
  // Stereo depth by block matching, in the rectified image's pixels.
  EXPECT_EQ(d.depth.type(), CV_32FC1);
  EXPECT_EQ(d.depth.size(), d.colour.size());
}

}  // namespace
}  // namespace dynaorb::dynamic
