// RegionMemory: what it remembers of one frame's regions and what the next
// frame's regions inherit, against the rule computed pixel by pixel.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "dynaorb/dynamic/candidate_regions.h"
#include "dynaorb/dynamic/region_memory.h"

namespace dynaorb::dynamic {
namespace {

cv::Mat random_blobs(cv::RNG& rng, cv::Size size) {
  cv::Mat m = cv::Mat::zeros(size, CV_8UC1);
  for (int k = rng.uniform(0, 7); k > 0; --k) {
    const cv::Point c(rng.uniform(0, size.width), rng.uniform(0, size.height));
    if (rng.uniform(0, 2)) cv::circle(m, c, rng.uniform(1, 40), 255, -1);
    else cv::rectangle(m, cv::Rect(c, cv::Size(rng.uniform(1, 60), rng.uniform(1, 30))), 255, -1);
  }
  return m;
}

TEST(RegionMemory, RemembersAndInheritsPixelByPixel) {
  cv::RNG rng(11);
  for (int scene = 0; scene < 40; ++scene) {
    const cv::Size size(rng.uniform(1, 300), rng.uniform(1, 120));
    const CandidateRegions first = candidate_regions(random_blobs(rng, size), cv::Mat(), false);
    std::vector<unsigned char> ages(first.count + 1, 0);
    for (int r = 1; r <= first.count; ++r)  // a third static, the rest dynamic of any age
      ages[r] = rng.uniform(0, 3) ? static_cast<unsigned char>(rng.uniform(1, 256)) : 0;
    RegionMemory memory;
    const cv::Mat dynamic = memory.remember(5, first, ages);
    ASSERT_TRUE(memory.holds(5, size));
    // Remembered: region r's pixels dynamic (with its age) when ages[r] != 0, else static.
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        const int r = first.ids.at<int>(y, x);
        ASSERT_EQ(dynamic.at<unsigned char>(y, x), r > 0 && ages[r] != 0 ? 255 : 0) << "scene " << scene;
      }

    const CandidateRegions next = candidate_regions(random_blobs(rng, size), cv::Mat(), false);
    const RegionInheritance in = memory.inherit(next, true);
    std::vector<int> dyn(next.count + 1, 0), stat(next.count + 1, 0), least(next.count + 1, 255);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) {
        const int r = next.ids.at<int>(y, x), before = first.ids.at<int>(y, x);
        if (r == 0 || before == 0) continue;
        if (ages[before] != 0) {
          ++dyn[r];
          least[r] = std::min<int>(least[r], ages[before]);
        } else {
          ++stat[r];
        }
      }
    EXPECT_EQ(in.dynamic_pixels, dyn) << "scene " << scene;
    EXPECT_EQ(in.static_pixels, stat) << "scene " << scene;
    EXPECT_EQ(in.least_age, least) << "scene " << scene;

    const RegionInheritance unusable = memory.inherit(next, false);
    EXPECT_EQ(unusable.dynamic_pixels, std::vector<int>(next.count + 1, 0));
    EXPECT_EQ(unusable.least_age, std::vector<int>(next.count + 1, 255));
  }
}

}  // namespace
}  // namespace dynaorb::dynamic
