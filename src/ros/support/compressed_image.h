#pragma once
// image_transport's compressed formats, decoded without ROS (the node
// subscribes to sensor_msgs/CompressedImage itself with ~image_transport
// compressed: Debian ships no compressed transport plugin).
//   compressed:      format "<encoding>; jpeg|png compressed <encoding>" (or
//                    just "jpeg" / "png"); colour decodes to bgr8 / bgra8,
//                    grey to mono8 / mono16.
//   compressedDepth: format "16UC1|32FC1; compressedDepth [png]": a 12-byte
//                    header (int32 compression format, float32 depthQuantA,
//                    depthQuantB) and a 16-bit PNG; 16UC1 as it was, 32FC1
//                    from the quantised inverse depth q: A / (q - B), NaN
//                    where q is 0. Its rvl compression is not read.
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace dynaorb::node {

struct DecodedImage {
  cv::Mat image;         // CV_8UC1/3/4, CV_16UC1 or CV_32FC1
  std::string encoding;  // mono8, bgr8, bgra8, mono16, 16UC1, 32FC1
};

// std::invalid_argument naming the format when the data does not decode.
DecodedImage decode_compressed(const std::string& format, const std::vector<std::uint8_t>& data);

}  // namespace dynaorb::node
