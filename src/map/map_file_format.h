#pragma once
// Private to src/map: the low-level map file format (header with magic,
// version, payload length and FNV-1a checksum; little-endian values) and the
// calibration block that map_io.cc writes before the map itself.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "dynaorb/io/errors.h"
#include "dynaorb/map/calibration.h"
#include "dynaorb/map/map_io.h"

namespace dynaorb::map::file {

constexpr std::size_t kHeaderBytes = 8 + 4 + 8 + 8;

inline std::uint64_t fnv1a(const char* data, std::size_t n) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(data[i]);
    h *= 1099511628211ull;
  }
  return h;
}

class Writer {
 public:
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    buf_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void put_bytes(const void* p, std::size_t n) { buf_.append(static_cast<const char*>(p), n); }
  void put_pose(const Eigen::Isometry3d& T) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) put<double>(T.matrix()(r, c));
  }
  void put_keys(const std::vector<cv::KeyPoint>& keys) {
    put<std::uint64_t>(keys.size());
    for (const cv::KeyPoint& k : keys) {
      put<float>(k.pt.x);
      put<float>(k.pt.y);
      put<float>(k.size);
      put<float>(k.angle);
      put<float>(k.response);
      put<std::int32_t>(k.octave);
      put<std::int32_t>(k.class_id);
    }
  }
  std::string& buffer() { return buf_; }

 private:
  std::string buf_;
};

// Bounds-checked reads of the payload; every problem is an InputError naming the file.
class Reader {
 public:
  Reader(const std::string& path, const char* data, std::size_t n) : path_(path), p_(data), end_(data + n) {}
  [[noreturn]] void fail(const std::string& what) const { throw InputError(path_, 0, what); }
  template <typename T>
  T get(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, p_, sizeof(T));
    p_ += sizeof(T);
    return v;
  }
  void get_bytes(void* out, std::size_t n, const char* what) {
    need(n, what);
    std::memcpy(out, p_, n);
    p_ += n;
  }
  // A count of items of at least item_bytes each, that the rest of the file can hold.
  std::size_t count(std::size_t item_bytes, const char* what) {
    const std::uint64_t n = get<std::uint64_t>(what);
    if (item_bytes > 0 && n > remaining() / item_bytes)
      fail(std::string("corrupt map file: ") + what + " count " + std::to_string(n) + " exceeds the file");
    return static_cast<std::size_t>(n);
  }
  double finite(const char* what) {
    const double v = get<double>(what);
    if (!std::isfinite(v)) fail(std::string("corrupt map file: ") + what + " is not finite");
    return v;
  }
  Eigen::Isometry3d pose(const char* what) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) T.matrix()(r, c) = finite(what);
    return T;
  }
  std::vector<cv::KeyPoint> keys(int n_levels, const char* what) {
    std::vector<cv::KeyPoint> out(count(28, what));
    for (cv::KeyPoint& k : out) {
      k.pt.x = get<float>(what);
      k.pt.y = get<float>(what);
      k.size = get<float>(what);
      k.angle = get<float>(what);
      k.response = get<float>(what);
      k.octave = get<std::int32_t>(what);
      k.class_id = get<std::int32_t>(what);
      if (k.octave < 0 || k.octave >= n_levels)
        fail(std::string("corrupt map file: ") + what + " on pyramid level " + std::to_string(k.octave));
      if (!std::isfinite(k.pt.x) || !std::isfinite(k.pt.y))
        fail(std::string("corrupt map file: ") + what + " with a non-finite position");
    }
    return out;
  }
  std::size_t remaining() const { return static_cast<std::size_t>(end_ - p_); }

 private:
  void need(std::size_t n, const char* what) const {
    if (remaining() < n) fail(std::string("truncated map file: it ends inside ") + what);
  }
  const std::string& path_;
  const char* p_;
  const char* end_;
};

inline void put_info(Writer& w, const Calibration& c, Sensor sensor) {
  w.put<std::uint32_t>(static_cast<std::uint32_t>(sensor));
  w.put<std::int32_t>(c.width);
  w.put<std::int32_t>(c.height);
  for (double v : {c.fx, c.fy, c.cx, c.cy, c.bf, c.th_depth}) w.put<double>(v);
  cv::Mat d;
  if (!c.dist.empty()) c.dist.reshape(1, 1).convertTo(d, CV_64F);
  w.put<std::uint64_t>(d.total());
  for (std::size_t i = 0; i < d.total(); ++i) w.put<double>(d.at<double>(0, static_cast<int>(i)));
  w.put<std::int32_t>(c.scale.n_levels);
  w.put<double>(c.scale.scale_factor);
}

inline std::string sensor_name(std::uint32_t s) {
  switch (s) {
    case 0: return to_string(Sensor::kMono);
    case 1: return to_string(Sensor::kStereo);
    case 2: return to_string(Sensor::kRGBD);
  }
  return "unknown";
}

inline MapFileInfo get_info(Reader& r) {
  MapFileInfo info;
  const std::uint32_t s = r.get<std::uint32_t>("the sensor");
  if (s > 2) r.fail("corrupt map file: unknown sensor " + std::to_string(s));
  info.sensor = static_cast<Sensor>(s);
  info.width = r.get<std::int32_t>("the image size");
  info.height = r.get<std::int32_t>("the image size");
  info.fx = r.finite("the calibration");
  info.fy = r.finite("the calibration");
  info.cx = r.finite("the calibration");
  info.cy = r.finite("the calibration");
  info.bf = r.finite("the calibration");
  info.th_depth = r.finite("the calibration");
  info.dist.resize(r.count(8, "the distortion"));
  for (double& v : info.dist) v = r.finite("the distortion");
  info.n_levels = r.get<std::int32_t>("the ORB pyramid");
  info.scale_factor = r.finite("the ORB pyramid");
  if (info.width <= 0 || info.height <= 0 || info.n_levels <= 0 || info.n_levels > 64 || info.fx <= 0 ||
      info.fy <= 0)
    r.fail("corrupt map file: impossible calibration summary");
  return info;
}

inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open the map file (missing or unreadable)");
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, "cannot read the map file");
  return data;
}

// Checks the header; returns the payload's reader.
inline Reader open_payload(const std::string& path, const std::string& data, MapFileInfo& info) {
  if (data.size() < 8 || std::memcmp(data.data(), kMapMagic, 8) != 0)
    throw InputError(path, 0, "not a dynaorb map file (no DYNAOMAP magic at its start)");
  if (data.size() < kHeaderBytes)
    throw InputError(path, 0, "truncated map file: " + std::to_string(data.size()) + " bytes, shorter than its header");
  std::uint32_t version;
  std::uint64_t payload, checksum;
  std::memcpy(&version, data.data() + 8, 4);
  std::memcpy(&payload, data.data() + 12, 8);
  std::memcpy(&checksum, data.data() + 20, 8);
  if (version < kMapFormatOldestVersion || version > kMapFormatVersion)
    throw InputError(path, 0, "map file format version " + std::to_string(version) + ": this build reads versions " +
                                  std::to_string(kMapFormatOldestVersion) + " to " + std::to_string(kMapFormatVersion));
  const std::uint64_t have = data.size() - kHeaderBytes;
  if (have < payload)
    throw InputError(path, 0, "truncated map file: " + std::to_string(data.size()) + " bytes, the header says " +
                                  std::to_string(payload + kHeaderBytes));
  if (have > payload)
    throw InputError(path, 0, "corrupt map file: " + std::to_string(have - payload) +
                                  " bytes after the end its header gives");
  if (fnv1a(data.data() + kHeaderBytes, payload) != checksum)
    throw InputError(path, 0, "corrupt map file: checksum mismatch");
  info.version = version;
  info.file_bytes = data.size();
  return Reader(path, data.data() + kHeaderBytes, payload);
}

inline bool close(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}); }

inline std::string num(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

}  // namespace dynaorb::map::file
