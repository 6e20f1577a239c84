#pragma once
// A stage's per-region decisions on the frame before, for decisions that
// carry over to the next frame (ours; the papers decide every frame
// afresh): which pixels it declared moving (with the age of that decision:
// 1 when the region's own points proved it moving in that frame, n when it
// was kept n - 1 frames after such a frame) and which static. Used by
// DM-SLAM's stage (keep_moving_frames, the "previous" few-points policy) and
// STDyn-SLAM's (keep_moving_frames).
#include <algorithm>
#include <opencv2/core.hpp>
#include <vector>

#include "dynaorb/dynamic/candidate_regions.h"

namespace dynaorb::dynamic {

// Per region r (index r, 0 unused) of the current frame: its pixels covered
// by regions remembered dynamic / static, and the least age among the
// dynamic ones it covers (255 when none).
struct RegionInheritance {
  std::vector<int> dynamic_pixels, static_pixels;
  std::vector<int> least_age;
  // The region as moving by inheritance: not older than max_age frames and
  // covered for at least min_overlap of its area by remembered moving
  // regions.
  bool keeps_moving(const CandidateRegions& regions, int r, int max_age, double min_overlap) const {
    return max_age > 0 && least_age[r] <= max_age &&
           dynamic_pixels[r] >= min_overlap * regions.pixels[r - 1];
  }
};

class RegionMemory {
 public:
  void reset();
  // True when it holds the decisions of frame previous_id, of this size.
  bool holds(long previous_id, const cv::Size& size) const;
  // Overlaps of `regions` with the remembered decisions (all zero / 255
  // when it holds none).
  RegionInheritance inherit(const CandidateRegions& regions, bool usable) const;
  // Remembers frame_id's decisions: region r dynamic with age region_age[r]
  // when non-zero, else static. Returns the dynamic pixels (CV_8UC1 255).
  cv::Mat remember(long frame_id, const CandidateRegions& regions, const std::vector<unsigned char>& region_age);

 private:
  long frame_ = -1;
  cv::Mat age_, static_;  // CV_8UC1: the age of dynamic pixels (0: not dynamic); 255 on static ones
};

// The age of a region decided in this frame: 1 when proven by its own
// points, else one more than the least age it inherited (saturated at 255).
inline unsigned char region_age(bool proven, int least_inherited_age) {
  return proven ? 1 : static_cast<unsigned char>(std::min(least_inherited_age + 1, 255));
}

}  // namespace dynaorb::dynamic
