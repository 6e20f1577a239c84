// TrackerOptions::validate: the defaults pass; a bad value of each kind
// (two_view's and reloc.pnp's included) is refused with an InputError that
// names the field.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "dynaorb/io/errors.h"
#include "dynaorb/tracking/tracker.h"
#include "../test_util.h"

namespace dynaorb {
namespace {

using tracking::TrackerOptions;

std::string refusal(const std::function<void(TrackerOptions&)>& change) {
  return test::validation_refusal<TrackerOptions>(change);
}

TEST(TrackerOptions, DefaultsAreValid) { EXPECT_NO_THROW(TrackerOptions().validate()); }

TEST(TrackerOptions, ZeroIsAcceptedWhereItMeansOff) {
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.new_map_after_lost_s = 0; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.refine_lag_keyframes = 0; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.pose_final_huber = 0; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.min_frames = 0; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.stereo_right_budget_max_factor = 1; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.ref_ratio_mono = 1; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.two_view.min_parallax_deg = 0; }), "");
  EXPECT_EQ(refusal([](TrackerOptions& o) { o.two_view.homography_sample = 8; }), "");  // ORB-SLAM2's code
}

// max_frames: -1 (the default) is the camera's fps, as ORB-SLAM2's
// mMaxFrames; a value the user sets is kept.
TEST(TrackerOptions, MaxFramesIsTheCameraFpsUnlessSet) {
  EXPECT_EQ(TrackerOptions().max_frames, -1);
  EXPECT_EQ(TrackerOptions().with_camera_fps(10).max_frames, 10);
  EXPECT_EQ(TrackerOptions().with_camera_fps(20.4).max_frames, 20);
  EXPECT_EQ(TrackerOptions().with_camera_fps(0).max_frames, 30);  // no fps known
  EXPECT_EQ(TrackerOptions().with_camera_fps(std::numeric_limits<double>::quiet_NaN()).max_frames, 30);
  TrackerOptions set;
  set.max_frames = 7;
  EXPECT_EQ(set.with_camera_fps(10).max_frames, 7);
  set.max_frames = 0;  // a keyframe whenever local mapping is idle
  EXPECT_EQ(set.with_camera_fps(10).max_frames, 0);
  EXPECT_NE(refusal([](TrackerOptions& o) { o.max_frames = -2; }).find("'max_frames' is -2"), std::string::npos);
}

TEST(TrackerOptions, BadValuesAreRefusedByName) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  struct Case {
    std::string field;
    std::function<void(TrackerOptions&)> change;
  };
  const std::vector<Case> cases = {
      {"'new_map_after_lost_s' is nan", [&](TrackerOptions& o) { o.new_map_after_lost_s = nan; }},
      {"'new_map_after_lost_s' is -1", [](TrackerOptions& o) { o.new_map_after_lost_s = -1; }},
      {"'new_map_after_lost_s' is inf", [&](TrackerOptions& o) { o.new_map_after_lost_s = inf; }},
      {"'min_local_map_inliers' is -5", [](TrackerOptions& o) { o.min_local_map_inliers = -5; }},
      {"'reloc.min_inliers' is -1", [](TrackerOptions& o) { o.reloc.min_inliers = -1; }},
      {"'max_local_keyframes' is 0", [](TrackerOptions& o) { o.max_local_keyframes = 0; }},
      {"'max_sharing_keyframes' is -1", [](TrackerOptions& o) { o.max_sharing_keyframes = -1; }},
      {"'refine_lag_keyframes' is -1", [](TrackerOptions& o) { o.refine_lag_keyframes = -1; }},
      {"'refine_min_points' is 0", [](TrackerOptions& o) { o.refine_min_points = 0; }},
      {"'refine_rounds' is 0", [](TrackerOptions& o) { o.refine_rounds = 0; }},
      {"'refine_max_pending' is 0", [](TrackerOptions& o) { o.refine_max_pending = 0; }},
      {"'pose_final_huber' is -0.5", [](TrackerOptions& o) { o.pose_final_huber = -0.5; }},
      {"'pose_final_huber' is nan", [&](TrackerOptions& o) { o.pose_final_huber = nan; }},
      {"'pose_final_huber_mono' is inf", [&](TrackerOptions& o) { o.pose_final_huber_mono = inf; }},
      {"'mono_init_feature_factor' is 0", [](TrackerOptions& o) { o.mono_init_feature_factor = 0; }},
      {"'motion_th_stereo' is 0", [](TrackerOptions& o) { o.motion_th_stereo = 0; }},
      {"'reloc.wide_window' is nan", [&](TrackerOptions& o) { o.reloc.wide_window = nan; }},
      {"'ref_ratio_stereo' is 1.5", [](TrackerOptions& o) { o.ref_ratio_stereo = 1.5; }},
      {"'reloc.bow_ratio' is 0", [](TrackerOptions& o) { o.reloc.bow_ratio = 0; }},
      {"'stereo_right_budget_max_factor' is 0.5",
       [](TrackerOptions& o) { o.stereo_right_budget_max_factor = 0.5; }},
      {"'two_view.sigma' is 0", [](TrackerOptions& o) { o.two_view.sigma = 0; }},
      {"'two_view.chi2_f' is nan", [&](TrackerOptions& o) { o.two_view.chi2_f = nan; }},
      {"'two_view.ransac_iterations' is 0", [](TrackerOptions& o) { o.two_view.ransac_iterations = 0; }},
      {"'two_view.homography_sample' is 3", [](TrackerOptions& o) { o.two_view.homography_sample = 3; }},
      {"'two_view.min_triangulated' is 5", [](TrackerOptions& o) { o.two_view.min_triangulated = 5; }},
      {"'two_view.min_parallax_deg' is -1", [](TrackerOptions& o) { o.two_view.min_parallax_deg = -1; }},
      {"'two_view.ratio_h' is 1.2", [](TrackerOptions& o) { o.two_view.ratio_h = 1.2; }},
      {"'reloc.pnp.probability' is 1", [](TrackerOptions& o) { o.reloc.pnp.probability = 1; }},
      {"'reloc.pnp.min_inliers' is 3", [](TrackerOptions& o) { o.reloc.pnp.min_inliers = 3; }},
      {"'reloc.pnp.chi2' is inf", [&](TrackerOptions& o) { o.reloc.pnp.chi2 = inf; }},
  };
  for (const Case& c : cases) {
    const std::string msg = refusal(c.change);
    EXPECT_NE(msg.find("tracker option " + c.field), std::string::npos) << c.field << ": got '" << msg << "'";
    EXPECT_NE(msg.find("it must be"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace dynaorb
