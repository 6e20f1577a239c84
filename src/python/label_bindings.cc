#include "label_bindings.h"

#include "dynaorb/dynamic/label_propagation.h"
#include "numpy_mat.h"

#include <pybind11/stl.h>
#include <vector>

namespace dynaorb {

void bind_labels(py::module_& m) {
  using dynamic::FrameLabels;
  using dynamic::LabelPropagationOptions;
  using dynamic::LabelPropagator;
  using dynamic::LiveLabels;

  py::class_<LabelPropagator>(
      m, "LabelPropagator",
      "Labels of one image moved to another by optical flow (DIS, ultrafast, at flow_scale of the\n"
      "image; include/dynaorb/dynamic/label_propagation.h).")
      .def(py::init<double>(), py::arg("flow_scale") = 0.5)
      .def(
          "warp",
          [](LabelPropagator& p, const py::object& labels, const py::object& src, const py::object& dst) {
            const cv::Mat l = as_mat(labels, "labels"), a = as_mat(src, "source image"),
                          b = as_mat(dst, "destination image");
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = p.warp(l, a, b);
            }
            return to_numpy(out);
          },
          py::arg("labels"), py::arg("src_grey"), py::arg("dst_grey"),
          "labels (uint8 / uint16 HxW) of src_grey -> labels of dst_grey (the same type and size).");

  py::class_<LiveLabels>(
      m, "LiveLabels",
      "Per frame, the newest label image not later than the frame, moved onto it along the\n"
      "frames since (chained flows between consecutive frames). Stamps are any increasing\n"
      "time key (seconds, or frame indices with max_age in frames).")
      .def(py::init([](bool propagate, double flow_scale, double max_age, int frames_kept, std::vector<int> classes) {
             LabelPropagationOptions o;
             o.propagate = propagate;
             o.flow_scale = flow_scale;
             o.max_age_s = max_age;
             o.frames_kept = frames_kept;
             o.classes = std::move(classes);
             return LiveLabels(o);
           }),
           py::arg("propagate") = true, py::arg("flow_scale") = 0.5, py::arg("max_age") = 0.5,
           py::arg("frames_kept") = 64, py::arg("classes") = std::vector<int>(),
           "classes: the label ids carried (others become background); empty: all.")
      .def("set_classes", &LiveLabels::set_classes, py::arg("ids"),
           "Other ids to carry, from now on (the label images kept are reduced again).")
      .def(
          "add_labels",
          [](LiveLabels& l, double stamp, const py::object& labels) { l.add_labels(stamp, as_mat(labels, "labels")); },
          py::arg("stamp"), py::arg("labels"), "The network's labels of the image stamped `stamp`.")
      .def(
          "labels_for",
          [](LiveLabels& l, double stamp, const py::object& grey) {
            const cv::Mat g = as_mat(grey, "grey image");
            FrameLabels out;
            {
              py::gil_scoped_release release;
              out = l.labels_for(stamp, g);
            }
            return py::make_tuple(to_numpy(out.labels), dynamic::to_string(out.source), out.age_s, out.propagate_ms);
          },
          py::arg("stamp"), py::arg("grey"),
          "(labels or None, source: fresh | propagated | as_is | stale | none, age (-1: none),\n"
          "propagation ms) for the frame; frames in stamp order.")
      .def("clear", &LiveLabels::clear)
      .def("forget_after", &LiveLabels::forget_after, py::arg("stamp"),
           "Forgets the label images and frames stamped after `stamp` (time went back: a bag\n"
           "played again, a simulator reset; they belong to the time before).")
      .def(
          "count",
          [](const LiveLabels& l, const std::string& source) {
            for (auto s : {FrameLabels::Source::kNone, FrameLabels::Source::kFresh, FrameLabels::Source::kPropagated,
                           FrameLabels::Source::kAsIs, FrameLabels::Source::kStale})
              if (source == dynamic::to_string(s)) return l.count(s);
            throw InputError("LiveLabels.count: unknown source '" + source +
                             "' (fresh, propagated, as_is, stale, none)");
          },
          py::arg("source"));
}

}  // namespace dynaorb
