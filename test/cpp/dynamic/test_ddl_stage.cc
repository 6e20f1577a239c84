// DDL-SLAM's multi-view geometry stage on rendered views of a known room:
// a box crossing in front of the camera and a box receding with the camera
// are found, the static room is not (also where the camera's motion hides
// background behind static boxes), the pose sources, the semantic union,
// degenerate input and option reading.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "dynaorb/dynamic/ddl_stage.h"
#include "dynaorb/io/errors.h"
#include "synthetic_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

constexpr int kW = 320, kH = 240;
constexpr double kF = 250;

struct View {
  std::shared_ptr<FrameData> frame;
  cv::Mat mover;  // CV_8UC1 255 on the moving box (the truth)
};

Eigen::Isometry3d camera_at(const Eigen::Vector3d& centre) {
  Eigen::Isometry3d T_wc = Eigen::Isometry3d::Identity();
  T_wc.translation() = centre;
  return T_wc.inverse();
}

// The room of synthetic_scene.h with textures no finer than the pixels
// they are seen at (the ray caster does not filter textures, and a floor
// minified at a grazing angle aliases differently in every view, which no
// camera does), and an optional moving box (a textured quad facing the
// camera, label 15) at `mover_centre`.
std::vector<TexturedQuad> scene(const std::optional<Eigen::Vector3d>& mover_centre) {
  std::vector<TexturedQuad> s;
  s.push_back(facing_quad({0, 0, 6}, 5, 4, 40, 3));
  s.push_back(floor_quad(1.2, 3.5, 5, 3.5, 25, 4));
  s.push_back(facing_quad({-1.25, 0.35, 3.0}, 0.75, 0.85, 80, 5));
  s.push_back(facing_quad({1.0, 0.3, 2.2}, 0.5, 0.6, 100, 6));
  if (mover_centre) s.push_back(facing_quad(*mover_centre, 0.35, 0.6, 200, 77, 15));
  return s;
}

View make_view(long id, const std::vector<TexturedQuad>& quads, const Eigen::Isometry3d& T_cw,
               const map::Calibration& calib) {
  const RenderedView rv = render(quads, T_cw, calib);
  View v;
  v.frame = std::make_shared<FrameData>();
  v.frame->id = id;
  v.frame->grey = rv.grey;
  v.frame->depth = rv.depth;
  v.mover = rv.labels == 15;
  return v;
}

// A keyframe as SLAM makes it: pose, depth, its dynamic mask, and corners
// with depth outside that mask.
KeyFrameData make_keyframe(const View& v, const Eigen::Isometry3d& T_cw, bool mask_mover) {
  auto f = std::make_shared<FrameData>(*v.frame);
  f->T_cw = T_cw;
  f->dynamic = mask_mover ? v.mover.clone() : cv::Mat(v.mover.size(), CV_8UC1, cv::Scalar(0));
  KeyFrameData kf;
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(f->grey, corners, 600, 0.01, 5, ~f->dynamic);
  for (const cv::Point2f& c : corners) {
    kf.keypoints.push_back(c);
    kf.depth.push_back(f->depth.at<float>(cvRound(c.y), cvRound(c.x)));
  }
  kf.frame = f;
  return kf;
}

struct Outcome {
  double mover_coverage = 0;  // share of the mover's pixels marked
  double static_marked = 0;   // share of the other pixels marked
  StageReport report;
  cv::Mat dynamic;
};

Outcome evaluate(Context& ctx, DdlStage& stage, const cv::Mat& mover) {
  Outcome out;
  stage.process(ctx, out.report);
  out.dynamic = ctx.dynamic;
  const int n_mover = cv::countNonZero(mover);
  const int n_static = static_cast<int>(mover.total()) - n_mover;
  out.mover_coverage = n_mover ? cv::countNonZero(ctx.dynamic & mover) / static_cast<double>(n_mover) : 0.0;
  out.static_marked = cv::countNonZero(ctx.dynamic & ~mover) / static_cast<double>(n_static);
  return out;
}

// Keyframes 0..4 and the current frame 6 of a camera moving forward and to
// the right; the box's centre at step k is mover(k).
struct Sequence {
  std::shared_ptr<map::Calibration> calib;
  std::vector<KeyFrameData> keyframes;
  View current;
  Eigen::Isometry3d T_cw_current;
};

template <typename MoverAt, typename CameraAt>
Sequence make_sequence(MoverAt mover, CameraAt camera, bool mask_mover_in_keyframes, cv::Mat dist = cv::Mat()) {
  Sequence s;
  s.calib = make_calibration(Sensor::kRGBD, kW, kH, kF, 0.1, dist);
  for (int k = 0; k <= 4; ++k) {
    const Eigen::Isometry3d T_cw = camera_at(camera(k));
    const View v = make_view(k, scene(mover(k)), T_cw, *s.calib);
    s.keyframes.push_back(make_keyframe(v, T_cw, mask_mover_in_keyframes));
  }
  s.T_cw_current = camera_at(camera(6));
  s.current = make_view(6, scene(mover(6)), s.T_cw_current, *s.calib);
  return s;
}

Sequence crossing_box(cv::Mat dist = cv::Mat()) {
  return make_sequence([](int k) { return std::optional<Eigen::Vector3d>({-0.9 + 0.15 * k, 0.2, 2.0}); },
                       [](int k) { return Eigen::Vector3d(0.03 * k, 0, 0.05 * k); }, true, dist);
}

// Every member named: Context is an aggregate with a reference member.
Context make_context(Sequence& s) {
  return Context{Sensor::kRGBD, s.calib, *s.current.frame, nullptr, cv::Mat(kH, kW, CV_8UC1, cv::Scalar(0)),
                 nullptr,       nullptr, s.T_cw_current,    &s.keyframes, {}};
}

// A fresh stage with `options` on the sequence's current frame.
Outcome evaluate_with(Sequence& s, const DdlOptions& options) {
  Context ctx = make_context(s);
  DdlStage stage(options);
  return evaluate(ctx, stage, s.current.mover);
}

TEST(DdlStage, CrossingBoxIsFoundStaticRoomIsNot) {
  Sequence s = crossing_box();
  Context ctx = make_context(s);
  DdlStage stage;
  const Outcome o = evaluate(ctx, stage, s.current.mover);
  EXPECT_GT(o.mover_coverage, 0.85);
  EXPECT_LT(o.static_marked, 0.01);
  EXPECT_EQ(o.report.values.at("keyframes_used"), 5);
  EXPECT_EQ(o.report.values.at("pose_source"), 3);
  EXPECT_EQ(o.report.values.at("tau_d_m"), 0.4);
  EXPECT_EQ(o.report.values.at("tau_alpha_deg"), 30);
  EXPECT_GT(o.report.values.at("region_pixels"), 0);
  // The dynamic points lie on the box; the static ones mostly elsewhere.
  ASSERT_GT(o.report.dynamic_points.size(), 10u);
  int on_mover = 0;
  for (const cv::Point2f& p : o.report.dynamic_points) on_mover += s.current.mover.at<unsigned char>(p) != 0;
  EXPECT_GT(on_mover, 0.95 * o.report.dynamic_points.size());
  int static_off_mover = 0;
  for (const cv::Point2f& p : o.report.static_points) static_off_mover += s.current.mover.at<unsigned char>(p) == 0;
  EXPECT_GT(static_off_mover, 0.95 * o.report.static_points.size());
}

// The keyframes' prepared images (depth windows, grey, LK pyramids) are
// kept between frames: a second frame, a reset, a fresh stage and a changed
// keyframe list all give what a fresh stage gives.
TEST(DdlStage, KeptKeyframeImagesGiveTheSameAnswer) {
  Sequence s = crossing_box();
  const auto mask_of = [&](DdlStage& stage) {
    Context ctx = make_context(s);
    StageReport rep;
    stage.process(ctx, rep);
    return std::make_pair(ctx.dynamic.clone(), rep);
  };
  DdlStage kept;
  const auto first = mask_of(kept);
  ASSERT_GT(cv::countNonZero(first.first), 0);
  EXPECT_GT(first.second.values.at("evidence_build_ms"), 0);
  for (const char* k : {"refine_ms", "check_ms", "grow_ms"}) EXPECT_TRUE(first.second.values.count(k)) << k;
  const auto second = mask_of(kept);
  EXPECT_EQ(cv::countNonZero(first.first != second.first), 0);
  EXPECT_EQ(first.second.dynamic_points, second.second.dynamic_points);
  kept.reset();
  EXPECT_EQ(cv::countNonZero(first.first != mask_of(kept).first), 0);
  // One keyframe gone: the kept stage answers as a fresh one does.
  s.keyframes.erase(s.keyframes.begin() + 1);
  DdlStage fresh;
  EXPECT_EQ(cv::countNonZero(mask_of(fresh).first != mask_of(kept).first), 0);
}

TEST(DdlStage, DistortedImagesGiveTheSameAnswer) {
  Sequence s = crossing_box((cv::Mat_<double>(1, 5) << 0.12, -0.2, 0.001, -0.0015, 0.05));
  Context ctx = make_context(s);
  DdlStage stage;
  const Outcome o = evaluate(ctx, stage, s.current.mover);
  EXPECT_GT(o.mover_coverage, 0.85);
  EXPECT_LT(o.static_marked, 0.01);
}

TEST(DdlStage, BoxRecedingWithTheCameraNeedsVanishedPoints) {
  // The box drives straight ahead of the camera at its speed (a car
  // followed on a road): its image never changes and the static scene
  // around it expands away from it, so no old keypoint ever ends up behind
  // it (Algorithm 1's Delta z > tau_d); its own old points are seen through
  // instead.
  auto mover = [](int k) { return std::optional<Eigen::Vector3d>({0.0, 0.0, 2.2 + 0.12 * k}); };
  auto camera = [](int k) { return Eigen::Vector3d(0, 0, 0.12 * k); };
  Sequence s = make_sequence(mover, camera, false);
  {
    Context ctx = make_context(s);
    DdlStage stage;
    const Outcome o = evaluate(ctx, stage, s.current.mover);
    EXPECT_GT(o.mover_coverage, 0.6);
    EXPECT_LT(o.static_marked, 0.01);
    EXPECT_GT(o.report.values.at("vanished"), 0);
  }
  {
    Context ctx = make_context(s);
    DdlOptions printed;
    printed.vanished_points_dynamic = false;
    DdlStage stage(printed);
    const Outcome o = evaluate(ctx, stage, s.current.mover);
    EXPECT_LT(o.mover_coverage, 0.1);
    EXPECT_EQ(o.report.values.at("vanished"), 0);
  }
}

// The side of a vehicle driving beside the camera, faster than it: a
// surface sliding along itself. Its old keypoints land on it again at their
// own depth (neither depth test fires); only other texture at that depth
// tells that it moved.
TEST(DdlStage, SideOfAVehicleBesideTheCameraNeedsSlidingSurfaces) {
  const Eigen::Matrix3d side = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
  auto vehicle = [&](int k) {
    // The room without its left box, which would hide the vehicle.
    std::vector<TexturedQuad> s = scene(std::nullopt);
    s.erase(s.begin() + 2);
    s.push_back(make_quad({-0.6, 0.3, 2.6 + 0.2 * k}, side, 4.0, 0.4, 100, 78, 15));
    return s;
  };
  auto camera = [](int k) { return Eigen::Vector3d(0, 0, 0.08 * k); };
  Sequence s;
  s.calib = make_calibration(Sensor::kRGBD, kW, kH, kF, 0.1);
  for (int k = 0; k <= 4; ++k) {
    const Eigen::Isometry3d T_cw = camera_at(camera(k));
    s.keyframes.push_back(make_keyframe(make_view(k, vehicle(k), T_cw, *s.calib), T_cw, false));
  }
  s.T_cw_current = camera_at(camera(6));
  s.current = make_view(6, vehicle(6), s.T_cw_current, *s.calib);
  ASSERT_GT(cv::countNonZero(s.current.mover), 0.02 * kW * kH);
  const auto on_vehicle = [&](const StageReport& r) {
    int n = 0;
    for (const cv::Point2f& p : r.dynamic_points) n += s.current.mover.at<unsigned char>(p) != 0;
    return n;
  };
  DdlOptions sliding;
  sliding.seed_sliding_surfaces = true;
  const Outcome on = evaluate_with(s, sliding);
  const Outcome off = evaluate_with(s, DdlOptions());
  std::printf("vehicle side: %d / %d dynamic points with / without sliding surfaces (%g sliding), "
              "marked %.3f / %.3f, static marked %.4f / %.4f\n",
              on_vehicle(on.report), on_vehicle(off.report), on.report.values.at("sliding"), on.mover_coverage,
              off.mover_coverage, on.static_marked, off.static_marked);
  // Without them the side has no dynamic point of its own (what reaches it
  // grows from elsewhere); with them its points are dynamic.
  EXPECT_LE(on_vehicle(off.report), 2);
  EXPECT_GT(on_vehicle(on.report), 50);
  EXPECT_GT(on.report.values.at("sliding"), 50);
  EXPECT_EQ(off.report.values.at("sliding"), 0);
  EXPECT_GT(on.mover_coverage, 0.8);
  EXPECT_LT(on.static_marked, 0.01);
}

TEST(DdlStage, ParallaxOcclusionOfAStaticRoomIsNotMotion) {
  // No mover; the camera slides sideways, so background keypoints end up
  // behind the static boxes: Algorithm 1 alone calls that motion.
  auto none = [](int) { return std::optional<Eigen::Vector3d>(); };
  auto camera = [](int k) { return Eigen::Vector3d(0.1 * k, 0, 0.02 * k); };
  Sequence s = make_sequence(none, camera, false);
  {
    Context ctx = make_context(s);
    DdlStage stage;
    const Outcome o = evaluate(ctx, stage, s.current.mover);
    EXPECT_LT(o.static_marked, 0.002);
    EXPECT_GT(o.report.values.at("seen_static_rejected"), 0);
  }
  // Nor does it slide: the sliding-surface seeds find nothing here.
  DdlOptions sliding;
  sliding.seed_sliding_surfaces = true;
  EXPECT_LT(evaluate_with(s, sliding).static_marked, 0.002);
  {
    Context ctx = make_context(s);
    DdlOptions algorithm1;
    algorithm1.confirm_with_keyframes = false;
    DdlStage stage(algorithm1);
    const Outcome o = evaluate(ctx, stage, s.current.mover);
    EXPECT_GT(o.static_marked, 0.02);
  }
}

TEST(DdlStage, EgoMotionPoseIsPreferredOverThePrediction) {
  Sequence s = crossing_box();
  // The previous frame's pose and an ego-motion that together give the true
  // current pose; the constant-velocity prediction is off by 30 cm.
  auto previous = std::make_shared<FrameData>();
  previous->id = 5;
  previous->T_cw = camera_at({0.15, 0, 0.25});
  EgoMotion ego;
  ego.valid = true;
  ego.T_cur_prev = s.T_cw_current * previous->T_cw->inverse();
  Context ctx = make_context(s);
  ctx.previous = previous;
  ctx.ego = &ego;
  ctx.T_cw_predicted = camera_at({0.5, 0, 0.3});
  DdlStage stage;
  const Outcome o = evaluate(ctx, stage, s.current.mover);
  EXPECT_EQ(o.report.values.at("pose_source"), 2);
  EXPECT_GT(o.mover_coverage, 0.85);
  EXPECT_LT(o.static_marked, 0.01);

  // A failed ego-motion falls back to the (wrong) prediction, which then
  // shows up as marked static pixels or a lost box: the pose matters.
  ego.valid = false;
  Context ctx2 = make_context(s);
  ctx2.previous = previous;
  ctx2.ego = &ego;
  ctx2.T_cw_predicted = camera_at({0.5, 0, 0.3});
  DdlOptions unrefined;
  unrefined.refine_pose = false;
  DdlStage as_given(unrefined);
  const Outcome bad = evaluate(ctx2, as_given, s.current.mover);
  EXPECT_EQ(bad.report.values.at("pose_source"), 3);
  EXPECT_TRUE(bad.static_marked > 0.01 || bad.mover_coverage < 0.85);
}

TEST(DdlStage, PoseRefinementAgainstTheKeyframesMendsASmallPoseError) {
  Sequence s = crossing_box();
  // A prediction off by 2 cm and 0.6 degrees (about 3 px here).
  Eigen::Isometry3d off = make_motion(0.3, -0.5, 0.2, {0.015, -0.01, 0.01});
  {
    Context ctx = make_context(s);
    ctx.T_cw_predicted = off * s.T_cw_current;
    DdlStage stage;
    const Outcome o = evaluate(ctx, stage, s.current.mover);
    EXPECT_EQ(o.report.values.at("pose_refined"), 1);
    EXPECT_GT(o.mover_coverage, 0.85);
    EXPECT_LT(o.static_marked, 0.01);
    EXPECT_GT(o.report.values.at("pose_correction_deg"), 0.4);
  }
  {
    Context ctx = make_context(s);
    ctx.T_cw_predicted = off * s.T_cw_current;
    DdlOptions o;
    o.refine_pose = false;
    DdlStage stage(o);
    const Outcome bad = evaluate(ctx, stage, s.current.mover);
    EXPECT_TRUE(bad.static_marked > 0.01 || bad.mover_coverage < 0.85);
  }
}

TEST(DdlStage, SemanticMaskIsCombinedByUnion) {
  Sequence s = crossing_box();
  cv::Mat candidates(kH, kW, CV_8UC1, cv::Scalar(0));
  candidates(cv::Rect(10, 10, 30, 20)).setTo(255);  // a "person" the geometry has no evidence on
  s.current.frame->candidates = candidates;
  {
    Context ctx = make_context(s);
    DdlStage stage;
    StageReport rep;
    stage.process(ctx, rep);
    EXPECT_EQ(cv::countNonZero(ctx.dynamic & candidates), 600);
    EXPECT_GT(cv::countNonZero(ctx.dynamic & s.current.mover), 0.85 * cv::countNonZero(s.current.mover));
    EXPECT_EQ(rep.values.at("semantic_pixels"), 600);
  }
  {
    Context ctx = make_context(s);
    DdlOptions o;
    o.combine_semantic = false;
    DdlStage stage(o);
    StageReport rep;
    stage.process(ctx, rep);
    EXPECT_EQ(cv::countNonZero(ctx.dynamic & candidates), 0);
  }
  {
    // Without keyframes the geometry cannot run; the semantic half still applies.
    Context ctx = make_context(s);
    std::vector<KeyFrameData> none;
    ctx.keyframes = &none;
    DdlStage stage;
    StageReport rep;
    stage.process(ctx, rep);
    EXPECT_EQ(rep.values.at("skipped_no_keyframes"), 1);
    EXPECT_EQ(cv::countNonZero(ctx.dynamic), 600);
  }
}

TEST(DdlStage, DegenerateInputMarksNothingAndSaysWhy) {
  DdlStage stage;
  const auto run = [&](Sequence& s, auto&& tweak) {
    Context ctx = make_context(s);
    tweak(ctx);
    StageReport rep;
    EXPECT_NO_THROW(stage.process(ctx, rep));
    return std::make_pair(rep, ctx.dynamic.empty() ? 0 : cv::countNonZero(ctx.dynamic));
  };
  Sequence s = crossing_box();
  {
    auto [rep, marked] = run(s, [](Context& c) { c.T_cw_predicted.reset(); });
    EXPECT_EQ(rep.values.at("skipped_no_pose"), 1);
    EXPECT_EQ(marked, 0);
  }
  {
    auto [rep, marked] = run(s, [](Context& c) { c.keyframes = nullptr; });
    EXPECT_EQ(rep.values.at("skipped_no_keyframes"), 1);
    EXPECT_EQ(marked, 0);
  }
  {
    // Stereo without a disparity stage before this one: no depth.
    Sequence t = crossing_box();
    t.current.frame->depth = cv::Mat();
    auto [rep, marked] = run(t, [](Context& c) { c.sensor = Sensor::kStereo; });
    EXPECT_EQ(rep.values.at("skipped_no_depth"), 1);
    EXPECT_EQ(marked, 0);
  }
  {
    Sequence t = crossing_box();
    t.current.frame->depth = cv::Mat(10, 10, CV_32FC1, cv::Scalar(1));
    auto [rep, marked] = run(t, [](Context&) {});
    EXPECT_EQ(rep.values.at("skipped_bad_input"), 1);
    EXPECT_EQ(marked, 0);
  }
  {
    // A depth image with no measurement at all (and NaNs): nothing to compare.
    Sequence t = crossing_box();
    t.current.frame->depth.setTo(0);
    t.current.frame->depth(cv::Rect(0, 0, 40, 40)).setTo(std::numeric_limits<float>::quiet_NaN());
    auto [rep, marked] = run(t, [](Context&) {});
    EXPECT_EQ(rep.values.at("dynamic"), 0);
    EXPECT_GT(rep.values.at("no_depth"), 0);
    EXPECT_EQ(marked, 0);
  }
  {
    // Keyframes without pose or keypoints are no references.
    Sequence t = crossing_box();
    for (KeyFrameData& kf : t.keyframes) {
      auto f = std::make_shared<FrameData>(*kf.frame);
      f->T_cw.reset();
      kf.frame = f;
    }
    t.keyframes[0].keypoints.clear();
    auto [rep, marked] = run(t, [](Context&) {});
    EXPECT_EQ(rep.values.at("skipped_no_keyframes"), 1);
    EXPECT_EQ(marked, 0);
  }
  {
    auto [rep, marked] = run(s, [](Context& c) { c.current.grey = cv::Mat(); });
    EXPECT_EQ(rep.values.at("skipped_bad_input"), 1);
    EXPECT_EQ(marked, 0);
  }
  {
    // A frame that is all moving object: a wall of it one metre in front of
    // the camera. Every old point is covered; the whole frame is marked.
    Sequence t = crossing_box();
    std::vector<TexturedQuad> quads = scene(std::nullopt);
    quads.push_back(facing_quad({0.18, 0, 1.3}, 3, 3, 150, 99, 15));
    t.current = make_view(6, quads, t.T_cw_current, *t.calib);
    auto [rep, marked] = run(t, [](Context&) {});
    EXPECT_GT(marked, 0.9 * kW * kH);
  }
  EXPECT_EQ(stage.name(), "ddl");
  EXPECT_TRUE(stage.supports(Sensor::kRGBD));
  EXPECT_TRUE(stage.supports(Sensor::kStereo));
  EXPECT_FALSE(stage.supports(Sensor::kMono));
  EXPECT_TRUE(stage.needs_motion_cues());
}

TEST(DdlStage, RegionGrowingFollowsDepthAndStopsAtEdges) {
  // A slanted plane (depth rising across the image) next to a far wall.
  cv::Mat depth(50, 100, CV_32FC1);
  for (int y = 0; y < 50; ++y)
    for (int x = 0; x < 100; ++x) depth.at<float>(y, x) = x < 60 ? 2.0f + 0.02f * x : 8.0f;
  DdlOptions o;
  cv::Mat r = ddl_grow_regions(depth, {cv::Point(5, 5)}, o);
  EXPECT_EQ(cv::countNonZero(r), 60 * 50);
  EXPECT_EQ(cv::countNonZero(r.colRange(60, 100)), 0);
  // The seed band keeps it near the seed's depth.
  o.grow_max_from_seed_m = 0.25;
  r = ddl_grow_regions(depth, {cv::Point(5, 5)}, o);
  EXPECT_EQ(cv::countNonZero(r), 18 * 50);  // x = 0..17: depth 2.0 .. 2.34, the seed's 2.1 +- 0.25
  // A blocked column stops it.
  o.grow_max_from_seed_m = 0;
  r = ddl_grow_regions(depth, {cv::Point(5, 5)}, o, [](int x, int) { return x == 30; });
  EXPECT_EQ(cv::countNonZero(r), 30 * 50);
  // Seeds without depth grow nothing; an empty image gives an empty region.
  depth.at<float>(5, 5) = 0;
  EXPECT_EQ(cv::countNonZero(ddl_grow_regions(depth, {cv::Point(5, 5), cv::Point(-3, 400)}, o)), 0);
  EXPECT_TRUE(ddl_grow_regions(cv::Mat(), {cv::Point(0, 0)}, o).empty());
}

TEST(DdlStage, OptionsReadKeepDefaultsAndRejectWrongTypes) {
  cv::FileStorage fs(
      "%YAML:1.0\nddl:\n  reference_keyframes: 3\n  depth_threshold_m: 0.3\n  vanished_points_dynamic: false\n"
      "  seed_sliding_surfaces: 1\n"
      "bad:\n  dilation_px: 1.5\n",
      cv::FileStorage::READ | cv::FileStorage::MEMORY);
  DdlOptions o;
  o.read(fs["ddl"]);
  EXPECT_EQ(o.reference_keyframes, 3);
  EXPECT_DOUBLE_EQ(o.depth_threshold_m, 0.3);
  EXPECT_FALSE(o.vanished_points_dynamic);
  EXPECT_TRUE(o.seed_sliding_surfaces);
  EXPECT_FALSE(DdlOptions().seed_sliding_surfaces);
  EXPECT_DOUBLE_EQ(o.parallax_threshold_deg, 30.0);
  EXPECT_TRUE(o.confirm_with_keyframes);
  DdlOptions p;
  EXPECT_THROW(p.read(fs["bad"]), InputError);
  DdlOptions q;
  q.read(fs["missing"]);
  EXPECT_EQ(q.reference_keyframes, 5);
}

}  // namespace
}  // namespace dynaorb::dynamic
