#include <gtest/gtest.h>

#include "dynaorb/io/errors.h"
#include "dynaorb/system.h"
#include "../test_util.h"

namespace dynaorb {
namespace {

using test::rgbd_settings;

TEST(System, RejectsMissingSensorKeys) {
  Settings s = rgbd_settings();
  s.camera.depth_map_factor.reset();
  EXPECT_THROW(System(s, Sensor::kRGBD), InputError);
  EXPECT_NO_THROW(System(s, Sensor::kStereo));
}

TEST(System, CountsBadFramesInsteadOfCrashing) {
  System sys(rgbd_settings(), Sensor::kRGBD);
  cv::Mat rgb(480, 640, CV_8UC3, cv::Scalar(10, 20, 30));
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(5000));
  TrackResult ok = sys.track_rgbd(rgb, depth, 1.0);
  EXPECT_EQ(ok.rejected, RejectReason::kNone);
  EXPECT_EQ(ok.invalid_depth_pixels, 0);
  EXPECT_EQ(sys.track_rgbd(rgb, depth, 1.0).rejected, RejectReason::kStampNotIncreasing);
  EXPECT_EQ(sys.track_rgbd(cv::Mat(), depth, 2.0).rejected, RejectReason::kEmptyImage);
  EXPECT_EQ(sys.track_rgbd(cv::Mat(240, 320, CV_8UC3), cv::Mat(240, 320, CV_16UC1), 3.0).rejected,
            RejectReason::kWrongSize);
  EXPECT_EQ(sys.track_rgbd(rgb, cv::Mat(480, 640, CV_8UC1), 4.0).rejected, RejectReason::kWrongType);
  const SystemCounters& c = sys.counters();
  EXPECT_EQ(c.frames, 5);
  EXPECT_EQ(c.rejected, 4);
  EXPECT_EQ(c.rejected_by_reason.at("wrong_size"), 1);
  EXPECT_THROW(sys.track_mono(rgb, 9.0), InputError);
}

TEST(System, InvalidDepthIsCountedAndMasksChecked) {
  System sys(rgbd_settings(), Sensor::kRGBD);
  cv::Mat rgb(480, 640, CV_8UC3, cv::Scalar::all(100));
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.5f));
  depth(cv::Rect(0, 0, 10, 10)).setTo(std::numeric_limits<float>::quiet_NaN());
  depth(cv::Rect(10, 0, 10, 10)).setTo(0.0f);
  depth(cv::Rect(20, 0, 10, 10)).setTo(-1.0f);
  Settings s = rgbd_settings();
  s.camera.depth_map_factor = 1.0;  // 32FC1 in metres, as on ROS topics
  System metres(s, Sensor::kRGBD);
  TrackResult r = metres.track_rgbd(rgb, depth, 1.0, cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)));
  EXPECT_EQ(r.invalid_depth_pixels, 300);
  EXPECT_TRUE(r.mask_used);
  r = metres.track_rgbd(rgb, depth, 2.0, cv::Mat(100, 100, CV_8UC1));
  EXPECT_FALSE(r.mask_used);
  EXPECT_EQ(metres.counters().masks_dropped, 1);
  // 16-bit depth: zeros are the invalid pixels.
  cv::Mat raw(480, 640, CV_16UC1, cv::Scalar(5000));
  raw(cv::Rect(0, 0, 10, 10)).setTo(0);
  raw(cv::Rect(30, 30, 5, 4)).setTo(0);
  EXPECT_EQ(sys.track_rgbd(rgb, raw, 1.0).invalid_depth_pixels, 120);
}

}  // namespace
}  // namespace dynaorb
