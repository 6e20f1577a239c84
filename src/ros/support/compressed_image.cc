#include "support/compressed_image.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace dynaorb::node {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t");
  const size_t b = s.find_last_not_of(" \t");
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

DecodedImage decode_depth(const std::string& format, const std::vector<std::uint8_t>& data) {
  const std::string what = "compressedDepth image ('" + format + "')";
  if (lower(format).find("rvl") != std::string::npos)
    throw std::invalid_argument(what + ": only its png compression is read, not rvl");
  constexpr size_t kHeader = 12;  // int32 format, float32 depthQuantA, depthQuantB
  if (data.size() <= kHeader)
    throw std::invalid_argument(what + " of " + std::to_string(data.size()) + " bytes has no image after its header");
  const cv::Mat png(1, static_cast<int>(data.size() - kHeader), CV_8UC1, const_cast<std::uint8_t*>(data.data() + kHeader));
  const cv::Mat q = cv::imdecode(png, cv::IMREAD_UNCHANGED);
  if (q.empty() || q.type() != CV_16UC1) throw std::invalid_argument(what + " does not decode to a 16-bit PNG");
  const std::string encoding = trim(format.substr(0, format.find(';')));
  if (encoding == "16UC1" || encoding == "mono16") return {q, "16UC1"};
  if (encoding != "32FC1")
    throw std::invalid_argument(what + ": encoding '" + encoding + "' is neither 16UC1 nor 32FC1");
  float a = 0.f, b = 0.f;
  std::memcpy(&a, data.data() + 4, sizeof(float));
  std::memcpy(&b, data.data() + 8, sizeof(float));
  cv::Mat depth(q.size(), CV_32FC1);
  for (int r = 0; r < q.rows; ++r) {
    const auto* in = q.ptr<std::uint16_t>(r);
    auto* out = depth.ptr<float>(r);
    for (int c = 0; c < q.cols; ++c)
      out[c] = in[c] ? a / (static_cast<float>(in[c]) - b) : std::numeric_limits<float>::quiet_NaN();
  }
  return {depth, "32FC1"};
}

}  // namespace

DecodedImage decode_compressed(const std::string& format, const std::vector<std::uint8_t>& data) {
  if (lower(format).find("compresseddepth") != std::string::npos) return decode_depth(format, data);
  const std::string what = "compressed image ('" + format + "', " + std::to_string(data.size()) + " bytes)";
  if (data.empty()) throw std::invalid_argument(what + " is empty");
  const cv::Mat buffer(1, static_cast<int>(data.size()), CV_8UC1, const_cast<std::uint8_t*>(data.data()));
  cv::Mat image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  if (image.empty()) throw std::invalid_argument(what + " does not decode");
  switch (image.type()) {
    case CV_8UC1: return {image, "mono8"};
    case CV_16UC1: return {image, "mono16"};
    case CV_8UC3: return {image, "bgr8"};
    case CV_8UC4: return {image, "bgra8"};
    default: break;
  }
  throw std::invalid_argument(what + " decodes to an image of OpenCV type " + std::to_string(image.type()));
}

}  // namespace dynaorb::node
