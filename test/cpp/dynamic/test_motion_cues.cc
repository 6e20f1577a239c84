// Shared motion cues on rendered views of a known scene and camera motion:
// flow accuracy, stereo depth, T_cur_prev and F against the truth, lens
// distortion, candidate regions kept out of the ego-motion, degenerate input
// and option reading.
#include <gtest/gtest.h>

#include <opencv2/features2d.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/dynamic/motion_cues.h"
#include "dynaorb/io/errors.h"
#include "synthetic_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

// The camera moves by T_cur_prev between the two views (world = previous camera).
const Eigen::Isometry3d kMotion = make_motion(0.5, 1.5, 0.3, {0.08, -0.02, 0.12});

struct Pair {
  FrameData prev, cur;
  RenderedView prev_view, cur_view;
};

Pair render_pair(const std::vector<TexturedQuad>& prev_scene, const std::vector<TexturedQuad>& cur_scene,
                 const map::Calibration& calib, Sensor sensor) {
  Pair p;
  p.prev_view = render(prev_scene, Eigen::Isometry3d::Identity(), calib);
  p.cur_view = render(cur_scene, kMotion, calib);
  p.prev.id = 0;
  p.cur.id = 1;
  p.prev.grey = p.prev_view.grey;
  p.cur.grey = p.cur_view.grey;
  if (sensor == Sensor::kRGBD) {
    p.prev.depth = p.prev_view.depth;
    p.cur.depth = p.cur_view.depth;
  }
  if (sensor == Sensor::kStereo) {
    // The right camera sits baseline metres along +x of the left one.
    Eigen::Isometry3d T_rl = Eigen::Isometry3d::Identity();
    T_rl.translation() = Eigen::Vector3d(-calib.baseline, 0, 0);
    p.prev.right = render(prev_scene, T_rl, calib).grey;
    p.cur.right = render(cur_scene, T_rl * kMotion, calib).grey;
  }
  return p;
}

Pair render_pair(const map::Calibration& calib, Sensor sensor) {
  return render_pair(room(), room(), calib, sensor);
}

// Where a previous pixel with true depth lands in the current image (raw pixels).
cv::Point2f true_flow(const map::Calibration& calib, const cv::Point2f& prev, float depth) {
  std::vector<cv::Point2f> in{prev}, u;
  const cv::Matx33d K(calib.fx, 0, calib.cx, 0, calib.fy, calib.cy, 0, 0, 1);
  if (!calib.dist.empty()) {
    cv::undistortPoints(in, u, K, calib.dist, cv::noArray(), K);
  } else {
    u = in;
  }
  const Eigen::Vector3d X = kMotion * calib.unproject(u[0].x, u[0].y, depth);
  std::vector<cv::Point3f> obj{cv::Point3f(X.x(), X.y(), X.z())};
  std::vector<cv::Point2f> img;
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K,
                    calib.dist.empty() ? cv::Mat() : calib.dist, img);
  return img[0];
}

// Epipolar distances of true correspondences (scene points on a pixel grid of
// the previous view) under F, in undistorted pixels.
std::vector<double> epipolar_errors(const cv::Matx33d& F, const map::Calibration& calib,
                                    const RenderedView& prev_view) {
  std::vector<double> d;
  for (int v = 20; v < calib.height - 20; v += 20)
    for (int u = 20; u < calib.width - 20; u += 20) {
      const float z = prev_view.depth.at<float>(v, u);
      if (!(z > 0)) continue;
      cv::Point2f p(u, v);
      const Eigen::Vector3d X = calib.unproject(u, v, z);  // undistorted rendering only
      const Eigen::Vector2d q = calib.project(kMotion * X);
      d.push_back(epipolar_distance(F, p, cv::Point2f(q.x(), q.y())));
    }
  return d;
}

TEST(MotionCues, RgbdTracksCornersAndRecoversTheCameraMotion) {
  auto calib = make_calibration(Sensor::kRGBD);
  Pair p = render_pair(*calib, Sensor::kRGBD);
  const MotionCueOptions o;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_GT(pts.size(), 300u);

  std::vector<double> flow_err;
  int with_depth = 0;
  for (const auto& t : pts) {
    EXPECT_FALSE(t.in_candidate);  // no candidates given
    EXPECT_GE(t.prev.x, o.border);
    EXPECT_GE(t.cur.y, o.border);
    EXPECT_LE(t.cur.x, calib->width - 1 - o.border);
    if (t.prev_depth > 0) {
      ++with_depth;
      const cv::Point2f q = true_flow(*calib, t.prev, t.prev_depth);
      flow_err.push_back(cv::norm(q - t.cur));
    }
  }
  EXPECT_GT(with_depth, 0.9 * pts.size());  // the rest lie on depth edges
  EXPECT_LT(median(flow_err), 0.2);

  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
  ASSERT_TRUE(ego.valid);
  EXPECT_LT(rotation_error_deg(ego.T_cur_prev, kMotion), 0.1);
  EXPECT_LT((ego.T_cur_prev.translation() - kMotion.translation()).norm(), 0.01);
  EXPECT_GT(ego.inliers, 0.8 * pts.size());
  ASSERT_EQ(ego.inlier.size(), pts.size());
  EXPECT_EQ(std::count(ego.inlier.begin(), ego.inlier.end(), 1), ego.inliers);

  ASSERT_TRUE(ego.has_F);
  const auto d = epipolar_errors(ego.F, *calib, p.prev_view);
  ASSERT_GT(d.size(), 200u);
  EXPECT_LT(median(d), 0.3);
  EXPECT_LT(percentile(d, 0.9), 1.0);

  // Without F (what the filter asks for stereo / RGB-D): the same pose and
  // inliers, no F.
  const EgoMotion pose_only = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o, /*with_F=*/false);
  ASSERT_TRUE(pose_only.valid);
  EXPECT_FALSE(pose_only.has_F);
  EXPECT_EQ(pose_only.F, cv::Matx33d::zeros());
  EXPECT_TRUE(pose_only.T_cur_prev.isApprox(ego.T_cur_prev, 1e-9));
  EXPECT_EQ(pose_only.inlier, ego.inlier);
}

TEST(MotionCues, CornersOnDepthEdgesGetNoDepthAndNoCornerIsCountedTwice) {
  auto calib = make_calibration(Sensor::kRGBD);
  Pair p = render_pair(*calib, Sensor::kRGBD);
  MotionCueOptions o;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_GT(pts.size(), 300u);
  auto on_edge = [&](const cv::Point2f& c) {
    const cv::Rect r(cvRound(c.x) - o.depth_edge_radius, cvRound(c.y) - o.depth_edge_radius,
                     2 * o.depth_edge_radius + 1, 2 * o.depth_edge_radius + 1);
    double lo, hi;
    cv::minMaxLoc(p.prev_view.depth(r), &lo, &hi);
    const float z = p.prev_view.depth.at<float>(cvRound(c.y), cvRound(c.x));
    return hi - lo > o.depth_edge_max_ratio * z;
  };
  int edges = 0;
  for (const auto& t : pts) {
    if (on_edge(t.prev)) {
      ++edges;
      EXPECT_EQ(t.prev_depth, 0.f);
    } else {
      EXPECT_GT(t.prev_depth, 0.f);
    }
  }
  EXPECT_GT(edges, 5);  // the boxes' silhouettes against the wall
  for (size_t i = 0; i < pts.size(); ++i)
    for (size_t j = i + 1; j < pts.size(); ++j)
      ASSERT_GE(cv::norm(pts[i].prev - pts[j].prev), o.min_distance / 2) << i << " " << j;

  o.depth_edge_max_ratio = 0;  // check off: every corner keeps its depth
  for (const auto& t : track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o)) EXPECT_GT(t.prev_depth, 0.f);
}

TEST(MotionCues, StereoDepthFromTheRightImage) {
  auto calib = make_calibration(Sensor::kStereo);
  Pair p = render_pair(*calib, Sensor::kStereo);
  const MotionCueOptions o;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kStereo, o);
  ASSERT_GT(pts.size(), 300u);
  std::vector<double> rel;
  for (const auto& t : pts) {
    if (!(t.prev_depth > 0)) continue;
    const float z = p.prev_view.depth.at<float>(cvRound(t.prev.y), cvRound(t.prev.x));
    rel.push_back(std::abs(t.prev_depth - z) / z);
  }
  EXPECT_GT(rel.size(), 0.7 * pts.size());
  EXPECT_LT(median(rel), 0.02);

  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kStereo, o);
  ASSERT_TRUE(ego.valid);
  EXPECT_LT(rotation_error_deg(ego.T_cur_prev, kMotion), 0.15);
  EXPECT_LT((ego.T_cur_prev.translation() - kMotion.translation()).norm(), 0.02);
}

bool same_points(const std::vector<TrackedPoint>& a, const std::vector<TrackedPoint>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].prev != b[i].prev || a[i].cur != b[i].cur || a[i].prev_depth != b[i].prev_depth ||
        a[i].in_candidate != b[i].in_candidate)
      return false;
  return true;
}

// Without the backward check (forward_backward_max 0) every forward track
// that stays inside the border is kept, at the same place: the checked
// tracks are a subset.
TEST(MotionCues, BackwardCheckOnlyRemovesTracks) {
  for (Sensor sensor : {Sensor::kRGBD, Sensor::kStereo, Sensor::kMono}) {
    auto calib = make_calibration(sensor);
    Pair p = render_pair(*calib, sensor);
    const MotionCueOptions checked;
    MotionCueOptions unchecked;
    unchecked.forward_backward_max = 0;
    const auto a = track_points(p.prev, p.cur, *calib, sensor, checked);
    const auto b = track_points(p.prev, p.cur, *calib, sensor, unchecked);
    ASSERT_GT(a.size(), 300u);
    EXPECT_GT(b.size(), a.size());
    size_t k = 0;
    for (const auto& t : a) {
      while (k < b.size() && b[k].prev != t.prev) ++k;
      ASSERT_LT(k, b.size()) << "a checked track missing without the check";
      EXPECT_EQ(b[k].cur, t.cur);
    }
  }
}

// The stereo depths' own backward check (stereo_depth_forward_backward_max)
// leaves the flow alone: the same tracks, and without it every depth the
// check kept is kept, the same, and more are found (still true depths).
TEST(MotionCues, StereoDepthBackwardCheckOnlyRemovesDepths) {
  auto calib = make_calibration(Sensor::kStereo);
  Pair p = render_pair(*calib, Sensor::kStereo);
  const MotionCueOptions checked;
  MotionCueOptions unchecked;
  unchecked.stereo_depth_forward_backward_max = 0;
  const auto a = track_points(p.prev, p.cur, *calib, Sensor::kStereo, checked);
  const auto b = track_points(p.prev, p.cur, *calib, Sensor::kStereo, unchecked);
  ASSERT_GT(a.size(), 300u);
  ASSERT_EQ(a.size(), b.size());
  size_t with_depth_a = 0, with_depth_b = 0;
  std::vector<double> rel;
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].prev, b[i].prev);
    ASSERT_EQ(a[i].cur, b[i].cur);
    if (a[i].prev_depth > 0) {
      ++with_depth_a;
      EXPECT_EQ(b[i].prev_depth, a[i].prev_depth);
    }
    if (b[i].prev_depth > 0) {
      ++with_depth_b;
      const float z = p.prev_view.depth.at<float>(cvRound(b[i].prev.y), cvRound(b[i].prev.x));
      rel.push_back(std::abs(b[i].prev_depth - z) / z);
    }
  }
  EXPECT_GT(with_depth_b, with_depth_a);
  EXPECT_LT(median(rel), 0.02);
}

// LK reads the derivatives of the image it tracks from only, so the right
// image's pyramid is built without them where nothing is tracked back from it
// (motion_cues.cc): the depths are the same with and without them in the
// right pyramid, with and without the depths' backward check.
TEST(MotionCues, StereoDepthsNeedNoDerivativesOfTheRightImage) {
  auto calib = make_calibration(Sensor::kStereo);
  Pair p = render_pair(*calib, Sensor::kStereo);
  MotionCueOptions o;
  const std::vector<cv::Point2f> corners = detect_corners(p.prev.grey, o);
  ASSERT_GT(corners.size(), 300u);
  const cv::Size window(o.lk_window, o.lk_window);
  std::vector<cv::Mat> left, right_with, right_without;
  cv::buildOpticalFlowPyramid(p.prev.grey, left, window, o.lk_levels, true);
  cv::buildOpticalFlowPyramid(p.prev.right, right_with, window, o.lk_levels, true);
  cv::buildOpticalFlowPyramid(p.prev.right, right_without, window, o.lk_levels, false);
  for (double fb_max : {1.0, 0.0}) {
    o.stereo_depth_forward_backward_max = fb_max;
    const std::vector<float> a = stereo_depths(left, right_with, corners, calib->bf, o);
    const std::vector<float> b = stereo_depths(left, right_without, corners, calib->bf, o);
    ASSERT_EQ(a.size(), corners.size());
    EXPECT_EQ(a, b) << "backward check " << fb_max;
    EXPECT_GT(std::count_if(a.begin(), a.end(), [](float z) { return z > 0; }), 0.7 * corners.size());
  }
}

// The cache only saves work: the previous image's pyramid kept from the last
// call, its corners (and for stereo their depths) found ahead on another
// thread; the points are the
// same as without it, frame after frame, and a frame the cache did not see
// (a stale entry) is tracked from scratch.
TEST(MotionCues, CacheGivesTheSamePointsAsWithout) {
  for (Sensor sensor : {Sensor::kRGBD, Sensor::kStereo}) {
    auto calib = make_calibration(sensor);
    Pair p = render_pair(*calib, sensor);
    Pair q = render_pair(*calib, sensor);  // same views, other buffers
    FrameData third = p.prev;  // back to the first view
    third.grey = p.prev.grey.clone();
    third.id = 2;
    const MotionCueOptions o;
    MotionCueCache cache;
    detect_corners_ahead(p.prev, *calib, sensor, o, cache);
    detect_corners_ahead(p.cur, *calib, sensor, o, cache);
    const auto a1 = track_points(p.prev, p.cur, *calib, sensor, o, &cache);
    EXPECT_TRUE(cache.ms.count("corners") && cache.ms.count("flow"));
    // What the detection ahead took on its thread: more than nothing.
    ASSERT_TRUE(cache.ms.count("corners_ahead"));
    EXPECT_GT(cache.ms.at("corners_ahead"), 0.0);
    // Stereo: the depths came with the corners (and are the same, below).
    EXPECT_FALSE(cache.ms.count("stereo"));
    EXPECT_EQ(cache.ms.count("stereo_ahead"), sensor == Sensor::kStereo ? 1u : 0u);
    if (sensor == Sensor::kStereo) { EXPECT_GT(cache.ms.at("stereo_ahead"), 0.0); }
    detect_corners_ahead(third, *calib, sensor, o, cache);
    const auto a2 = track_points(p.cur, third, *calib, sensor, o, &cache);
    const auto a3 = track_points(q.prev, q.cur, *calib, sensor, o, &cache);  // not the cached images
    EXPECT_FALSE(cache.ms.count("corners_ahead"));  // detected in the call
    ASSERT_GT(a1.size(), 300u);
    EXPECT_TRUE(same_points(a1, track_points(p.prev, p.cur, *calib, sensor, o)));
    EXPECT_TRUE(same_points(a2, track_points(p.cur, third, *calib, sensor, o)));
    EXPECT_TRUE(same_points(a3, a1));
  }
}

// The filter starts a frame's corners after that frame's track_points (once
// its features are extracted): the next call finds them in the cache's next
// slot, takes them from there and tracks the same points.
TEST(MotionCues, CornersStartedAfterTheCallAreFoundByTheNext) {
  for (Sensor sensor : {Sensor::kRGBD, Sensor::kStereo}) {
    auto calib = make_calibration(sensor);
    Pair p = render_pair(*calib, sensor);
    FrameData third = p.prev;
    third.grey = p.prev.grey.clone();
    third.id = 2;
    const MotionCueOptions o;
    MotionCueCache cache;
    detect_corners_ahead(p.prev, *calib, sensor, o, cache);
    const auto a1 = track_points(p.prev, p.cur, *calib, sensor, o, &cache);
    EXPECT_TRUE(cache.ms.count("corners_ahead"));
    EXPECT_EQ(cache.ms.count("stereo_ahead"), sensor == Sensor::kStereo ? 1u : 0u);
    EXPECT_FALSE(cache.ms.count("stereo"));
    detect_corners_ahead(p.cur, *calib, sensor, o, cache);
    const auto a2 = track_points(p.cur, third, *calib, sensor, o, &cache);
    EXPECT_TRUE(cache.ms.count("corners_ahead"));
    detect_corners_ahead(third, *calib, sensor, o, cache);
    ASSERT_GT(a1.size(), 300u);
    EXPECT_TRUE(same_points(a1, track_points(p.prev, p.cur, *calib, sensor, o)));
    EXPECT_TRUE(same_points(a2, track_points(p.cur, third, *calib, sensor, o)));
  }
}

TEST(MotionCues, MonocularGivesTheFundamentalMatrixOnly) {
  auto calib = make_calibration(Sensor::kMono);
  Pair p = render_pair(*calib, Sensor::kMono);
  const MotionCueOptions o;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kMono, o);
  ASSERT_GT(pts.size(), 300u);
  for (const auto& t : pts) EXPECT_EQ(t.prev_depth, 0.f);
  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kMono, o);
  ASSERT_TRUE(ego.valid);
  ASSERT_TRUE(ego.has_F);
  EXPECT_TRUE(ego.T_cur_prev.isApprox(Eigen::Isometry3d::Identity()));
  const auto d = epipolar_errors(ego.F, *calib, p.prev_view);
  EXPECT_LT(median(d), 0.3);
  EXPECT_LT(percentile(d, 0.9), 1.0);
  // F is monocular's ego-motion: estimated whatever with_F says.
  const EgoMotion asked_without = estimate_ego_motion(pts, *calib, Sensor::kMono, o, /*with_F=*/false);
  EXPECT_TRUE(asked_without.valid && asked_without.has_F);
}

TEST(MotionCues, DistortedImagesAreUndistortedBeforeGeometry) {
  const cv::Mat dist = (cv::Mat_<double>(1, 5) << -0.28, 0.09, 0.001, -0.0008, 0.0);
  auto calib = make_calibration(Sensor::kRGBD, 640, 480, 500, 0.1, dist);
  Pair p = render_pair(*calib, Sensor::kRGBD);
  const MotionCueOptions o;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_GT(pts.size(), 300u);
  std::vector<double> flow_err;
  for (const auto& t : pts)
    if (t.prev_depth > 0) flow_err.push_back(cv::norm(true_flow(*calib, t.prev, t.prev_depth) - t.cur));
  EXPECT_LT(median(flow_err), 0.2);

  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
  ASSERT_TRUE(ego.valid);
  const double rot_err = rotation_error_deg(ego.T_cur_prev, kMotion);
  const double t_err = (ego.T_cur_prev.translation() - kMotion.translation()).norm();
  EXPECT_LT(rot_err, 0.1);
  EXPECT_LT(t_err, 0.01);

  // The same pixels read as undistorted give a visibly worse pose: the
  // undistortion is what makes the estimate right.
  auto pinhole = std::make_shared<map::Calibration>(*calib);
  pinhole->dist = cv::Mat();
  const EgoMotion wrong = estimate_ego_motion(pts, *pinhole, Sensor::kRGBD, o);
  const double wrong_t = wrong.valid ? (wrong.T_cur_prev.translation() - kMotion.translation()).norm() : 1e9;
  const double wrong_r = wrong.valid ? rotation_error_deg(wrong.T_cur_prev, kMotion) : 1e9;
  EXPECT_TRUE(wrong_t > 3 * t_err || wrong_r > 3 * rot_err || wrong.inliers < 0.8 * ego.inliers)
      << "t " << wrong_t << " vs " << t_err << ", r " << wrong_r << " vs " << rot_err;
}

// Points nearly all on one plane seen at a grazing angle (a ceiling 3.5-10.5 m
// ahead, 3 % of the points up to 1 m off it), as the background of rendered
// rooms often is once the movers are left out: OpenCV's default PnP RANSAC
// refits its inliers from a DLT guess and returned poses metres off, every
// point behind the camera, for about a fifth of such point sets. A valid
// ego-motion must be right; none at all is allowed (measured: 97 of 100 valid).
TEST(MotionCues, NearPlanarBackgroundNeverGivesAWrongValidEgoMotion) {
  auto calib = make_calibration(Sensor::kRGBD, 640, 480, 525);
  Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d rvec(0.003, -0.004, 0.002);
  motion.linear() = Eigen::AngleAxisd(rvec.norm(), rvec.normalized()).toRotationMatrix();
  motion.translation() = Eigen::Vector3d(0.004, -0.003, -0.027);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> x(-3, 3), z(3.5, 10.5), off(0.1, 1.0), u01(0, 1);
  std::normal_distribution<double> noise(0, 0.3);
  const MotionCueOptions o;
  int valid = 0;
  const int trials = 100;
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<TrackedPoint> pts;
    for (int i = 0; i < 94; ++i) {
      Eigen::Vector3d X(x(rng), -1.5, z(rng));
      if (u01(rng) < 0.03) X.y() += off(rng);
      const Eigen::Vector3d Xc = motion * X;
      TrackedPoint t;
      t.prev = cv::Point2f(static_cast<float>(calib->fx * X.x() / X.z() + calib->cx),
                           static_cast<float>(calib->fy * X.y() / X.z() + calib->cy));
      t.cur = cv::Point2f(static_cast<float>(calib->fx * Xc.x() / Xc.z() + calib->cx + noise(rng)),
                          static_cast<float>(calib->fy * Xc.y() / Xc.z() + calib->cy + noise(rng)));
      t.prev_depth = static_cast<float>(X.z());
      pts.push_back(t);
    }
    const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
    if (!ego.valid) continue;
    ++valid;
    EXPECT_LT((ego.T_cur_prev.translation() - motion.translation()).norm(), 0.01) << "trial " << trial;
    EXPECT_LT(rotation_error_deg(ego.T_cur_prev, motion), 0.2) << "trial " << trial;
  }
  EXPECT_GE(valid, 85);
}

TEST(MotionCues, CandidateRegionsAreFlaggedAndLeftOutOfTheEgoMotion) {
  auto calib = make_calibration(Sensor::kRGBD);
  // A large textured "person" close to the camera that moves 12 cm sideways.
  std::vector<TexturedQuad> prev_scene = room(), cur_scene = room();
  TexturedQuad mover = facing_quad({0.1, 0.0, 1.8}, 0.45, 0.9, 200, 77, 15);
  prev_scene.push_back(mover);
  mover.T_wq.translation().x() += 0.12;
  cur_scene.push_back(mover);
  Pair p = render_pair(prev_scene, cur_scene, *calib, Sensor::kRGBD);
  const int mover_index = static_cast<int>(prev_scene.size()) - 1;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(11, 11));
  cv::dilate(p.prev_view.labels == 15, p.prev.candidates, kernel);
  cv::dilate(p.cur_view.labels == 15, p.cur.candidates, kernel);

  const MotionCueOptions o;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  int on_mover = 0;
  for (const auto& t : pts) {
    const bool mover_px = p.prev_view.object.at<int>(cvRound(t.prev.y), cvRound(t.prev.x)) == mover_index;
    if (mover_px) {
      ++on_mover;
      EXPECT_TRUE(t.in_candidate);
    }
  }
  ASSERT_GT(on_mover, 40) << pts.size();
  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
  ASSERT_TRUE(ego.valid);
  for (size_t i = 0; i < pts.size(); ++i)
    if (pts[i].in_candidate) { EXPECT_EQ(ego.inlier[i], 0); }
  EXPECT_LT(rotation_error_deg(ego.T_cur_prev, kMotion), 0.1);
  EXPECT_LT((ego.T_cur_prev.translation() - kMotion.translation()).norm(), 0.01);

  // Every point a candidate: nothing is left to estimate from.
  auto all = pts;
  for (auto& t : all) t.in_candidate = true;
  const EgoMotion none = estimate_ego_motion(all, *calib, Sensor::kRGBD, o);
  EXPECT_FALSE(none.valid);
  EXPECT_FALSE(none.has_F);
  EXPECT_EQ(none.inliers, 0);
  EXPECT_EQ(none.inlier.size(), all.size());
}

// The background budget leaves every corner inside the candidates, keeps a
// spatially even subset of the rest (every quadrant of the image), and the
// ego-motion from that subset is as good as from all of them.
TEST(MotionCues, BackgroundBudgetKeepsCandidateCornersAndSpreadsTheRest) {
  auto calib = make_calibration(Sensor::kRGBD);
  Pair p = render_pair(*calib, Sensor::kRGBD);
  cv::Mat candidates = cv::Mat::zeros(p.prev.grey.size(), CV_8UC1);
  candidates(cv::Rect(200, 120, 160, 200)).setTo(255);
  MotionCueOptions all;
  const auto every = detect_corners(p.prev.grey, all, candidates);
  const auto inside = [&](const cv::Point2f& c) {
    return candidates.at<unsigned char>(cvRound(c.y), cvRound(c.x)) != 0;
  };
  const long n_in = std::count_if(every.begin(), every.end(), inside);
  const long n_out = static_cast<long>(every.size()) - n_in;
  ASSERT_GT(n_in, 20);
  ASSERT_GT(n_out, 250);

  MotionCueOptions o;
  o.max_background_corners = 120;
  const auto some = detect_corners(p.prev.grey, o, candidates);
  const long some_in = std::count_if(some.begin(), some.end(), inside);
  // Sub-pixel refinement and duplicate removal run after the choice: allow a
  // corner or two to merge.
  EXPECT_NEAR(static_cast<double>(some_in), static_cast<double>(n_in), 2.0);
  EXPECT_NEAR(static_cast<double>(some.size() - some_in), 120.0, 3.0);
  int quadrant[4] = {0, 0, 0, 0};
  for (const auto& c : some)
    if (!inside(c)) ++quadrant[(c.x >= calib->width / 2 ? 1 : 0) + (c.y >= calib->height / 2 ? 2 : 0)];
  for (int q : quadrant)
    EXPECT_GE(q, 15) << quadrant[0] << " " << quadrant[1] << " " << quadrant[2] << " " << quadrant[3];

  // The same inside the candidates: at most max_candidate_corners there,
  // spread over them, the corners outside untouched.
  MotionCueOptions in = all;
  in.max_candidate_corners = 12;
  const auto fewer_in = detect_corners(p.prev.grey, in, candidates);
  std::vector<cv::Point2f> every_out, fewer_out, kept_in;
  for (const auto& c : every)
    if (!inside(c)) every_out.push_back(c);
  for (const auto& c : fewer_in) (inside(c) ? kept_in : fewer_out).push_back(c);
  EXPECT_EQ(fewer_out, every_out);
  EXPECT_NEAR(static_cast<double>(kept_in.size()), 12.0, 2.0);
  int half[2] = {0, 0};  // left and right half of the candidates' box
  for (const auto& c : kept_in) ++half[c.x >= 280 ? 1 : 0];
  EXPECT_GE(std::min(half[0], half[1]), 3) << half[0] << " " << half[1];

  // A budget no detection can exceed, or no candidates mask with no budget:
  // the same corners as without the option.
  MotionCueOptions large;
  large.max_background_corners = large.max_corners;
  large.max_candidate_corners = large.max_corners;
  EXPECT_EQ(detect_corners(p.prev.grey, large, candidates), every);
  MotionCueOptions no_mask = all;
  no_mask.max_candidate_corners = 5;
  EXPECT_EQ(detect_corners(p.prev.grey, no_mask, cv::Mat()), detect_corners(p.prev.grey, all));
  EXPECT_EQ(detect_corners(p.prev.grey, all, cv::Mat()), detect_corners(p.prev.grey, all));

  // track_points applies the budget with prev.candidates; the ego-motion
  // from the subset is still accurate.
  p.prev.candidates = candidates;
  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_LE(pts.size(), some.size());
  ASSERT_GT(pts.size(), 100u);
  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
  ASSERT_TRUE(ego.valid);
  EXPECT_LT(rotation_error_deg(ego.T_cur_prev, kMotion), 0.1);
  EXPECT_LT((ego.T_cur_prev.translation() - kMotion.translation()).norm(), 0.01);
}

// A low-contrast mover (its texture at 10 % contrast) in a view with strong
// corners elsewhere, with candidates that stop short of the patch's outline
// (whose step against the full-contrast room would be the strongest corner
// inside them).
struct LowContrastMover {
  cv::Mat grey, candidates;
  cv::Rect mover;
  LowContrastMover() {
    auto calib = make_calibration(Sensor::kRGBD);
    Pair p = render_pair(*calib, Sensor::kRGBD);
    const cv::Rect patch(380, 150, 180, 220);
    grey = p.prev.grey.clone();
    cv::Mat part;
    grey(patch).convertTo(part, CV_8U, 0.1, 0.9 * cv::mean(grey(patch))[0]);
    part.copyTo(grey(patch));
    mover = cv::Rect(patch.x + 10, patch.y + 10, patch.width - 20, patch.height - 20);
    candidates = cv::Mat::zeros(grey.size(), CV_8UC1);
    candidates(mover).setTo(255);
  }
  // detect_corners with `o`, split into the corners on the mover and the rest.
  void detect(const MotionCueOptions& o, std::vector<cv::Point2f>& in, std::vector<cv::Point2f>& out) const {
    for (const auto& c : detect_corners(grey, o, candidates))
      (mover.contains(cv::Point(cvRound(c.x), cvRound(c.y))) ? in : out).push_back(c);
  }
};

// One detection over the image finds almost no corners on the mover, so none
// of its points could be judged. With candidate_quality_level the candidates
// get their own detection; the background keeps its corners.
TEST(MotionCues, CandidatesGetTheirOwnCornerQuality) {
  const LowContrastMover m;
  MotionCueOptions one;
  one.subpix_window = 0;  // the detections themselves
  std::vector<cv::Point2f> one_in, one_out;
  m.detect(one, one_in, one_out);
  MotionCueOptions own = one;
  own.candidate_quality_level = 0.001;
  std::vector<cv::Point2f> own_in, own_out;
  m.detect(own, own_in, own_out);
  EXPECT_LE(one_in.size(), 3u);  // measured: 0 and 148
  EXPECT_GE(own_in.size(), 30u);
  EXPECT_EQ(own_out, one_out);
  // Not below quality_level, or without candidates: one detection, as before.
  MotionCueOptions higher = one;
  higher.candidate_quality_level = 0.05;
  EXPECT_EQ(detect_corners(m.grey, higher, m.candidates), detect_corners(m.grey, one, m.candidates));
  EXPECT_EQ(detect_corners(m.grey, own, cv::Mat()), detect_corners(m.grey, one, cv::Mat()));
}

// The same with FAST: candidate_fast_threshold below fast_threshold gives the
// candidates a detection of their own.
TEST(MotionCues, FastCandidatesGetTheirOwnThreshold) {
  const LowContrastMover m;
  MotionCueOptions one;
  one.detector = "fast";
  one.subpix_window = 0;
  one.candidate_fast_threshold = one.fast_threshold;  // one detection
  MotionCueOptions own = one;
  own.candidate_fast_threshold = 3;
  std::vector<cv::Point2f> one_in, one_out, own_in, own_out;
  m.detect(one, one_in, one_out);
  m.detect(own, own_in, own_out);
  EXPECT_LE(one_in.size(), 3u);
  EXPECT_GE(own_in.size(), 30u);
  EXPECT_EQ(own_out, one_out);
  EXPECT_EQ(detect_corners(m.grey, own, cv::Mat()), detect_corners(m.grey, one, cv::Mat()));
}

// detector: fast. The corners are FAST's own (pixel positions, each a
// FAST keypoint at the threshold), the strongest first at least min_distance
// apart; tracked like the Harris corners, they give the same ego-motion.
TEST(MotionCues, FastCornersAreSpreadFastKeypointsThatTrackLikeHarris) {
  auto calib = make_calibration(Sensor::kRGBD);
  Pair p = render_pair(*calib, Sensor::kRGBD);
  MotionCueOptions o;
  o.detector = "fast";
  o.subpix_window = 0;
  const auto corners = detect_corners(p.prev.grey, o);
  ASSERT_GT(corners.size(), 150u);
  std::vector<cv::KeyPoint> fast;
  cv::FAST(p.prev.grey, fast, o.fast_threshold, true);
  std::set<std::pair<int, int>> at;
  for (const auto& k : fast) at.insert({cvRound(k.pt.x), cvRound(k.pt.y)});
  for (size_t i = 0; i < corners.size(); ++i) {
    const cv::Point2f& c = corners[i];
    EXPECT_EQ(c.x, std::round(c.x));
    EXPECT_EQ(c.y, std::round(c.y));
    EXPECT_TRUE(at.count({cvRound(c.x), cvRound(c.y)})) << c;
    EXPECT_GE(std::min({c.x, c.y}), o.border);
    EXPECT_LE(c.x, calib->width - 1 - o.border);
    EXPECT_LE(c.y, calib->height - 1 - o.border);
    for (size_t j = 0; j < i; ++j) ASSERT_GE(cv::norm(c - corners[j]), o.min_distance) << c << corners[j];
  }
  // The budget: the strongest come first.
  MotionCueOptions few = o;
  few.max_corners = 40;
  const auto strongest = detect_corners(p.prev.grey, few);
  ASSERT_EQ(strongest.size(), 40u);
  EXPECT_TRUE(std::equal(strongest.begin(), strongest.end(), corners.begin()));

  const auto pts = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_GT(pts.size(), 100u);
  int close = 0, with_depth = 0;
  for (const auto& t : pts) {
    if (!(t.prev_depth > 0)) continue;
    ++with_depth;
    close += cv::norm(t.cur - true_flow(*calib, t.prev, t.prev_depth)) < 0.5;
  }
  EXPECT_GT(close, 0.9 * with_depth) << close << " of " << with_depth;
  const EgoMotion ego = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
  ASSERT_TRUE(ego.valid);
  EXPECT_LT(rotation_error_deg(ego.T_cur_prev, kMotion), 0.1);
  EXPECT_LT((ego.T_cur_prev.translation() - kMotion.translation()).norm(), 0.01);
}

TEST(MotionCues, DegenerateInputGivesNothingAndNeverThrows) {
  auto calib = make_calibration(Sensor::kRGBD);
  Pair p = render_pair(*calib, Sensor::kRGBD);
  const MotionCueOptions o;

  FrameData empty;  // no previous frame
  EXPECT_TRUE(track_points(empty, p.cur, *calib, Sensor::kRGBD, o).empty());
  EXPECT_TRUE(track_points(p.prev, empty, *calib, Sensor::kRGBD, o).empty());

  FrameData small = p.cur;
  small.grey = p.cur.grey(cv::Rect(0, 0, 320, 240)).clone();
  EXPECT_TRUE(track_points(p.prev, small, *calib, Sensor::kRGBD, o).empty());

  FrameData colour = p.cur;
  cv::cvtColor(p.cur.grey, colour.grey, cv::COLOR_GRAY2BGR);
  EXPECT_TRUE(track_points(p.prev, colour, *calib, Sensor::kRGBD, o).empty());

  FrameData flat = p.prev, flat_cur = p.cur;
  flat.grey = cv::Mat(480, 640, CV_8UC1, cv::Scalar(128));
  flat_cur.grey = flat.grey.clone();
  EXPECT_TRUE(track_points(flat, flat_cur, *calib, Sensor::kRGBD, o).empty());

  FrameData tiny = p.prev, tiny_cur = p.cur;
  tiny.grey = p.prev.grey(cv::Rect(0, 0, 15, 15)).clone();
  tiny_cur.grey = tiny.grey.clone();
  tiny.depth = cv::Mat();
  EXPECT_TRUE(track_points(tiny, tiny_cur, *calib, Sensor::kRGBD, o).empty());

  // Depth with holes and NaN: those points get no depth, the rest keep theirs.
  FrameData holes = p.prev;
  holes.depth = p.prev.depth.clone();
  holes.depth(cv::Rect(0, 0, 320, 480)).setTo(std::numeric_limits<float>::quiet_NaN());
  holes.depth(cv::Rect(320, 0, 320, 240)).setTo(0);
  const auto with_holes = track_points(holes, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_FALSE(with_holes.empty());
  int zero = 0;
  for (const auto& t : with_holes) {
    EXPECT_TRUE(std::isfinite(t.prev_depth));
    if (t.prev.x < 319 || t.prev.y < 239) { EXPECT_EQ(t.prev_depth, 0.f); }
    zero += t.prev_depth == 0.f;
  }
  EXPECT_GT(zero, 0);

  // No depth at all (wrong type): the pose cannot be estimated, F still is.
  FrameData no_depth = p.prev;
  p.prev.depth.convertTo(no_depth.depth, CV_16UC1, 5000);
  const auto pts = track_points(no_depth, p.cur, *calib, Sensor::kRGBD, o);
  ASSERT_GT(pts.size(), 100u);
  const EgoMotion e = estimate_ego_motion(pts, *calib, Sensor::kRGBD, o);
  EXPECT_FALSE(e.valid);
  EXPECT_TRUE(e.has_F);

  // Too few points, none, NaN, and a calibration without focal length.
  const auto good = track_points(p.prev, p.cur, *calib, Sensor::kRGBD, o);
  std::vector<TrackedPoint> few(good.begin(), good.begin() + 7);
  EXPECT_FALSE(estimate_ego_motion(few, *calib, Sensor::kRGBD, o).valid);
  EXPECT_FALSE(estimate_ego_motion({}, *calib, Sensor::kMono, o).valid);
  std::vector<TrackedPoint> nan = good;
  for (auto& t : nan) t.cur.x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(estimate_ego_motion(nan, *calib, Sensor::kRGBD, o).valid);
  map::Calibration bad = *calib;
  bad.fx = 0;
  EXPECT_FALSE(estimate_ego_motion(good, bad, Sensor::kRGBD, o).valid);

  // All points identical: RANSAC has nothing to fit.
  std::vector<TrackedPoint> same(30);
  for (auto& t : same) {
    t.prev = t.cur = cv::Point2f(100, 100);
    t.prev_depth = 2;
  }
  const EgoMotion s = estimate_ego_motion(same, *calib, Sensor::kRGBD, o);
  EXPECT_FALSE(s.valid);
}

TEST(MotionCues, OptionsReadFromYaml) {
  cv::FileStorage fs(
      "%YAML:1.0\nmotion:\n  max_corners: 500\n  use_harris: 0\n  border: 5\n  forward_backward_max: 0.5\n"
      "  stereo_depth_forward_backward_max: 0.25\n  max_background_corners: 200\n"
      "  candidate_quality_level: 0.002\n  detector: fast\n  fast_threshold: 25\n"
      "  candidate_fast_threshold: 9\n  max_candidate_corners: 150\n"
      "bad:\n  max_corners: many\n",
      cv::FileStorage::READ | cv::FileStorage::MEMORY);
  MotionCueOptions o;
  o.read(fs["motion"]);
  EXPECT_EQ(o.max_corners, 500);
  EXPECT_FALSE(o.use_harris);
  EXPECT_EQ(o.border, 5);
  EXPECT_DOUBLE_EQ(o.forward_backward_max, 0.5);
  EXPECT_DOUBLE_EQ(o.stereo_depth_forward_backward_max, 0.25);
  EXPECT_EQ(o.max_background_corners, 200);
  EXPECT_DOUBLE_EQ(o.candidate_quality_level, 0.002);
  EXPECT_EQ(o.detector, "fast");
  EXPECT_EQ(o.fast_threshold, 25);
  EXPECT_EQ(o.candidate_fast_threshold, 9);
  EXPECT_EQ(o.max_candidate_corners, 150);
  EXPECT_DOUBLE_EQ(o.quality_level, 0.01);  // missing: default kept
  EXPECT_EQ(o.min_ego_points, 12);
  MotionCueOptions b;
  EXPECT_THROW(b.read(fs["bad"]), InputError);
  MotionCueOptions c;
  c.read(fs["absent"]);
  EXPECT_EQ(c.max_corners, 1000);
}

TEST(MotionCues, OptionsOutOfRangeAreRefusedByName) {
  EXPECT_NO_THROW(MotionCueOptions().validate());
  MotionCueOptions on;
  on.candidate_quality_level = 0.005;  // below quality_level: used
  on.forward_backward_max = 0;         // no backward check
  on.max_background_corners = 0;        // all
  EXPECT_NO_THROW(on.validate());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::pair<std::string, std::function<void(MotionCueOptions&)>>> bad = {
      {"max_corners", [](MotionCueOptions& o) { o.max_corners = 0; }},
      {"min_distance", [](MotionCueOptions& o) { o.min_distance = -0.5; }},
      {"min_distance", [&](MotionCueOptions& o) { o.min_distance = nan; }},
      {"quality_level", [](MotionCueOptions& o) { o.quality_level = 0; }},
      {"quality_level", [&](MotionCueOptions& o) { o.quality_level = nan; }},
      {"candidate_quality_level", [](MotionCueOptions& o) { o.candidate_quality_level = 0.01; }},
      {"candidate_quality_level", [&](MotionCueOptions& o) { o.candidate_quality_level = nan; }},
      {"lk_window", [](MotionCueOptions& o) { o.lk_window = 2; }},
      {"lk_epsilon", [](MotionCueOptions& o) { o.lk_epsilon = 0; }},
      {"forward_backward_max", [&](MotionCueOptions& o) { o.forward_backward_max = nan; }},
      {"depth_edge_max_ratio", [](MotionCueOptions& o) { o.depth_edge_max_ratio = -0.1; }},
      {"ransac_reprojection_px", [](MotionCueOptions& o) { o.ransac_reprojection_px = 0; }},
      {"ransac_confidence", [](MotionCueOptions& o) { o.ransac_confidence = 1; }},
      {"min_ego_points", [](MotionCueOptions& o) { o.min_ego_points = 4; }},
      {"max_background_corners", [](MotionCueOptions& o) { o.max_background_corners = -5; }},
      {"max_candidate_corners", [](MotionCueOptions& o) { o.max_candidate_corners = -1; }},
      {"detector", [](MotionCueOptions& o) { o.detector = "sift"; }},
      {"fast_threshold", [](MotionCueOptions& o) { o.fast_threshold = 0; }},
      {"candidate_fast_threshold", [](MotionCueOptions& o) { o.candidate_fast_threshold = 255; }},
  };
  for (const auto& [key, change] : bad) {
    MotionCueOptions o;
    change(o);
    try {
      o.validate();
      ADD_FAILURE() << key << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("'" + key + "'"), std::string::npos) << e.what();
    }
  }
  // Through a preset: refused when it is loaded, the file and the key named (as a stage's options are),
  // with or without stages that use them.
  for (const std::string stages : {"[semantic, dm]", "[]"}) {
    try {
      DynamicFilterOptions::parse("Dynamic.stages: " + stages +
                                      "\nDynamic.motion_cues:\n  candidate_quality_level: 0.02\n",
                                  "mine.yaml");
      ADD_FAILURE() << stages << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("mine.yaml"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("'candidate_quality_level' is 0.02"), std::string::npos) << e.what();
    }
  }
  // Options built in code are checked by validate(sensor), which the filter and the System call.
  DynamicFilterOptions o = DynamicFilterOptions::parse("Dynamic.stages: [semantic, dm]\n", "mine.yaml");
  o.motion_cues.min_ego_points = 3;
  try {
    o.validate(Sensor::kRGBD);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mine.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'min_ego_points' is 3"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dynaorb::dynamic
