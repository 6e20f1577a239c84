#include "dynaorb/core/grey_image.h"

#include <opencv2/imgproc.hpp>

namespace dynaorb {

bool to_grey(const cv::Mat& in, bool rgb_order, cv::Mat& grey) {
  if (in.depth() != CV_8U) return false;
  grey.release();  // it may share an earlier caller's image: convert into a new one
  switch (in.channels()) {
    case 1: grey = in; return true;
    case 3: cv::cvtColor(in, grey, rgb_order ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY); return true;
    case 4: cv::cvtColor(in, grey, rgb_order ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY); return true;
    default: return false;
  }
}

}  // namespace dynaorb
