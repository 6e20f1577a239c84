#pragma once
// Runs of one id along an image row of region ids (CV_32S), for the loops
// that do the same per run as per pixel: candidate_regions' component
// boxes, RegionMemory's remembered and inherited regions.
#include <opencv2/core/hal/intrin.hpp>

namespace dynaorb::dynamic::detail {

// The end of the run of ids equal to id[x] from x on (x < n), 4 at a time
// where it can.
inline int id_run_end(const int* id, int x, int n) {
  const int r = id[x];
  const cv::v_int32x4 vr = cv::v_setall_s32(r);
  ++x;
  for (; x + 4 <= n; x += 4)
    if (!cv::v_check_all(cv::v_load(id + x) == vr)) break;
  while (x < n && id[x] == r) ++x;
  return x;
}

}  // namespace dynaorb::dynamic::detail
