// When a lost map is given up (TrackerOptions reset_after_lost /
// reset_if_lost_below_keyframes, ORB-SLAM2; new_map_after_lost_s, ORB-SLAM3):
// the decision, through System, on RGB-D frames made here. A map starts on
// one texture; frames of another texture (nothing of the map in view, so
// tracking fails, and enough keypoints with depth to start a new map) or
// blank frames (no keypoints: no map could start from them) follow.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <vector>

#include "dynaorb/system.h"
#include "../test_util.h"

namespace dynaorb {
namespace {

cv::Mat texture(unsigned seed) {
  cv::Mat grey(480, 640, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(grey, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(grey, grey, cv::Size(5, 5), 1.2);
  cv::Mat rgb;
  cv::cvtColor(grey, rgb, cv::COLOR_GRAY2BGR);
  return rgb;
}

const cv::Mat& plane() {  // 2 m everywhere (DepthMapFactor 5000)
  static const cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(10000));
  return depth;
}

struct Frames {
  std::vector<TrackResult> results;
  int dropped_at = -1;  // index of the frame that gave the map up
};

// Frame 0 on the map's texture at stamp 0, then `frames` (texture or blank)
// every `step` seconds.
Frames run(const SystemOptions& so, const std::vector<cv::Mat>& frames, double step) {
  SystemOptions o = so;
  o.synchronous_mapping = true;
  System sys(test::rgbd_settings(), Sensor::kRGBD, o);
  Frames r;
  r.results.push_back(sys.track_rgbd(texture(1), plane(), 0.0));
  for (size_t i = 0; i < frames.size(); ++i) {
    r.results.push_back(sys.track_rgbd(frames[i], plane(), step * static_cast<double>(i + 1)));
    if (r.results.back().map_dropped && r.dropped_at < 0) r.dropped_at = static_cast<int>(i + 1);
  }
  return r;
}

std::vector<cv::Mat> repeat(const cv::Mat& image, int n) { return std::vector<cv::Mat>(n, image); }

const cv::Mat kBlank(480, 640, CV_8UC3, cv::Scalar::all(128));

TEST(MapDrop, SmallMapGoesAfterResetAfterLostFramesThatCouldStartOne) {
  SystemOptions so;
  so.tracker.new_map_after_lost_s = 0;  // the small-map rule alone
  ASSERT_EQ(so.tracker.reset_after_lost, 10);
  const Frames r = run(so, repeat(texture(2), 12), 0.1);
  ASSERT_EQ(r.results[0].method, "init");
  for (int i = 1; i <= 10; ++i) EXPECT_EQ(r.results[i].method, "lost") << i;
  EXPECT_EQ(r.dropped_at, 10);
  // The next frame starts map 1 on what it sees.
  EXPECT_EQ(r.results[11].method, "init");
  EXPECT_EQ(r.results[11].map, 1);
  EXPECT_EQ(r.results[10].map, 0);
}

TEST(MapDrop, FramesNoMapCouldStartFromAreNotCounted) {
  SystemOptions so;
  so.tracker.new_map_after_lost_s = 0;
  std::vector<cv::Mat> frames = repeat(kBlank, 20);  // 20 blank frames: lost, nothing counted
  for (const cv::Mat& m : repeat(texture(2), 10)) frames.push_back(m);
  const Frames r = run(so, frames, 0.1);
  for (int i = 1; i <= 20; ++i) EXPECT_EQ(r.results[i].method, "lost") << i;
  EXPECT_EQ(r.dropped_at, 30);  // the tenth textured one
}

TEST(MapDrop, LargerMapsGoAfterNewMapAfterLostSecondsOfStamps) {
  SystemOptions so;
  so.tracker.reset_if_lost_below_keyframes = 0;  // no map counts as small
  so.tracker.new_map_after_lost_s = 0.5;
  // Lost from stamp 0.125 (frame 1, blank: the clock starts all the same);
  // frame 5 (stamp 0.625) is the first 0.5 s later that could start a map.
  std::vector<cv::Mat> frames = {kBlank};
  for (const cv::Mat& m : repeat(texture(2), 7)) frames.push_back(m);
  const Frames r = run(so, frames, 0.125);
  EXPECT_EQ(r.dropped_at, 5);
  EXPECT_EQ(r.results[6].map, 1);
  // 0: never.
  so.tracker.new_map_after_lost_s = 0;
  const Frames never = run(so, repeat(texture(2), 30), 0.125);
  EXPECT_EQ(never.dropped_at, -1);
  EXPECT_EQ(never.results.back().method, "lost");
  EXPECT_EQ(never.results.back().map, 0);
}

}  // namespace
}  // namespace dynaorb
