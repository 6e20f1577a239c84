#pragma once
// Private to src/loop: a loop found by detection and closed by correction,
// and the helpers both use.
#include <memory>
#include <vector>

#include "dynaorb/loop/loop_closer.h"
#include "dynaorb/loop/sim3.h"

namespace dynaorb::loop {

struct LoopCloser::Loop {
  std::shared_ptr<map::KeyFrame> current, match;
  Sim3 S_cw;                                                // corrected pose of the current keyframe
  std::vector<std::shared_ptr<map::MapPoint>> matched;      // per keypoint of current: loop-side point
  std::vector<std::shared_ptr<map::MapPoint>> loop_points;  // points of match and its covisibles
  int matches = 0;
};

inline Sim3 pose_of(const map::KeyFrame& kf) { return Sim3::from_isometry(kf.T_cw()); }

}  // namespace dynaorb::loop
