// Li's step 2 with our rigidity check (li_rigidity.h), on LK pairs made from
// known 3-D points and a known camera motion: an object travelling with the
// camera (its pairs judged static by eq. 3) is found, a lone bad pair is not,
// and SLAM's prediction keeps a larger rigid mover from winning the PnP.
#include <gtest/gtest.h>

#include <random>

#include "dynaorb/dynamic/li_rigidity.h"
#include "synthetic_scene.h"

namespace dynaorb::dynamic {
namespace {

using namespace dynaorb::test::synth;

class LiRigidity : public ::testing::Test {
 protected:
  void SetUp() override {
    calib_ = make_calibration(Sensor::kStereo, 640, 480, 500, 0.1);
    depth_ = cv::Mat::zeros(480, 640, CV_32FC1);
    // The camera moves 0.15 m forward and turns 1 degree about y.
    T_ = Eigen::Isometry3d::Identity();
    T_.linear() = Eigen::AngleAxisd(M_PI / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
    T_.translation() = Eigen::Vector3d(0, 0, -0.15);
  }

  // A pair of the 3-D point X (previous camera) that moves by `motion`
  // (previous camera's axes) before the current frame; eq. 3 judged it
  // (`epipolar_dynamic`), its previous depth goes into the depth image.
  void add(const Eigen::Vector3d& X, const Eigen::Vector3d& motion = Eigen::Vector3d::Zero(),
           bool epipolar_dynamic = false, cv::Point2f noise = {0, 0}) {
    const Eigen::Vector2d p = calib_->project(X);
    ASSERT_TRUE(calib_->in_image(p));
    const Eigen::Vector3d Y = T_ * (X + motion);
    const Eigen::Vector2d q = calib_->project(Y);
    LiTrack t;
    t.prev = t.prev_u = cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
    t.cur = t.cur_u = cv::Point2f(static_cast<float>(q.x()), static_cast<float>(q.y())) + noise;
    t.disparity = static_cast<float>(calib_->bf / Y.z());
    t.distance = epipolar_dynamic ? 5 : 0;
    t.dynamic = epipolar_dynamic;
    e_.tracks.push_back(t);
    depth_.at<float>(cvRound(p.y()), cvRound(p.x())) = static_cast<float>(X.z());
  }

  // n points on a wall at depth 5-7 m over the whole view, from `seed`.
  void add_background(int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-0.5, 0.5), z(5, 7);
    for (int i = 0; i < n; ++i) {
      const double depth = z(rng);
      add({u(rng) * 1.1 * depth, u(rng) * 0.8 * depth, depth});
    }
  }

  std::shared_ptr<map::Calibration> calib_;
  cv::Mat depth_;
  Eigen::Isometry3d T_;
  LiEpipolarResult e_;
  LiOptions o_;
};

TEST_F(LiRigidity, FindsAnObjectTravellingWithTheCamera) {
  add_background(200, 1);
  // A vehicle beside the camera, 3 m ahead, driving 0.1 m forward in the
  // frame: its pairs stay on their epipolar lines, eq. 3 left them static.
  std::vector<int> vehicle;
  for (int i = 0; i < 15; ++i) {
    vehicle.push_back(static_cast<int>(e_.tracks.size()));
    add({1.0 + 0.03 * (i % 5), -0.2 + 0.08 * (i / 5), 3.0}, {0, 0, 0.1});
  }
  // A static pair LK lost track of: 4 px off, alone.
  const int lone = static_cast<int>(e_.tracks.size());
  add({-1.0, 0.5, 6.0}, Eigen::Vector3d::Zero(), false, {4, 0});

  const LiRigidityResult r = li_rigidity_check(e_, depth_, *calib_, std::nullopt, o_);
  ASSERT_TRUE(r.has_motion) << r.failure;
  EXPECT_FALSE(r.used_prior);
  EXPECT_LT((r.T_cur_prev.translation() - T_.translation()).norm(), 0.01);
  EXPECT_EQ(r.judged, 216);
  for (int i : vehicle) {
    EXPECT_TRUE(e_.tracks[i].dynamic) << i;
    EXPECT_GT(e_.tracks[i].rigid_residual, e_.tracks[i].rigid_threshold);
  }
  EXPECT_FALSE(e_.tracks[lone].dynamic);  // over its threshold, but no neighbour agrees
  EXPECT_GT(e_.tracks[lone].rigid_residual, e_.tracks[lone].rigid_threshold);
  EXPECT_EQ(r.over_threshold, 16);
  EXPECT_EQ(r.added, 15);
  EXPECT_EQ(e_.dynamic, 15);
  for (int i = 0; i < 200; ++i) EXPECT_FALSE(e_.tracks[i].dynamic) << i;
}

TEST_F(LiRigidity, WithoutAgreementEveryPairOverItsThresholdIsDynamic) {
  add_background(200, 2);
  const int lone = static_cast<int>(e_.tracks.size());
  add({-1.0, 0.5, 6.0}, Eigen::Vector3d::Zero(), false, {4, 0});
  o_.rigid_min_agreeing = 0;
  const LiRigidityResult r = li_rigidity_check(e_, depth_, *calib_, std::nullopt, o_);
  ASSERT_TRUE(r.has_motion) << r.failure;
  EXPECT_TRUE(e_.tracks[lone].dynamic);
  EXPECT_EQ(r.added, 1);
}

TEST_F(LiRigidity, ThePredictionKeepsALargeRigidMoverOutOfThePnp) {
  add_background(120, 3);
  // A person crossing close to the camera, more pairs than the background,
  // and eq. 3's F locked onto it: all judged static.
  std::vector<int> person;
  for (int i = 0; i < 200; ++i) {
    person.push_back(static_cast<int>(e_.tracks.size()));
    add({-0.4 + 0.04 * (i % 20), -0.5 + 0.1 * (i / 20), 2.5 + 0.002 * i}, {0.12, 0, 0});
  }
  // Without the prediction the PnP takes the person's motion.
  LiEpipolarResult alone = e_;
  ASSERT_TRUE(li_rigidity_check(alone, depth_, *calib_, std::nullopt, o_).has_motion);
  int person_marked = 0;
  for (int i : person) person_marked += alone.tracks[i].dynamic ? 1 : 0;
  EXPECT_EQ(person_marked, 0);

  // With it (1 px off) the PnP runs on the pairs it explains: the background.
  Eigen::Isometry3d prior = T_;
  prior.translation() += Eigen::Vector3d(0.002, 0, 0.002);
  const LiRigidityResult r = li_rigidity_check(e_, depth_, *calib_, prior, o_);
  ASSERT_TRUE(r.has_motion) << r.failure;
  EXPECT_TRUE(r.used_prior);
  EXPECT_EQ(r.candidates, 120);
  for (int i : person) EXPECT_TRUE(e_.tracks[i].dynamic) << i;
  for (int i = 0; i < 120; ++i) EXPECT_FALSE(e_.tracks[i].dynamic) << i;
}

TEST_F(LiRigidity, APredictionThatExplainsNothingFallsBackToEq3) {
  add_background(100, 4);
  Eigen::Isometry3d wrong = T_;
  wrong.translation() += Eigen::Vector3d(0.5, 0, 0);
  const LiRigidityResult r = li_rigidity_check(e_, depth_, *calib_, wrong, o_);
  ASSERT_TRUE(r.has_motion) << r.failure;
  EXPECT_FALSE(r.used_prior);
  EXPECT_EQ(r.candidates, 100);
  EXPECT_EQ(r.added, 0);
}

TEST_F(LiRigidity, DegradesWithoutDepthOrPairs) {
  add_background(10, 5);
  LiEpipolarResult copy = e_;
  EXPECT_EQ(li_rigidity_check(copy, cv::Mat(), *calib_, std::nullopt, o_).failure, "no_previous_depth");
  EXPECT_EQ(li_rigidity_check(copy, depth_, *calib_, std::nullopt, o_).failure, "too_few_points");
  EXPECT_EQ(li_rigidity_check(copy, cv::Mat::zeros(480, 640, CV_32FC1), *calib_, std::nullopt, o_).failure,
            "too_few_points");
  for (const LiTrack& t : copy.tracks) EXPECT_FALSE(t.dynamic);
}

}  // namespace
}  // namespace dynaorb::dynamic
