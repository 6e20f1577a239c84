#pragma once
// The first ring of the tracker's local map (ORB-SLAM's UpdateLocalKeyFrames,
// K1 in ORB-SLAM2 Sec. V-D): the keyframes that observe the frame's tracked
// points, with how many of them each observes.
#include <utility>
#include <vector>

#include "dynaorb/map/frame.h"

namespace dynaorb::tracking {

// The keyframes observing f's matched points that are not outliers (erased
// points and keyframes skipped), each with the number of those points it
// observes, by keyframe id. When more than max_keyframes (> 0) keyframes
// observe them, only the max_keyframes observing the most are returned (ties:
// the lower id), still by id; 0: all (ORB-SLAM2). The caller holds the map's
// mutex.
std::vector<std::pair<map::KeyFrame*, int>> sharing_keyframes(const map::Frame& f, int max_keyframes);

}  // namespace dynaorb::tracking
