#pragma once
// The 8-bit grey image tracking works on, from what cameras and datasets give.
#include <opencv2/core.hpp>

namespace dynaorb {

// Grey image from an 8-bit grey / 3- or 4-channel image (rgb_order: RGB(A)
// channel order, else BGR(A)); false when the type is unusable. A grey input
// is shared, not copied.
bool to_grey(const cv::Mat& in, bool rgb_order, cv::Mat& grey);

}  // namespace dynaorb
