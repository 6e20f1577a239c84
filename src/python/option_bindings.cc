// dynaorb._core's option classes (option_bindings.h). Each is checked where
// a System is made (its validate(): an InputError naming the option). Their
// attributes are the C++ structs' option_fields lists
// (dynaorb/core/option_fields.h), the names the ROS node's ~tracker/NAME,
// ~mapping/NAME and ~loop/NAME parameters use.
#include "option_bindings.h"

#include "dynaorb/core/option_fields.h"
#include "dynaorb/loop/loop_closer.h"
#include "dynaorb/mapping/local_mapper.h"
#include "dynaorb/place/pnp_ransac.h"
#include "dynaorb/tracking/tracker.h"

namespace py = pybind11;

namespace dynaorb {

namespace {

// A class with an attribute per field of Options' list.
template <class Options>
py::class_<Options> bind_option_class(py::module_& m, const char* name, const char* doc) {
  py::class_<Options> cls(m, name, doc);
  cls.def(py::init<>());
  for_each_option_field<Options>([&](const char* field, auto member) { cls.def_readwrite(field, member); });
  return cls;
}

}  // namespace

void bind_options(py::module_& m) {
  // Nested ones first: their parents' attributes return them.
  bind_option_class<place::PnpRansacOptions>(m, "PnpRansacOptions",
                                             "Relocalisation's PnP RANSAC (dynaorb/place/pnp_ransac.h).");
  bind_option_class<tracking::RelocalizationOptions>(
      m, "RelocalizationOptions", "Relocalisation's options (dynaorb/tracking/tracker.h; ORB-SLAM2's values).");
  bind_option_class<tracking::TwoViewOptions>(
      m, "TwoViewOptions",
      "The monocular initialisation's two-view reconstruction (dynaorb/tracking/two_view_initializer.h).");
  bind_option_class<tracking::TrackerOptions>(m, "TrackerOptions",
                                              "The tracking thread's options (dynaorb/tracking/tracker.h; defaults\n"
                                              "are ORB-SLAM2's). max_frames -1 (the default) takes the settings'\n"
                                              "Camera.fps; a value set here wins.")
      .def("validate", &tracking::TrackerOptions::validate, "InputError naming a value out of range.");

  bind_option_class<mapping::LocalMapperOptions>(
      m, "LocalMapperOptions",
      "Local mapping's options (dynaorb/mapping/local_mapper.h; defaults are\n"
      "ORB-SLAM2's). thread_nice is replaced by System's background_nice when given.")
      .def("validate", &mapping::LocalMapperOptions::validate, "InputError naming a value out of range.");

  bind_option_class<loop::Sim3RansacOptions>(m, "Sim3RansacOptions",
                                             "The loop candidates' similarity RANSAC (dynaorb/loop/sim3_ransac.h); its\n"
                                             "scale is fixed by the sensor (stereo, RGB-D) or free (mono).");
  bind_option_class<loop::LoopCloserOptions>(
      m, "LoopCloserOptions",
      "Loop closing's options (dynaorb/loop/loop_closer.h; defaults are ORB-SLAM2's).\n"
      "global_ba and thread_nice are replaced by System's global_ba and background_nice\n"
      "when those are given.")
      .def("validate", &loop::LoopCloserOptions::validate, "InputError naming a value out of range.");
}

}  // namespace dynaorb
