// Dynamic feature points (Li et al. Sec. III-A, eq. 1-3) on the rendered
// stereo pair of li_test_scene.h: the quadtree spreads the corners, F is the
// camera's, points on the walking box break the epipolar constraint and the
// static ones keep it.
#include <gtest/gtest.h>

#include <cstdio>

#include "dynaorb/dynamic/li_disparity.h"
#include "dynaorb/dynamic/li_epipolar.h"
#include "li_test_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

TEST(LiEpipolar, QuadtreeSpreadsTheCorners) {
  // Texture only in the left third, but strong, plus faint texture elsewhere:
  // plain strongest-N FAST would put every corner in the left third.
  cv::Mat img = random_texture(640, 480, 5);
  cv::Mat faint = random_texture(640, 480, 6);
  faint.convertTo(faint, CV_8U, 0.15, 100);
  faint(cv::Rect(213, 0, 427, 480)).copyTo(img(cv::Rect(213, 0, 427, 480)));
  LiOptions o;
  const auto pts = li_quadtree_fast(img, o);
  ASSERT_GE(static_cast<int>(pts.size()), o.n_points * 9 / 10);
  ASSERT_LE(static_cast<int>(pts.size()), o.n_points + 3);
  int right = 0;
  for (const auto& p : pts) {
    right += p.x >= 213 ? 1 : 0;
    EXPECT_GE(p.x, o.border_px);
    EXPECT_LT(p.x, 640 - o.border_px);
  }
  EXPECT_GT(right, static_cast<int>(pts.size()) / 3);
  EXPECT_TRUE(li_quadtree_fast(cv::Mat(), o).empty());
}

TEST(LiEpipolar, BoxPointsBreakTheEpipolarConstraint) {
  const auto calib = make_calibration(Sensor::kStereo, 640, 480, 500, 0.1);
  const auto pair = dynaorb::test::li::render_stereo_pair(*calib);
  LiOptions o;
  const cv::Mat disparity = li_disparity(pair.cur->grey, pair.cur->right, o);
  const LiEpipolarResult r = li_epipolar_check(pair.prev->grey, pair.cur->grey, disparity, *calib, o);
  ASSERT_TRUE(r.failure.empty()) << r.failure;
  ASSERT_TRUE(r.has_F);

  // F against the camera's true motion: the true epipolar lines of the static
  // tracks agree with the estimated ones to a fraction of a pixel.
  const Eigen::Isometry3d& T = dynaorb::test::li::camera_motion();
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d t = T.translation();
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  const Eigen::Matrix3d Kinv = calib->K_eigen().inverse();
  const Eigen::Matrix3d Fe = Kinv.transpose() * tx * R * Kinv;
  cv::Matx33d F_true;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) F_true(i, j) = Fe(i, j);

  int box_n = 0, box_dyn = 0, static_n = 0, static_dyn = 0;
  std::vector<double> disagreement;
  for (const LiTrack& tr : r.tracks) {
    if (tr.distance < 0) continue;
    EXPECT_GT(tr.disparity, 0.f);
    EXPECT_NEAR(tr.threshold, o.alpha_epi + o.beta_epi * tr.disparity, 1e-9);  // eq. 3
    const int obj = pair.cur_view.object.at<int>(cvRound(tr.cur.y), cvRound(tr.cur.x));
    const int obj_prev = pair.prev_view.object.at<int>(cvRound(tr.prev.y), cvRound(tr.prev.x));
    if (obj == dynaorb::test::li::kMoverIndex && obj_prev == obj) {
      ++box_n;
      box_dyn += tr.dynamic ? 1 : 0;
    } else if (obj != dynaorb::test::li::kMoverIndex && obj_prev != dynaorb::test::li::kMoverIndex) {
      ++static_n;
      static_dyn += tr.dynamic ? 1 : 0;
      disagreement.push_back(std::abs(epipolar_distance(F_true, tr.prev, tr.cur) - tr.distance));
    }
  }
  ASSERT_GT(box_n, 20);
  ASSERT_GT(static_n, 200);
  EXPECT_GT(box_dyn, 0.8 * box_n);
  EXPECT_LT(static_dyn, 0.06 * static_n);
  EXPECT_LT(median(disagreement), 0.1);
  int judged = 0, dyn = 0;
  for (const LiTrack& tr : r.tracks) judged += tr.distance >= 0 ? 1 : 0, dyn += tr.dynamic ? 1 : 0;
  EXPECT_EQ(judged, r.judged);
  EXPECT_EQ(dyn, r.dynamic);
  std::printf("box %d/%d dynamic, static %d/%d dynamic, |D_est - D_true| median %.3f px\n", box_dyn, box_n,
              static_dyn, static_n, median(disagreement));
}

// f_exclude_previous_dynamic: F is fitted to the pairs starting outside the
// previous frame's dynamic mask, every pair is judged by it; with too few
// left, or the option off, F is fitted to all of them.
TEST(LiEpipolar, FIsFittedOutsideThePreviousDynamicMask) {
  const auto calib = make_calibration(Sensor::kStereo, 640, 480, 500, 0.1);
  const auto pair = dynaorb::test::li::render_stereo_pair(*calib);
  LiOptions o;
  o.f_exclude_previous_dynamic = true;
  const cv::Mat disparity = li_disparity(pair.cur->grey, pair.cur->right, o);
  const cv::Mat box = pair.prev_view.object == dynaorb::test::li::kMoverIndex;  // CV_8UC1 255 on the box
  const LiEpipolarResult r = li_epipolar_check(pair.prev->grey, pair.cur->grey, disparity, *calib, o, box);
  ASSERT_TRUE(r.has_F) << r.failure;
  int in_box = 0, box_n = 0, box_dyn = 0, static_n = 0, static_dyn = 0;
  for (const LiTrack& tr : r.tracks) {
    const bool from_box = box.at<unsigned char>(cvRound(tr.prev.y), cvRound(tr.prev.x)) != 0;
    in_box += from_box ? 1 : 0;
    if (tr.distance < 0) continue;
    (from_box ? box_n : static_n) += 1;
    (from_box ? box_dyn : static_dyn) += tr.dynamic ? 1 : 0;
  }
  ASSERT_GT(in_box, 20);
  EXPECT_EQ(r.f_excluded, in_box);
  EXPECT_EQ(r.f_fitted, static_cast<int>(r.tracks.size()) - in_box);
  EXPECT_LE(r.f_inliers, r.f_fitted);
  // The box's pairs are still judged, and still found moving.
  EXPECT_GT(box_dyn, 0.8 * box_n);
  EXPECT_LT(static_dyn, 0.06 * static_n);

  // A mask over everything leaves fewer than min_points: F from all pairs.
  const cv::Mat all(box.size(), CV_8UC1, cv::Scalar(255));
  const LiEpipolarResult a = li_epipolar_check(pair.prev->grey, pair.cur->grey, disparity, *calib, o, all);
  ASSERT_TRUE(a.has_F);
  EXPECT_EQ(a.f_excluded, static_cast<int>(a.tracks.size()));
  EXPECT_EQ(a.f_fitted, static_cast<int>(a.tracks.size()));
  // Off (the paper), or a mask of another size: the mask is not read.
  o.f_exclude_previous_dynamic = false;
  const LiEpipolarResult off = li_epipolar_check(pair.prev->grey, pair.cur->grey, disparity, *calib, o, box);
  EXPECT_EQ(off.f_excluded, 0);
  EXPECT_EQ(off.f_fitted, static_cast<int>(off.tracks.size()));
  o.f_exclude_previous_dynamic = true;
  const LiEpipolarResult small =
      li_epipolar_check(pair.prev->grey, pair.cur->grey, disparity, *calib, o, cv::Mat(10, 10, CV_8UC1, cv::Scalar(255)));
  EXPECT_EQ(small.f_excluded, 0);
  EXPECT_EQ(small.f_fitted, static_cast<int>(small.tracks.size()));
}

TEST(LiEpipolar, TooFewTracksNoF) {
  const auto calib = make_calibration(Sensor::kStereo, 640, 480, 500, 0.1);
  const cv::Mat flat(480, 640, CV_8UC1, cv::Scalar(100));
  const LiEpipolarResult r =
      li_epipolar_check(flat, flat, cv::Mat(480, 640, CV_32FC1, cv::Scalar(10)), *calib, LiOptions());
  EXPECT_EQ(r.failure, "too_few_points");
  EXPECT_FALSE(r.has_F);
  EXPECT_EQ(r.dynamic, 0);
  // Mismatched sizes: nothing tracked, no crash.
  const LiEpipolarResult m =
      li_epipolar_check(random_texture(640, 480, 1), cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)), cv::Mat(), *calib,
                        LiOptions());
  EXPECT_EQ(m.failure, "too_few_points");
  EXPECT_TRUE(m.tracks.empty());
}

TEST(LiEpipolar, DisparityAtFallsBackToTheNeighbourhood) {
  cv::Mat d(9, 9, CV_32FC1, cv::Scalar(0));
  d.at<float>(4, 6) = 12.f;
  d.at<float>(3, 5) = 10.f;
  d.at<float>(5, 5) = 11.f;
  EXPECT_FLOAT_EQ(li_disparity_at(d, {6, 4}, 2), 12.f);  // its own
  EXPECT_FLOAT_EQ(li_disparity_at(d, {4, 4}, 2), 11.f);  // median of 10, 11, 12
  EXPECT_FLOAT_EQ(li_disparity_at(d, {0, 8}, 2), 0.f);   // none near
  EXPECT_FLOAT_EQ(li_disparity_at(d, {-5, 4}, 2), 0.f);  // outside
}

}  // namespace
}  // namespace dynaorb::dynamic
