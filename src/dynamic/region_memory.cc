// A stage's per-region decisions on the frame before (region_memory.h).
#include "dynaorb/dynamic/region_memory.h"

#include <algorithm>

#include "id_runs.h"

namespace dynaorb::dynamic {

void RegionMemory::reset() {
  frame_ = -1;
  age_.release();
  static_.release();
}

bool RegionMemory::holds(long previous_id, const cv::Size& size) const {
  return frame_ >= 0 && previous_id == frame_ && age_.size() == size;
}

RegionInheritance RegionMemory::inherit(const CandidateRegions& regions, bool usable) const {
  RegionInheritance in;
  in.dynamic_pixels.assign(regions.count + 1, 0);
  in.static_pixels.assign(regions.count + 1, 0);
  in.least_age.assign(regions.count + 1, 255);
  if (!usable || age_.empty() || age_.size() != regions.ids.size()) return in;
  const int n = regions.ids.cols;
  for (int y = 0; y < regions.ids.rows; ++y) {
    const int* id = regions.ids.ptr<int>(y);
    const unsigned char* pa = age_.ptr<unsigned char>(y);
    const unsigned char* ps = static_.ptr<unsigned char>(y);
    // Run by run of one region id: the region's counts change once per run.
    for (int x = 0; x < n;) {
      const int r = id[x];
      const int end = detail::id_run_end(id, x, n);
      if (r > 0) {
        int dynamic = 0, statics = 0, least = in.least_age[r];
        for (int i = x; i < end; ++i) {
          dynamic += pa[i] != 0;
          statics += ps[i] != 0;
          if (pa[i] != 0 && pa[i] < least) least = pa[i];
        }
        in.dynamic_pixels[r] += dynamic;
        in.static_pixels[r] += statics;
        in.least_age[r] = least;
      }
      x = end;
    }
  }
  return in;
}

cv::Mat RegionMemory::remember(long frame_id, const CandidateRegions& regions,
                               const std::vector<unsigned char>& region_age) {
  cv::Mat age(regions.ids.size(), CV_8UC1, cv::Scalar(0));
  cv::Mat stat(regions.ids.size(), CV_8UC1, cv::Scalar(0));
  const int n = regions.ids.cols;
  for (int y = 0; y < regions.ids.rows; ++y) {
    const int* id = regions.ids.ptr<int>(y);
    unsigned char* da = age.ptr<unsigned char>(y);
    unsigned char* ds = stat.ptr<unsigned char>(y);
    for (int x = 0; x < n;) {
      const int r = id[x];
      const int end = detail::id_run_end(id, x, n);
      if (r > 0) {
        if (region_age[r] != 0)
          std::fill(da + x, da + end, region_age[r]);
        else
          std::fill(ds + x, ds + end, static_cast<unsigned char>(255));
      }
      x = end;
    }
  }
  frame_ = frame_id;
  age_ = age;
  static_ = stat;
  return age != 0;
}

}  // namespace dynaorb::dynamic
