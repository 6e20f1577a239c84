#pragma once
// dynamic::LabelPropagator and dynamic::LiveLabels for dynaorb._core: old
// network labels moved onto later frames by optical flow (the Python
// runner's asynchronous segmentation and the ROS node use the same code).
#include <pybind11/pybind11.h>

namespace dynaorb {

void bind_labels(pybind11::module_& m);

}  // namespace dynaorb
