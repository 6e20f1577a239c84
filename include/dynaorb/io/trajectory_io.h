#pragma once
// Trajectory files: TUM (`stamp tx ty tz qx qy qz qw`) and KITTI (3x4 row-major).
#include <string>
#include <vector>

#include "dynaorb/core/pose.h"

namespace dynaorb::io {

void write_tum(const std::string& path, const Trajectory& trajectory);
void write_kitti(const std::string& path, const Trajectory& trajectory);
// Throws InputError naming the file and line for malformed rows or unordered stamps.
Trajectory read_tum(const std::string& path);
// Stamps come from `stamps` when given (KITTI times.txt), else the row index.
Trajectory read_kitti(const std::string& path, const std::vector<double>& stamps = {});

}  // namespace dynaorb::io
