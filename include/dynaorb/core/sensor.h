#pragma once
// Sensor kinds the system runs with.
#include <string>

namespace dynaorb {

enum class Sensor { kMono, kStereo, kRGBD };

// "mono" | "stereo" | "rgbd" (case-insensitive); throws std::invalid_argument naming the value.
Sensor parse_sensor(const std::string& name);
std::string to_string(Sensor sensor);

}  // namespace dynaorb
