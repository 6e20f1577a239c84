#pragma once
// The option structs of the core's threads for dynaorb._core: TrackerOptions,
// LocalMapperOptions, LoopCloserOptions (fields as the C++ structs name them;
// defaults ORB-SLAM2's).
#include <pybind11/pybind11.h>

namespace dynaorb {

void bind_options(pybind11::module_& m);

}  // namespace dynaorb
