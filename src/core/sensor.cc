#include "dynaorb/core/sensor.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace dynaorb {

Sensor parse_sensor(const std::string& name) {
  std::string s = name;
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (s == "mono" || s == "monocular") return Sensor::kMono;
  if (s == "stereo") return Sensor::kStereo;
  if (s == "rgbd" || s == "rgb-d") return Sensor::kRGBD;
  throw std::invalid_argument("unknown sensor '" + name + "' (expected mono, stereo or rgbd)");
}

std::string to_string(Sensor sensor) {
  switch (sensor) {
    case Sensor::kMono: return "mono";
    case Sensor::kStereo: return "stereo";
    case Sensor::kRGBD: return "rgbd";
  }
  return "unknown";
}

}  // namespace dynaorb
