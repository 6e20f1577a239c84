// A stage's per-region decisions on the frame before (region_memory.h).
#include "dynaorb/dynamic/region_memory.h"

#include <algorithm>

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
  for (int y = 0; y < regions.ids.rows; ++y) {
    const int* id = regions.ids.ptr<int>(y);
    const unsigned char* pa = age_.ptr<unsigned char>(y);
    const unsigned char* ps = static_.ptr<unsigned char>(y);
    for (int x = 0; x < regions.ids.cols; ++x)
      if (id[x] > 0) {
        if (pa[x] != 0) {
          ++in.dynamic_pixels[id[x]];
          in.least_age[id[x]] = std::min<int>(in.least_age[id[x]], pa[x]);
        }
        in.static_pixels[id[x]] += ps[x] != 0;
      }
  }
  return in;
}

cv::Mat RegionMemory::remember(long frame_id, const CandidateRegions& regions,
                               const std::vector<unsigned char>& region_age) {
  cv::Mat age(regions.ids.size(), CV_8UC1, cv::Scalar(0));
  cv::Mat stat(regions.ids.size(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < regions.ids.rows; ++y) {
    const int* id = regions.ids.ptr<int>(y);
    unsigned char* da = age.ptr<unsigned char>(y);
    unsigned char* ds = stat.ptr<unsigned char>(y);
    for (int x = 0; x < regions.ids.cols; ++x)
      if (id[x] > 0) {
        if (region_age[id[x]] != 0)
          da[x] = region_age[id[x]];
        else
          ds[x] = 255;
      }
  }
  frame_ = frame_id;
  age_ = age;
  static_ = stat;
  return age != 0;
}

}  // namespace dynaorb::dynamic
