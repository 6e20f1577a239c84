// Background inpainting (DDL-SLAM Sec. III-E) on rendered views of a known
// room: the background behind a box that moved is recovered (against a
// render without the box), what no keyframe saw stays empty, a keyframe
// whose mask missed the box cannot paint the box back, lens distortion, and
// degenerate input.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "dynaorb/dynamic/inpainting.h"
#include "dynaorb/io/errors.h"
#include "synthetic_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

constexpr int kW = 320, kH = 240;

Eigen::Isometry3d camera_at(const Eigen::Vector3d& centre) {
  Eigen::Isometry3d T_wc = Eigen::Isometry3d::Identity();
  T_wc.translation() = centre;
  return T_wc.inverse();
}

// A room whose textures are no finer than the pixels they are seen at (the
// ray caster does not filter textures), and an optional box (label 15).
std::vector<TexturedQuad> scene(const std::optional<Eigen::Vector3d>& box) {
  std::vector<TexturedQuad> s;
  s.push_back(facing_quad({0, 0, 6}, 5, 4, 40, 13));
  s.push_back(floor_quad(1.2, 3.5, 5, 3.5, 25, 14));
  s.push_back(facing_quad({-1.25, 0.35, 3.0}, 0.75, 0.85, 80, 15));
  s.push_back(facing_quad({1.0, 0.3, 2.2}, 0.5, 0.6, 100, 16));
  if (box) s.push_back(facing_quad(*box, 0.4, 0.6, 150, 17, 15));
  return s;
}

// A colour image made from the grey one (a fixed tint per channel), so
// the colour path can be checked against the grey truth.
cv::Mat tint(const cv::Mat& grey) {
  std::vector<cv::Mat> ch{grey * 0.5, grey * 0.8, grey.clone()};
  cv::Mat bgr;
  cv::merge(ch, bgr);
  return bgr;
}

std::shared_ptr<FrameData> make_frame(long id, const std::optional<Eigen::Vector3d>& box,
                                      const Eigen::Isometry3d& T_cw, const map::Calibration& calib,
                                      bool mask_box = true) {
  const RenderedView rv = render(scene(box), T_cw, calib);
  auto f = std::make_shared<FrameData>();
  f->id = id;
  f->grey = rv.grey;
  f->colour = tint(rv.grey);
  f->depth = rv.depth;
  f->T_cw = T_cw;
  f->dynamic = mask_box ? cv::Mat(rv.labels == 15) : cv::Mat(rv.labels.size(), CV_8UC1, cv::Scalar(0));
  f->candidates = rv.labels == 15;  // the box is of a movable class
  f->motion_checked = true;
  return f;
}

struct Case {
  std::shared_ptr<map::Calibration> calib;
  std::vector<KeyFrameData> keyframes;
  FrameData current;
  RenderedView background;  // the current view without the box
};

// Keyframes 0..4 and the current frame 6 of a camera moving forward and to
// the right; the box's centre at step k is box(k).
template <typename BoxAt>
Case make_case(BoxAt box, bool mask_box_in_keyframes = true, cv::Mat dist = cv::Mat()) {
  Case c;
  c.calib = make_calibration(Sensor::kRGBD, kW, kH, 250, 0.1, dist);
  const auto camera = [](int k) { return Eigen::Vector3d(0.04 * k, 0, 0.06 * k); };
  for (int k = 0; k <= 4; ++k) {
    KeyFrameData kf;
    kf.frame = make_frame(k, box(k), camera_at(camera(k)), *c.calib, mask_box_in_keyframes);
    c.keyframes.push_back(kf);
  }
  const Eigen::Isometry3d T_cw = camera_at(camera(6));
  c.current = *make_frame(6, box(6), T_cw, *c.calib);
  c.background = render(scene(std::nullopt), T_cw, *c.calib);
  return c;
}

auto crossing = [](int k) { return std::optional<Eigen::Vector3d>({-1.0 + 0.3 * k, 0.1, 2.0}); };

// Mean absolute grey error and median absolute depth error over the filled pixels.
std::pair<double, double> errors(const InpaintResult& r, const RenderedView& truth) {
  std::vector<double> dz;
  double sum = 0;
  int n = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      if (!r.filled.at<unsigned char>(y, x)) continue;
      sum += std::abs(r.grey.at<unsigned char>(y, x) - truth.grey.at<unsigned char>(y, x));
      dz.push_back(std::abs(r.depth.at<float>(y, x) - truth.depth.at<float>(y, x)));
      ++n;
    }
  return {n ? sum / n : 1e9, median(dz)};
}

TEST(Inpainting, RecoversTheBackgroundBehindABoxThatMoved) {
  Case c = make_case(crossing);
  const int target = cv::countNonZero(c.current.dynamic);
  ASSERT_GT(target, 3000);
  const InpaintResult r = inpaint_background(c.current, c.keyframes, *c.calib);
  EXPECT_EQ(r.target_pixels, target);
  EXPECT_EQ(r.keyframes_used, 5);
  EXPECT_GT(r.filled_fraction, 0.9);
  const auto [mae, depth_err] = errors(r, c.background);
  EXPECT_LT(mae, 4.0);
  EXPECT_LT(depth_err, 0.02);
  // The colour comes from the keyframes' colour: the tint of the true grey.
  cv::Mat truth_colour = tint(c.background.grey), diff;
  cv::absdiff(r.colour, truth_colour, diff);
  EXPECT_LT(cv::mean(diff, r.filled)[2], 4.0);
  // Pixels outside the mask are untouched.
  cv::Mat outside = c.current.dynamic == 0;
  EXPECT_EQ(cv::countNonZero((r.grey != c.current.grey) & outside), 0);
  EXPECT_EQ(cv::countNonZero((r.depth != c.current.depth) & outside), 0);
  // The box itself is gone: every fill lies behind it.
  int not_behind = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      not_behind += r.filled.at<unsigned char>(y, x) && r.depth.at<float>(y, x) <= c.current.depth.at<float>(y, x);
  EXPECT_EQ(not_behind, 0);
}

TEST(Inpainting, WhatNoKeyframeSawStaysEmpty) {
  // The box drives ahead of the camera at its speed: the background behind
  // it is hidden in every keyframe.
  const auto ahead = [](int k) { return std::optional<Eigen::Vector3d>({0.04 * k, 0.1, 2.0 + 0.06 * k}); };
  Case c = make_case(ahead);
  const InpaintResult r = inpaint_background(c.current, c.keyframes, *c.calib);
  EXPECT_LT(r.filled_fraction, 0.05);
  const cv::Mat empty = (c.current.dynamic != 0) & (r.filled == 0);
  EXPECT_GT(cv::countNonZero(empty), 0.95 * r.target_pixels);
  EXPECT_EQ(cv::countNonZero(r.grey & empty), 0);
  cv::Mat depth_left;
  r.depth.copyTo(depth_left, empty);
  EXPECT_EQ(cv::countNonZero(depth_left), 0);
  cv::Mat colour_left;
  r.colour.copyTo(colour_left, empty);
  EXPECT_EQ(cv::countNonZero(colour_left.reshape(1)), 0);
}

TEST(Inpainting, AKeyframeMaskThatMissedTheBoxDoesNotPaintItBack) {
  // Same box, but the keyframes' masks are empty: their box pixels look
  // like background. They lie at the box's own depth, not behind it.
  const auto ahead = [](int k) { return std::optional<Eigen::Vector3d>({0.04 * k, 0.1, 2.0 + 0.06 * k}); };
  Case c = make_case(ahead, false);
  const InpaintResult r = inpaint_background(c.current, c.keyframes, *c.calib);
  EXPECT_LT(r.filled_fraction, 0.05);
  InpaintOptions o;
  o.background_behind_object = false;
  const InpaintResult without = inpaint_background(c.current, c.keyframes, *c.calib, o);
  EXPECT_GT(without.filled_fraction, 0.5);
}

TEST(Inpainting, UncheckedMovableRegionsOfAKeyframeAreNoSource) {
  // The keyframes' masks are empty because they had no previous frame to
  // judge motion by: their movable-class regions (the box) must not be
  // painted in as background.
  const auto ahead = [](int k) { return std::optional<Eigen::Vector3d>({0.04 * k, 0.1, 2.0 + 0.06 * k}); };
  Case c = make_case(ahead, false);
  InpaintOptions o;
  o.background_behind_object = false;  // only the candidates keep the box out
  for (KeyFrameData& kf : c.keyframes) {
    auto f = std::make_shared<FrameData>(*kf.frame);
    f->motion_checked = false;
    kf.frame = f;
  }
  const InpaintResult unchecked = inpaint_background(c.current, c.keyframes, *c.calib, o);
  for (KeyFrameData& kf : c.keyframes) {
    auto f = std::make_shared<FrameData>(*kf.frame);
    f->motion_checked = true;
    kf.frame = f;
  }
  const InpaintResult checked = inpaint_background(c.current, c.keyframes, *c.calib, o);
  EXPECT_GT(checked.filled_fraction, 0.5);  // "checked" and unmarked: taken as background
  const auto [mae, depth_err] = errors(unchecked, c.background);
  EXPECT_LT(depth_err, 0.05);  // what was filled is the wall behind, not the box
  EXPECT_LT(unchecked.filled_fraction, checked.filled_fraction);
}

TEST(Inpainting, DistortedImagesAreWarpedThroughTheLens) {
  Case c = make_case(crossing, true, (cv::Mat_<double>(1, 5) << 0.12, -0.2, 0.001, -0.0015, 0.05));
  const InpaintResult r = inpaint_background(c.current, c.keyframes, *c.calib);
  EXPECT_GT(r.filled_fraction, 0.9);
  const auto [mae, depth_err] = errors(r, c.background);
  EXPECT_LT(mae, 4.0);
  EXPECT_LT(depth_err, 0.02);
}

TEST(Inpainting, OnlyTheLastUsableKeyframesAreUsed) {
  Case c = make_case(crossing);
  InpaintOptions o;
  o.keyframes = 2;
  const InpaintResult r = inpaint_background(c.current, c.keyframes, *c.calib, o);
  EXPECT_EQ(r.keyframes_used, 2);
  EXPECT_EQ(r.values.at("keyframes_without_pose_or_depth"), 0);
  // The newest two have no depth: the two before them are taken instead.
  for (int i = 3; i <= 4; ++i) {
    auto f = std::make_shared<FrameData>(*c.keyframes[i].frame);
    f->depth = cv::Mat();
    c.keyframes[i].frame = f;
  }
  const InpaintResult older = inpaint_background(c.current, c.keyframes, *c.calib, o);
  EXPECT_EQ(older.keyframes_used, 2);
  EXPECT_EQ(older.values.at("keyframes_without_pose_or_depth"), 2);
  EXPECT_GT(older.filled_fraction, 0.5);
}

TEST(Inpainting, DegenerateInputLeavesTheMaskEmptyAndSaysWhy) {
  Case c = make_case(crossing);
  const int target = cv::countNonZero(c.current.dynamic);
  {
    const InpaintResult r = inpaint_background(c.current, {}, *c.calib);
    EXPECT_EQ(r.values.at("skipped_no_keyframes"), 1);
    EXPECT_EQ(r.filled_pixels, 0);
    EXPECT_EQ(r.target_pixels, target);
    EXPECT_EQ(cv::countNonZero(r.grey & c.current.dynamic), 0);
  }
  {
    FrameData no_pose = c.current;
    no_pose.T_cw.reset();
    const InpaintResult r = inpaint_background(no_pose, c.keyframes, *c.calib);
    EXPECT_EQ(r.values.at("skipped_no_pose"), 1);
    EXPECT_EQ(r.filled_pixels, 0);
  }
  {
    // Keyframes without depth or pose are not used.
    std::vector<KeyFrameData> bad = c.keyframes;
    for (size_t i = 0; i < bad.size(); ++i) {
      auto f = std::make_shared<FrameData>(*bad[i].frame);
      if (i % 2) f->depth = cv::Mat();
      else f->T_cw.reset();
      bad[i].frame = f;
    }
    bad.push_back(KeyFrameData{});
    const InpaintResult r = inpaint_background(c.current, bad, *c.calib);
    EXPECT_EQ(r.values.at("skipped_no_keyframes"), 1);
    EXPECT_EQ(r.values.at("keyframes_without_pose_or_depth"), 6);
  }
  {
    // No depth in the current frame: the background's depth is still filled in.
    FrameData no_depth = c.current;
    no_depth.depth = cv::Mat();
    const InpaintResult r = inpaint_background(no_depth, c.keyframes, *c.calib);
    EXPECT_GT(r.filled_fraction, 0.9);
    ASSERT_EQ(r.depth.type(), CV_32FC1);
    cv::Mat outside;
    r.depth.copyTo(outside, no_depth.dynamic == 0);
    EXPECT_EQ(cv::countNonZero(outside), 0);
  }
  {
    FrameData nothing = c.current;
    nothing.dynamic = cv::Mat();
    const InpaintResult r = inpaint_background(nothing, c.keyframes, *c.calib);
    EXPECT_EQ(r.values.at("nothing_to_fill"), 1);
    EXPECT_EQ(cv::countNonZero(r.grey != c.current.grey), 0);
  }
  {
    FrameData wrong = c.current;
    wrong.dynamic = cv::Mat(10, 10, CV_8UC1, cv::Scalar(255));
    EXPECT_EQ(inpaint_background(wrong, c.keyframes, *c.calib).values.at("skipped_bad_input"), 1);
    wrong = c.current;
    wrong.grey = cv::Mat();
    EXPECT_EQ(inpaint_background(wrong, c.keyframes, *c.calib).values.at("skipped_bad_input"), 1);
  }
  {
    // A frame marked dynamic all over: the box's background is filled in;
    // the static room, which no keyframe saw behind itself, stays empty.
    FrameData all = c.current;
    all.dynamic = cv::Mat(kH, kW, CV_8UC1, cv::Scalar(255));
    const InpaintResult r = inpaint_background(all, c.keyframes, *c.calib);
    EXPECT_EQ(r.target_pixels, kW * kH);
    EXPECT_GT(cv::countNonZero(r.filled & c.current.dynamic), 0.9 * target);
    EXPECT_LT(cv::countNonZero(r.filled & (c.current.dynamic == 0)), 0.005 * (kW * kH - target));
  }
}

TEST(Inpainting, OptionsReadKeepDefaultsAndRejectWrongTypes) {
  cv::FileStorage fs("%YAML:1.0\ninpaint:\n  keyframes: 10\n  depth_tolerance_m: 0.1\nbad:\n  keyframes: many\n",
                     cv::FileStorage::READ | cv::FileStorage::MEMORY);
  InpaintOptions o;
  o.read(fs["inpaint"]);
  EXPECT_EQ(o.keyframes, 10);
  EXPECT_DOUBLE_EQ(o.depth_tolerance_m, 0.1);
  EXPECT_TRUE(o.background_behind_object);
  InpaintOptions d;
  EXPECT_EQ(d.keyframes, 15);
  EXPECT_THROW(d.read(fs["bad"]), InputError);
}

}  // namespace
}  // namespace dynaorb::dynamic
