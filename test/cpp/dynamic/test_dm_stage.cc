// DM-SLAM's dynamic point detection on rendered views: a person crossing is
// dynamic and a parked car is not (RGB-D, stereo, monocular), a vehicle
// travelling with the camera is caught by the reprojection offset, regions
// split by class, the few-points policy, and every degenerate input.
#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "dynaorb/dynamic/candidate_regions.h"
#include "dynaorb/dynamic/dm_stage.h"
#include "dynaorb/dynamic/motion_cues.h"
#include "dynaorb/io/errors.h"
#include "synthetic_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

// The camera rises and moves forward a little: the epipolar lines run
// roughly vertically, so a person walking sideways crosses them.
const Eigen::Isometry3d kCamMotion = make_motion(0.3, 0.8, 0.0, {0.01, -0.06, 0.03});

constexpr unsigned char kCar = 7, kPerson = 15;

std::vector<TexturedQuad> base_scene() {
  std::vector<TexturedQuad> s;
  s.push_back(facing_quad({0, 0, 6}, 5, 4, 60, 11));
  s.push_back(floor_quad(1.2, 3.5, 5, 3.5, 80, 12));
  s.push_back(facing_quad({2.2, -0.3, 4.0}, 0.5, 0.6, 120, 13));  // a cupboard
  return s;
}

TexturedQuad parked_car() { return facing_quad({-1.4, 0.5, 3.5}, 0.8, 0.5, 120, 21, kCar); }
TexturedQuad person() { return facing_quad({0.5, 0.1, 2.2}, 0.3, 0.8, 200, 22, kPerson); }

cv::Mat candidates_of(const cv::Mat& labels) {
  cv::Mat c = (labels == kCar) | (labels == kPerson);
  cv::dilate(c, c, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
  return c;
}

Context make_context(Sensor sensor, std::shared_ptr<const map::Calibration> calib, FrameData& cur,
                     std::shared_ptr<const FrameData> prev) {
  return Context{sensor, std::move(calib), cur, std::move(prev), cv::Mat(), nullptr, nullptr, std::nullopt, nullptr, {}};
}

struct Case {
  std::shared_ptr<map::Calibration> calib;
  Sensor sensor = Sensor::kRGBD;
  std::shared_ptr<FrameData> prev;
  FrameData cur;
  RenderedView prev_view, cur_view;
  std::vector<TrackedPoint> points;
  EgoMotion ego;
  cv::Mat dynamic;

  // Runs the stage once on this pair (fresh dynamic mask).
  StageReport run(DmStage& stage, bool with_previous = true) {
    Context ctx = make_context(sensor, calib, cur, with_previous ? prev : nullptr);
    ctx.dynamic = cv::Mat(cur.grey.size(), CV_8UC1, cv::Scalar(0));
    ctx.tracked = &points;
    ctx.ego = &ego;
    StageReport r;
    stage.process(ctx, r);
    dynamic = ctx.dynamic;
    return r;
  }

  // Share of the current pixels of class `label` marked dynamic.
  double marked(unsigned char label) const {
    const cv::Mat px = cur_view.labels == label;
    const int n = cv::countNonZero(px);
    return n ? cv::countNonZero(px & dynamic) / static_cast<double>(n) : -1;
  }
};

FrameData frame_of(const RenderedView& v, Sensor sensor, long id) {
  FrameData f;
  f.id = id;
  f.grey = v.grey;
  if (sensor == Sensor::kRGBD) f.depth = v.depth;
  f.labels = v.labels;
  f.candidates = candidates_of(v.labels);
  return f;
}

Case make_case(Sensor sensor, const std::vector<TexturedQuad>& prev_scene,
               const std::vector<TexturedQuad>& cur_scene, const cv::Mat& dist = cv::Mat()) {
  Case c;
  c.sensor = sensor;
  c.calib = make_calibration(sensor, 640, 480, 500, 0.1, dist);
  c.prev_view = render(prev_scene, Eigen::Isometry3d::Identity(), *c.calib);
  c.cur_view = render(cur_scene, kCamMotion, *c.calib);
  c.prev = std::make_shared<FrameData>(frame_of(c.prev_view, sensor, 0));
  c.cur = frame_of(c.cur_view, sensor, 1);
  if (sensor == Sensor::kStereo) {
    Eigen::Isometry3d T_rl = Eigen::Isometry3d::Identity();
    T_rl.translation() = Eigen::Vector3d(-c.calib->baseline, 0, 0);
    c.prev->right = render(prev_scene, T_rl, *c.calib).grey;
    c.cur.right = render(cur_scene, T_rl * kCamMotion, *c.calib).grey;
  }
  const MotionCueOptions mo;
  c.points = track_points(*c.prev, c.cur, *c.calib, sensor, mo);
  c.ego = estimate_ego_motion(c.points, *c.calib, sensor, mo);
  return c;
}

// A person crossing (6 cm between frames, 2.2 m away) and a parked car:
// the previous and the current scene.
std::pair<std::vector<TexturedQuad>, std::vector<TexturedQuad>> crossing_scenes() {
  std::vector<TexturedQuad> prev_scene = base_scene(), cur_scene = base_scene();
  prev_scene.push_back(parked_car());
  cur_scene.push_back(parked_car());
  TexturedQuad p = person();
  prev_scene.push_back(p);
  p.T_wq.translation().x() += 0.06;
  cur_scene.push_back(p);
  return {prev_scene, cur_scene};
}

Case crossing_case(Sensor sensor, const cv::Mat& dist = cv::Mat()) {
  const auto [prev_scene, cur_scene] = crossing_scenes();
  return make_case(sensor, prev_scene, cur_scene, dist);
}

class DmCrossing : public ::testing::TestWithParam<Sensor> {};

TEST_P(DmCrossing, MovingPersonIsDynamicParkedCarStaysStatic) {
  Case c = crossing_case(GetParam());
  ASSERT_TRUE(GetParam() == Sensor::kMono ? c.ego.has_F : c.ego.valid);
  DmStage stage;
  const StageReport r = c.run(stage);
  EXPECT_EQ(r.values.count("skipped_no_previous"), 0u);
  EXPECT_EQ(r.values.at("regions"), 2);
  EXPECT_EQ(r.regions, 1);
  EXPECT_GT(c.marked(kPerson), 0.99);
  EXPECT_EQ(c.marked(kCar), 0.0);
  EXPECT_GT(r.values.at("dynamic_points"), 20);
  EXPECT_FALSE(r.dynamic_points.empty());
  EXPECT_FALSE(r.static_points.empty());
  // Nothing outside the candidate regions is ever marked.
  EXPECT_EQ(cv::countNonZero(c.dynamic & ~c.cur.candidates), 0);
  if (GetParam() != Sensor::kMono) {
    ASSERT_TRUE(r.values.count("phi_s"));
    // Eq. 6-7: the normalised terms of the static set each sum to 1.
    EXPECT_NEAR(r.values.at("phi_s") * r.values.at("static_set_points"), 2.0, 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(Sensors, DmCrossing,
                         ::testing::Values(Sensor::kRGBD, Sensor::kStereo, Sensor::kMono),
                         [](const auto& info) { return to_string(info.param); });

// TUM-like lens distortion: the stage judges undistorted pixels.
TEST(DmStage, DistortedImages) {
  const cv::Mat dist = (cv::Mat_<double>(1, 5) << -0.28, 0.09, 0.001, -0.0008, 0.0);
  for (Sensor s : {Sensor::kRGBD, Sensor::kMono}) {
    Case c = crossing_case(s, dist);
    DmStage stage;
    const StageReport r = c.run(stage);
    EXPECT_EQ(r.regions, 1) << to_string(s);
    EXPECT_GT(c.marked(kPerson), 0.99) << to_string(s);
    EXPECT_EQ(c.marked(kCar), 0.0) << to_string(s);
  }
}

TEST(DmStage, NothingMovesNothingIsMarked) {
  std::vector<TexturedQuad> scene = base_scene();
  scene.push_back(parked_car());
  scene.push_back(person());
  for (Sensor s : {Sensor::kRGBD, Sensor::kMono}) {
    Case c = make_case(s, scene, scene);
    DmStage stage;
    const StageReport r = c.run(stage);
    EXPECT_EQ(r.regions, 0) << to_string(s);
    EXPECT_EQ(cv::countNonZero(c.dynamic), 0) << to_string(s);
  }
}

// A vehicle that travels with the camera stays still in the image: the
// epipolar constraint holds for it, the reprojection with depth does not.
TEST(DmStage, VehicleTravellingWithTheCameraIsCaughtByTheReprojectionOffset) {
  std::vector<TexturedQuad> prev_scene = base_scene(), cur_scene = base_scene();
  TexturedQuad vehicle = facing_quad({-0.6, 0.3, 2.5}, 0.7, 0.6, 150, 31, kCar);
  prev_scene.push_back(vehicle);
  vehicle.T_wq = kCamMotion.inverse() * vehicle.T_wq;
  cur_scene.push_back(vehicle);
  for (Sensor s : {Sensor::kRGBD, Sensor::kStereo}) {
    Case c = make_case(s, prev_scene, cur_scene);
    DmStage stage;
    const StageReport r = c.run(stage);
    EXPECT_EQ(r.regions, 1) << to_string(s);
    EXPECT_GT(c.marked(kCar), 0.99) << to_string(s);
  }
}

TEST(DmStage, FewPointsPolicy) {
  Case c = crossing_case(Sensor::kRGBD);
  // The next frame sees the same regions but no tracked point on the person.
  std::vector<TrackedPoint> without_person;
  for (const auto& t : c.points)
    if (c.cur_view.labels.at<unsigned char>(cvRound(t.cur.y), cvRound(t.cur.x)) != kPerson)
      without_person.push_back(t);

  DmStage keep;  // default: "previous"
  ASSERT_EQ(c.run(keep).regions, 1);
  auto next = std::make_shared<FrameData>(c.cur);
  Case d = c;
  d.prev = next;
  d.cur.id = 2;
  d.points = without_person;
  StageReport r = d.run(keep);
  EXPECT_EQ(r.values.at("regions_few_points"), 1);
  EXPECT_EQ(r.values.at("regions_few_points_dynamic"), 1);
  EXPECT_GT(d.marked(kPerson), 0.99);
  EXPECT_EQ(d.marked(kCar), 0.0);

  // The memory speaks only for the frame right before.
  DmStage stale;
  ASSERT_EQ(c.run(stale).regions, 1);
  Case e = d;
  e.prev = std::make_shared<FrameData>(c.cur);
  const_cast<FrameData&>(*e.prev).id = 7;
  EXPECT_EQ(e.run(stale).regions, 0);

  DmOptions o;
  o.few_points_policy = "static";
  DmStage forget(o);
  ASSERT_EQ(c.run(forget).regions, 1);
  r = d.run(forget);
  EXPECT_EQ(r.regions, 0);
  EXPECT_EQ(r.values.at("regions_few_points"), 1);

  o.few_points_policy = "dynamic";
  DmStage cautious(o);
  r = d.run(cautious);  // no memory needed
  EXPECT_EQ(r.regions, 1);
  EXPECT_GT(d.marked(kPerson), 0.99);

  // reset() forgets.
  keep.reset();
  EXPECT_EQ(d.run(keep).regions, 0);
}

// keep_moving_frames(_mono): a region proven moving stays dynamic while
// later frames' points only fail to prove it (as the monocular epipolar test
// does for motion along the epipolar lines), for a limited number of frames.
TEST(DmStage, ARegionProvenMovingIsKeptForSomeFrames) {
  const auto [prev_scene, cur_scene] = crossing_scenes();
  for (Sensor s : {Sensor::kMono, Sensor::kRGBD}) {
    Case moving = make_case(s, prev_scene, cur_scene);
    // The same current image, but the person stands still since the frame before.
    Case still = make_case(s, cur_scene, cur_scene);
    DmOptions o;
    o.keep_moving_frames_mono = 2;
    DmStage stage(o);
    ASSERT_EQ(moving.run(stage).regions, 1) << to_string(s);
    for (long id = 2; id <= 4; ++id) {
      auto prev = std::make_shared<FrameData>(*still.prev);
      prev->id = id - 1;
      still.prev = prev;
      still.cur.id = id;
      const StageReport r = still.run(stage);
      const bool kept = s == Sensor::kMono && id <= 3;  // RGB-D: keep_moving_frames 0
      EXPECT_EQ(r.values.at("regions_kept_moving"), kept ? 1 : 0) << to_string(s) << " frame " << id;
      EXPECT_EQ(r.regions, kept ? 1 : 0) << to_string(s) << " frame " << id;
      EXPECT_EQ(still.marked(kPerson) > 0.99, kept) << to_string(s) << " frame " << id;
      EXPECT_EQ(still.marked(kCar), 0.0);
    }
  }
}

TEST(DmStage, DegenerateInputMarksNothingAndSaysWhy) {
  Case c = crossing_case(Sensor::kRGBD);
  DmStage stage;
  auto expect_skip = [&](Case& k, const char* why, bool with_previous = true) {
    const StageReport r = k.run(stage, with_previous);
    EXPECT_EQ(r.values.count(why), 1u) << why;
    EXPECT_EQ(r.regions, 0) << why;
    EXPECT_EQ(cv::countNonZero(k.dynamic), 0) << why;
  };
  expect_skip(c, "skipped_no_previous", false);

  Case k = c;
  k.cur.candidates = cv::Mat();
  expect_skip(k, "skipped_no_candidates");
  k.cur.candidates = cv::Mat(480, 640, CV_8UC1, cv::Scalar(0));
  expect_skip(k, "skipped_no_candidates");

  k = c;
  k.points.clear();
  expect_skip(k, "skipped_no_points");

  k = c;
  k.ego.valid = false;
  expect_skip(k, "skipped_no_ego_motion");

  {
    Case m = c;
    Context ctx = make_context(m.sensor, m.calib, m.cur, m.prev);
    StageReport r;
    stage.process(ctx, r);
    EXPECT_EQ(r.values.count("skipped_no_motion_cues"), 1u);
    ctx.tracked = &m.points;
    ctx.ego = &m.ego;
    ctx.dynamic = cv::Mat(10, 10, CV_8UC1, cv::Scalar(0));
    StageReport r2;
    stage.process(ctx, r2);
    EXPECT_EQ(r2.values.count("skipped_bad_dynamic_mask"), 1u);
    ctx.calib = nullptr;
    StageReport r3;
    stage.process(ctx, r3);
    EXPECT_EQ(r3.values.count("skipped_no_calibration"), 1u);
  }

  // A frame that is all moving objects: no static points, no ego-motion.
  k = c;
  k.cur.candidates = cv::Mat(480, 640, CV_8UC1, cv::Scalar(255));
  k.prev = std::make_shared<FrameData>(*c.prev);
  const_cast<FrameData&>(*k.prev).candidates = k.cur.candidates;
  k.points = track_points(*k.prev, k.cur, *k.calib, k.sensor, MotionCueOptions());
  k.ego = estimate_ego_motion(k.points, *k.calib, k.sensor, MotionCueOptions());
  EXPECT_FALSE(k.ego.valid);
  expect_skip(k, "skipped_no_ego_motion");
  // ... and if an ego-motion came from elsewhere, too few static offsets.
  k.ego = c.ego;
  expect_skip(k, "skipped_few_static_points");

  // No depth anywhere (points tracked, none with depth): nothing to judge.
  k = c;
  for (auto& t : k.points) t.prev_depth = 0;
  expect_skip(k, "skipped_few_static_points");

  // NaN positions and depths are counted, not fatal.
  k = c;
  for (size_t i = 0; i < k.points.size(); i += 5) k.points[i].cur.x = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = 1; i < k.points.size(); i += 5) k.points[i].prev_depth = std::numeric_limits<float>::quiet_NaN();
  const StageReport r = k.run(stage);
  EXPECT_GT(r.values.at("points_non_finite"), 0);
  EXPECT_EQ(r.regions, 1);

  // Empty dynamic mask in the context: the stage makes one.
  {
    Case m = c;
    Context ctx = make_context(m.sensor, m.calib, m.cur, m.prev);
    ctx.tracked = &m.points;
    ctx.ego = &m.ego;
    StageReport r4;
    stage.process(ctx, r4);
    ASSERT_EQ(ctx.dynamic.size(), m.cur.grey.size());
    EXPECT_EQ(r4.regions, 1);
  }
}

TEST(CandidateRegions, TouchingClassesAreSeparateObjects) {
  cv::Mat labels(100, 200, CV_8UC1, cv::Scalar(0));
  labels(cv::Rect(20, 20, 60, 60)).setTo(kPerson);
  labels(cv::Rect(80, 30, 60, 50)).setTo(kCar);  // touches the person
  labels(cv::Rect(160, 10, 20, 20)).setTo(kPerson);  // a second person, apart
  cv::Mat cand;
  cv::dilate(labels > 0, cand, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  const CandidateRegions split = candidate_regions(cand, labels, true);
  EXPECT_EQ(split.count, 3);
  ASSERT_EQ(split.label.size(), 3u);
  EXPECT_EQ(std::count(split.label.begin(), split.label.end(), kPerson), 2);
  EXPECT_NE(split.ids.at<int>(50, 50), split.ids.at<int>(50, 100));
  EXPECT_EQ(split.ids.at<int>(50, 18), split.ids.at<int>(50, 50));  // margin pixel: nearest class
  EXPECT_EQ(split.ids.at<int>(50, 141), split.ids.at<int>(50, 100));
  int total = 0;
  for (int p : split.pixels) total += p;
  EXPECT_EQ(total, cv::countNonZero(cand));

  const CandidateRegions merged = candidate_regions(cand, labels, false);
  EXPECT_EQ(merged.count, 2);
  const CandidateRegions no_labels = candidate_regions(cand, cv::Mat(), true);
  EXPECT_EQ(no_labels.count, 2);
  EXPECT_EQ(candidate_regions(cv::Mat(), labels, true).count, 0);
  EXPECT_EQ(candidate_regions(cv::Mat(10, 10, CV_32FC1, cv::Scalar(1)), cv::Mat(), true).count, 0);
}

// nearest_class is the per-class rule (one 5x5 chamfer distance transform per
// class, a running minimum, ties to the lower id) pixel for pixel, on random
// scenes of blobs, stripes and single pixels of up to four classes, with
// ties on purpose (classes placed symmetrically) and a class far away.
TEST(CandidateRegions, NearestClassIsTheClassOfTheNearestTransform) {
  std::mt19937 rng(7);
  const std::vector<unsigned char> classes = {2, 7, 15, 19};
  for (int scene = 0; scene < 40; ++scene) {
    const int w = 40 + static_cast<int>(rng() % 300), h = 40 + static_cast<int>(rng() % 300);
    cv::Mat lab(h, w, CV_8UC1, cv::Scalar(0));
    const int n_classes = 2 + static_cast<int>(rng() % 3);
    std::vector<unsigned char> present(classes.begin(), classes.begin() + n_classes);
    for (int k = 0; k < 12; ++k) {
      const unsigned char c = present[rng() % present.size()];
      const int x = static_cast<int>(rng() % w), y = static_cast<int>(rng() % h);
      switch (rng() % 3) {
        case 0: cv::circle(lab, {x, y}, 1 + static_cast<int>(rng() % 20), cv::Scalar(c), cv::FILLED); break;
        case 1: cv::line(lab, {x, y}, {static_cast<int>(rng() % w), static_cast<int>(rng() % h)}, cv::Scalar(c)); break;
        default: lab.at<unsigned char>(y, x) = c;
      }
    }
    // Mirror-image pixels of two classes: equal distances along the middle.
    lab.at<unsigned char>(h / 2, w / 4) = present[1];
    lab.at<unsigned char>(h / 2, w - 1 - w / 4) = present[0];
    lab.at<unsigned char>(0, 0) = 3;  // a class not asked about: no source
    std::vector<unsigned char> asked;
    for (unsigned char c : present)
      if (cv::countNonZero(lab == c) > 0) asked.push_back(c);
    const cv::Mat expected = nearest_class_by_transforms(lab, asked);
    const cv::Mat everywhere(lab.size(), CV_8UC1, cv::Scalar(255));
    const cv::Mat got = nearest_class(lab, asked, everywhere);
    ASSERT_EQ(cv::countNonZero(got != expected), 0) << "scene " << scene << " (" << w << "x" << h << ")";
  }
}

// candidate_blobs gives connectedComponentsWithStats' labels, areas and
// bounding boxes (it leaves the centroids out), on random masks of discs,
// lines and single pixels, on an empty mask and on a mask of all ones (no
// background: its row is zero).
TEST(CandidateRegions, BlobsAreConnectedComponentsWithStats) {
  std::mt19937 rng(11);
  std::vector<cv::Mat> masks = {cv::Mat::zeros(30, 40, CV_8UC1), cv::Mat(30, 40, CV_8UC1, cv::Scalar(255))};
  for (int scene = 0; scene < 40; ++scene) {
    const int w = 20 + static_cast<int>(rng() % 400), h = 20 + static_cast<int>(rng() % 300);
    cv::Mat m(h, w, CV_8UC1, cv::Scalar(0));
    for (int k = 0; k < 15; ++k) {
      const int x = static_cast<int>(rng() % w), y = static_cast<int>(rng() % h);
      switch (rng() % 3) {
        case 0: cv::circle(m, {x, y}, 1 + static_cast<int>(rng() % 40), cv::Scalar(255), cv::FILLED); break;
        case 1: cv::line(m, {x, y}, {static_cast<int>(rng() % w), static_cast<int>(rng() % h)}, cv::Scalar(1)); break;
        default: m.at<unsigned char>(y, x) = 7;
      }
    }
    masks.push_back(m);
  }
  for (size_t i = 0; i < masks.size(); ++i) {
    cv::Mat comp, stats, centroids;
    const int n = cv::connectedComponentsWithStats(masks[i], comp, stats, centroids, 8, CV_32S);
    const CandidateBlobs b = candidate_blobs(masks[i]);
    ASSERT_EQ(b.count, n - 1) << "mask " << i;
    ASSERT_EQ(cv::countNonZero(b.comp != comp), 0) << "mask " << i;
    ASSERT_EQ(b.stats.rows, n);
    const bool all_ones = cv::countNonZero(masks[i]) == static_cast<int>(masks[i].total());
    for (int r = all_ones ? 1 : 0; r < n; ++r)
      for (int k = 0; k < cv::CC_STAT_MAX; ++k)
        ASSERT_EQ(b.stats.at<int>(r, k), stats.at<int>(r, k)) << "mask " << i << " label " << r << " stat " << k;
    if (all_ones) { EXPECT_EQ(b.stats.at<int>(0, cv::CC_STAT_AREA), 0); }
  }
  EXPECT_EQ(candidate_blobs(cv::Mat()).count, 0);
  EXPECT_EQ(candidate_blobs(cv::Mat(10, 10, CV_32FC1, cv::Scalar(1))).count, 0);
}

// The memo gives what candidate_regions gives, once per distinct input:
// the same pixels in another buffer are the same input, other pixels are not.
TEST(CandidateRegions, MemoCutsEqualInputsOnce) {
  cv::Mat labels(100, 200, CV_8UC1, cv::Scalar(0));
  labels(cv::Rect(20, 20, 60, 60)).setTo(kPerson);
  labels(cv::Rect(80, 30, 60, 50)).setTo(kCar);
  cv::Mat cand;
  cv::dilate(labels > 0, cand, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  RegionsMemo memo;
  const CandidateRegions& a = memo.get(cand, labels, true);
  const CandidateRegions direct = candidate_regions(cand, labels, true);
  ASSERT_EQ(a.count, direct.count);
  EXPECT_EQ(cv::countNonZero(a.ids != direct.ids), 0);
  const CandidateRegions& b = memo.get(cand.clone(), labels.clone(), true);
  EXPECT_EQ(&a, &b);
  const CandidateRegions& merged = memo.get(cand, labels, false);
  EXPECT_NE(&merged, &a);
  EXPECT_EQ(merged.count, 1);
  cv::Mat other = labels.clone();
  other(cv::Rect(80, 30, 60, 50)).setTo(kPerson);  // one class now: one object
  const CandidateRegions& c = memo.get(cand, other, true);
  EXPECT_NE(&c, &a);
  EXPECT_EQ(c.count, 1);
  EXPECT_EQ(a.count, 2);  // the first answer is still there
}

TEST(DmStage, OptionsReadFromYaml) {
  cv::FileStorage fs(
      "%YAML:1.0\ndm:\n  epipolar_threshold_px: 2\n  few_points_policy: static\n  split_by_label: 0\n"
      "  keep_moving_frames: 3\n  keep_moving_overlap: 0.8\n"
      "bad:\n  few_points_policy: sometimes\nbad_type:\n  min_region_points: 2.5\n"
      "bad_keep:\n  keep_moving_frames_mono: -1\nbad_overlap:\n  keep_moving_overlap: 0\n",
      cv::FileStorage::READ | cv::FileStorage::MEMORY);
  DmOptions o;
  o.read(fs["dm"]);
  EXPECT_DOUBLE_EQ(o.epipolar_threshold_px, 2.0);
  EXPECT_EQ(o.few_points_policy, "static");
  EXPECT_FALSE(o.split_by_label);
  EXPECT_EQ(o.keep_moving_frames, 3);
  EXPECT_EQ(o.keep_moving_frames_mono, DmOptions().keep_moving_frames_mono);
  EXPECT_DOUBLE_EQ(o.keep_moving_overlap, 0.8);
  EXPECT_DOUBLE_EQ(o.region_dynamic_fraction, DmOptions().region_dynamic_fraction);
  DmOptions b;
  EXPECT_THROW(b.read(fs["bad"]), InputError);
  DmOptions t;
  EXPECT_THROW(t.read(fs["bad_type"]), InputError);
  DmOptions k;
  EXPECT_THROW(k.read(fs["bad_keep"]), InputError);
  EXPECT_THROW(k.read(fs["bad_overlap"]), InputError);
  DmStage s(o);
  EXPECT_EQ(s.name(), "dm");
  EXPECT_TRUE(s.needs_motion_cues());
  for (Sensor sensor : {Sensor::kMono, Sensor::kStereo, Sensor::kRGBD}) EXPECT_TRUE(s.supports(sensor));
}

}  // namespace
}  // namespace dynaorb::dynamic
