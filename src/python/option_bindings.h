#pragma once
// The option structs of the core's threads for dynaorb._core: TrackerOptions
// (with RelocalizationOptions, PnpRansacOptions, TwoViewOptions),
// LocalMapperOptions, LoopCloserOptions (with Sim3RansacOptions); fields as
// the C++ structs' option_fields lists name them, defaults ORB-SLAM2's.
#include <pybind11/pybind11.h>

namespace dynaorb {

void bind_options(pybind11::module_& m);

}  // namespace dynaorb
