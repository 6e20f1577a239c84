// dynaorb._core: the pybind11 module over the core's public API (System,
// Settings, DataProvider, Vocabulary, ORB extraction, trajectory files).
// Images cross as numpy arrays: uint8 HxW / HxWx3, uint16 or float32 HxW
// depth; ORB descriptors as (N, 32) uint8.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstring>
#include <opencv2/imgproc.hpp>

#include "dynaorb/core/thread_priority.h"
#include "dynaorb/dynamic/dynamic_filter.h"
#include "dynaorb/features/orb_extractor.h"
#include "dynaorb/io/dataset.h"
#include "dynaorb/io/errors.h"
#include "dynaorb/io/settings.h"
#include "dynaorb/io/trajectory_io.h"
#include "dynaorb/system.h"
#include "dynaorb/vocab/vocabulary.h"
#include "label_bindings.h"
#include "numpy_mat.h"
#include "option_bindings.h"

namespace py = pybind11;
using namespace dynaorb;

namespace {

py::tuple trajectory_to_numpy(const Trajectory& t) {
  py::array_t<double> stamps(static_cast<py::ssize_t>(t.size()));
  py::array_t<double> poses({static_cast<py::ssize_t>(t.size()), py::ssize_t(4), py::ssize_t(4)});
  auto s = stamps.mutable_unchecked<1>();
  auto p = poses.mutable_unchecked<3>();
  for (size_t i = 0; i < t.size(); ++i) {
    s(i) = t[i].stamp;
    const Eigen::Matrix4d m = t[i].pose.matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) p(i, r, c) = m(r, c);
  }
  return py::make_tuple(stamps, poses);
}

Trajectory trajectory_from_numpy(py::array_t<double, py::array::c_style | py::array::forcecast> stamps,
                                 py::array_t<double, py::array::c_style | py::array::forcecast> poses) {
  if (stamps.ndim() != 1 || poses.ndim() != 3 || poses.shape(0) != stamps.shape(0) || poses.shape(1) != 4 ||
      poses.shape(2) != 4)
    throw InputError("trajectory: expected stamps (N,) and poses (N,4,4)");
  Trajectory t(stamps.shape(0));
  auto s = stamps.unchecked<1>();
  auto p = poses.unchecked<3>();
  for (size_t i = 0; i < t.size(); ++i) {
    t[i].stamp = s(i);
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = p(i, r, c);
    t[i].pose.matrix() = m;
  }
  return t;
}

py::object optional_number(const std::optional<double>& v) { return v ? py::cast(*v) : py::none(); }

using VocabularyPtr = std::shared_ptr<vocab::Vocabulary>;

// str or os.PathLike -> path string.
std::string path_of(const py::object& obj) {
  return py::module_::import("os").attr("fspath")(obj).cast<std::string>();
}

// An (N, 32) uint8 array of ORB descriptors, copied into a cv::Mat.
cv::Mat descriptors_from(const py::handle& obj, const std::string& what) {
  auto arr = py::array::ensure(obj, py::array::c_style);
  if (!arr || !arr.dtype().is(py::dtype::of<uint8_t>()) || arr.ndim() != 2 ||
      (arr.shape(0) > 0 && arr.shape(1) != vocab::Vocabulary::kDescriptorBytes))
    throw InputError(what + ": expected an (N, 32) uint8 array of ORB descriptors");
  if (arr.shape(0) == 0) return cv::Mat();
  return cv::Mat(static_cast<int>(arr.shape(0)), vocab::Vocabulary::kDescriptorBytes, CV_8UC1,
                 const_cast<void*>(arr.data()))
      .clone();
}

vocab::BowVector bow_from(const py::dict& d) {
  vocab::BowVector b;
  for (const auto& [k, v] : d) b[k.cast<vocab::WordId>()] = v.cast<double>();
  return b;
}

// System's vocabulary argument: None, a Vocabulary, or a path (ORBvoc.txt or binary).
std::shared_ptr<const vocab::Vocabulary> vocabulary_from(const py::object& obj) {
  if (obj.is_none()) return nullptr;
  if (py::isinstance<vocab::Vocabulary>(obj)) return obj.cast<VocabularyPtr>();
  const std::string path = path_of(obj);
  py::gil_scoped_release release;
  return std::make_shared<const vocab::Vocabulary>(vocab::Vocabulary::load_any(path));
}

// System's dynamic argument: None (off), a DynamicFilterOptions, or a preset path.
dynamic::DynamicFilterOptions dynamic_from(const py::object& obj) {
  if (obj.is_none()) return {};
  if (py::isinstance<dynamic::DynamicFilterOptions>(obj)) return obj.cast<dynamic::DynamicFilterOptions>();
  return dynamic::DynamicFilterOptions::load(path_of(obj));
}

py::object pose_or_none(const std::optional<Pose>& p) {
  if (!p) return py::none();
  return py::cast(Eigen::Matrix4d(p->matrix()));
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "dynaorb core: visual SLAM with a dynamic-object front end";
  static py::exception<InputError> input_error(m, "InputError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(input_error.ptr(), e.what());
    }
  });

  m.def("parse_sensor", [](const std::string& s) { return to_string(parse_sensor(s)); },
        "Normalises a sensor name to mono|stereo|rgbd (ValueError otherwise).");

  py::class_<Settings>(m, "Settings")
      .def_static("load", &Settings::load, py::arg("path"), "Loads an ORB-SLAM2 settings YAML.")
      .def("save", &Settings::save, py::arg("path"))
      .def("validate", [](const Settings& s, const std::string& sensor) { s.validate(parse_sensor(sensor)); })
      .def("summary", &Settings::summary)
      .def_readwrite("source", &Settings::source)
      .def_property_readonly("fx", [](const Settings& s) { return s.camera.fx; })
      .def_property_readonly("fy", [](const Settings& s) { return s.camera.fy; })
      .def_property_readonly("cx", [](const Settings& s) { return s.camera.cx; })
      .def_property_readonly("cy", [](const Settings& s) { return s.camera.cy; })
      .def_property_readonly("dist", [](const Settings& s) { return to_numpy(s.camera.dist); })
      .def_property_readonly("width", [](const Settings& s) { return s.camera.width; })
      .def_property_readonly("height", [](const Settings& s) { return s.camera.height; })
      .def_property_readonly("fps", [](const Settings& s) { return s.camera.fps; })
      .def_property_readonly("rgb", [](const Settings& s) { return s.camera.rgb; })
      .def_property_readonly("bf", [](const Settings& s) { return optional_number(s.camera.bf); })
      .def_property_readonly("th_depth", [](const Settings& s) { return optional_number(s.camera.th_depth); })
      .def_property_readonly("depth_map_factor",
                             [](const Settings& s) { return optional_number(s.camera.depth_map_factor); })
      .def_property_readonly("n_features", [](const Settings& s) { return s.extractor.n_features; })
      .def_property_readonly("rectified_stereo", [](const Settings& s) { return s.rectification.enabled(); })
      .def_property_readonly("rectification_R_left",
                             [](const Settings& s) { return to_numpy(s.rectification.R_l); });

  py::class_<Frame>(m, "Frame")
      .def_readonly("index", &Frame::index)
      .def_readonly("stamp", &Frame::stamp)
      .def_readonly("image_path", &Frame::image_path)
      .def_property_readonly("image", [](const Frame& f) { return to_numpy(f.image); })
      .def_property_readonly("right", [](const Frame& f) { return to_numpy(f.right); })
      .def_property_readonly("depth", [](const Frame& f) { return to_numpy(f.depth); });

  py::class_<DataProvider>(m, "DataProvider")
      .def_property_readonly("kind", &DataProvider::kind)
      .def_property_readonly("root", &DataProvider::root)
      .def_property_readonly("sensor", [](const DataProvider& d) { return to_string(d.sensor()); })
      .def("__len__", &DataProvider::size)
      .def("stamp", &DataProvider::stamp)
      .def("load", &DataProvider::load, py::arg("index"), py::call_guard<py::gil_scoped_release>())
      .def("default_settings", &DataProvider::default_settings)
      .def("ground_truth", [](const DataProvider& d) { return trajectory_to_numpy(d.ground_truth()); },
           "(stamps (N,), poses (N,4,4)) of the left/colour camera in the world; empty when none.")
      .def_property_readonly("warnings", &DataProvider::warnings);

  m.def("open_dataset",
        [](const std::string& kind, const std::string& path, const std::optional<std::string>& sensor) {
          DatasetOptions options;
          if (sensor) options.sensor = parse_sensor(*sensor);
          return open_dataset(kind, path, options);
        },
        py::arg("kind"), py::arg("path"), py::arg("sensor") = py::none());
  m.def("tum_settings_for_name", &tum_settings_for_name, py::arg("name"),
        "The TUM RGB-D benchmark's camera (ORB-SLAM2's TUM1/2/3.yaml) for a name that names freiburg1, 2 or 3; "
        "None when it names none.");

  py::class_<vocab::Vocabulary, VocabularyPtr>(
      m, "Vocabulary",
      "Bag-of-binary-words vocabulary for ORB descriptors (DBoW2-style tree, TF-IDF, L1 score).")
      .def_static(
          "train",
          [](const py::list& descriptors, int k, int L, unsigned seed) {
            std::vector<cv::Mat> mats;
            for (size_t i = 0; i < descriptors.size(); ++i)
              mats.push_back(descriptors_from(descriptors[i], "descriptors[" + std::to_string(i) + "]"));
            py::gil_scoped_release release;
            return std::make_shared<vocab::Vocabulary>(vocab::Vocabulary::train(mats, k, L, seed));
          },
          py::arg("descriptors"), py::arg("k") = 10, py::arg("L") = 6, py::arg("seed") = 0,
          "Hierarchical k-means++ over a list of (N, 32) uint8 descriptor arrays, one per image.")
      .def_static(
          "load",
          [](const py::object& path) {
            const std::string p = path_of(path);
            py::gil_scoped_release release;
            return std::make_shared<vocab::Vocabulary>(vocab::Vocabulary::load_any(p));
          },
          py::arg("path"), "Loads the binary form or ORB-SLAM2's ORBvoc.txt.")
      .def("save", [](const vocab::Vocabulary& v, const py::object& path) {
        v.save(path_of(path));
      }, py::arg("path"), "Writes the binary form.")
      .def("save_text", [](const vocab::Vocabulary& v, const py::object& path) {
        v.save_orbvoc_text(path_of(path));
      }, py::arg("path"), "Writes ORB-SLAM2's ORBvoc.txt format.")
      .def_property_readonly("size", &vocab::Vocabulary::size, "Number of words.")
      .def("__len__", &vocab::Vocabulary::size)
      .def_property_readonly("k", &vocab::Vocabulary::branching)
      .def_property_readonly("L", &vocab::Vocabulary::depth)
      .def("transform",
           [](const vocab::Vocabulary& v, const py::object& descriptors) {
             const cv::Mat d = descriptors_from(descriptors, "descriptors");
             vocab::BowVector bow;
             v.transform(d, bow);
             return std::map<vocab::WordId, double>(bow.begin(), bow.end());
           },
           py::arg("descriptors"), "Bag of words {word: weight} (TF-IDF, L1-normalised).")
      .def("score", [](const vocab::Vocabulary& v, const py::dict& a, const py::dict& b) {
        return v.score(bow_from(a), bow_from(b));
      }, py::arg("a"), py::arg("b"), "L1 score of two bags of words, in [0, 1].");

  m.def(
      "extract_orb",
      [](const py::object& image, const Settings& settings) {
        cv::Mat img = as_mat(image, "image"), grey;
        if (img.depth() != CV_8U || (img.channels() != 1 && img.channels() != 3))
          throw InputError("image: expected uint8 HxW or HxWx3");
        std::vector<cv::KeyPoint> keys;
        cv::Mat desc;
        {
          py::gil_scoped_release release;
          if (img.channels() == 3) cv::cvtColor(img, grey, settings.camera.rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
          else grey = img;
          features::OrbExtractor(settings.extractor).extract(grey, cv::Mat(), keys, desc);
        }
        py::array_t<float> kp({static_cast<py::ssize_t>(keys.size()), py::ssize_t(4)});
        auto k = kp.mutable_unchecked<2>();
        for (size_t i = 0; i < keys.size(); ++i) {
          k(i, 0) = keys[i].pt.x;
          k(i, 1) = keys[i].pt.y;
          k(i, 2) = static_cast<float>(keys[i].octave);
          k(i, 3) = keys[i].angle;
        }
        py::array_t<uint8_t> d({static_cast<py::ssize_t>(keys.size()), py::ssize_t(32)});
        if (!keys.empty()) std::memcpy(d.mutable_data(), desc.data, keys.size() * 32);
        return py::make_tuple(kp, d);
      },
      py::arg("image"), py::arg("settings"),
      "ORB keypoints (N, 4: x, y, level, angle in degrees) and descriptors (N, 32) uint8 from the "
      "System's extractor with the settings' ORBextractor parameters (no undistortion).");

  bind_options(m);
  bind_labels(m);

  py::class_<dynamic::DynamicFilterOptions>(
      m, "DynamicFilterOptions",
      "The dynamic-object front end's preset: stages in order, per sensor, with their options\n"
      "(config/dynamic/*.yaml; see include/dynaorb/dynamic/dynamic_filter.h).")
      .def(py::init<>(), "Off: no stage.")
      .def_static("load", [](const py::object& path) { return dynamic::DynamicFilterOptions::load(path_of(path)); },
                  py::arg("path"), "Reads a preset file (InputError naming the file and key when it is wrong).")
      .def_static("parse", &dynamic::DynamicFilterOptions::parse, py::arg("yaml"), py::arg("source") = "<text>",
                  "Reads a preset from YAML text.")
      .def_readonly("source", &dynamic::DynamicFilterOptions::source)
      .def("stages_for", [](const dynamic::DynamicFilterOptions& o, const std::string& sensor) {
        return o.stages_for(parse_sensor(sensor));
      }, py::arg("sensor"), "The stage names that run for this sensor, in order.")
      .def("enabled", [](const dynamic::DynamicFilterOptions& o, const std::string& sensor) {
        return o.enabled(parse_sensor(sensor));
      }, py::arg("sensor"))
      .def("validate", [](const dynamic::DynamicFilterOptions& o, const std::string& sensor) {
        o.validate(parse_sensor(sensor));
      }, py::arg("sensor"), "InputError when a stage is unknown or does not support the sensor.")
      .def_readwrite("keyframes", &dynamic::DynamicFilterOptions::keyframes)
      .def_readwrite("all_dynamic_fraction", &dynamic::DynamicFilterOptions::all_dynamic_fraction)
      .def_readwrite("overlap_extraction", &dynamic::DynamicFilterOptions::overlap_extraction,
                     "1: the filter runs beside the ORB corner detection; 0: before it; -1: by sensor and cores.")
      .def_readwrite("movable_classes", &dynamic::DynamicFilterOptions::movable_classes,
                     "Non-empty: the semantic stage's movable class ids (the label source's own set).");
  m.def("dynamic_stages", &dynamic::registered_stages, "Names of the dynamic-filter stages a preset may list.");

  py::class_<TrackResult>(m, "TrackResult")
      .def_property_readonly("state", [](const TrackResult& r) { return to_string(r.state); })
      .def_property_readonly("rejected", [](const TrackResult& r) { return to_string(r.rejected); })
      .def_property_readonly("pose", [](const TrackResult& r) -> py::object {
        if (!r.pose) return py::none();
        return py::cast(Eigen::Matrix4d(r.pose->matrix()));
      })
      .def_readonly("message", &TrackResult::message)
      .def_readonly("stage_ms", &TrackResult::stage_ms)
      .def_readonly("invalid_depth_pixels", &TrackResult::invalid_depth_pixels)
      .def_readonly("mask_used", &TrackResult::mask_used)
      .def_readonly("keypoints", &TrackResult::keypoints)
      .def_readonly("tracked_points", &TrackResult::tracked_points)
      .def_readonly("new_keyframe", &TrackResult::new_keyframe)
      .def_readonly("method", &TrackResult::method)
      .def_readonly("map", &TrackResult::map, "The map the pose is in (one more after each map given up).")
      .def_readonly("map_dropped", &TrackResult::map_dropped, "This lost frame gave the map up.")
      .def_readonly("labels_used", &TrackResult::labels_used)
      .def_readonly("dynamic_keypoints", &TrackResult::dynamic_keypoints,
                    "Keypoints the dynamic filter's mask kept out (those an extraction without it kept there).")
      .def_readonly("dynamic_fraction", &TrackResult::dynamic_fraction)
      .def_readonly("dynamic_values", &TrackResult::dynamic_values,
                    "The stages' reports: '<stage>.<value>' -> number.");

  py::class_<System>(m, "System")
      .def(py::init([](const Settings& s, const std::string& sensor, bool synchronous_mapping,
                       const py::object& vocabulary, bool loop_closing, const py::object& global_ba,
                       const py::object& dyn, const py::object& tracker, const py::object& background_nice,
                       const py::object& mapping_options, const py::object& loop_options) {
             SystemOptions o;
             if (!tracker.is_none()) o.tracker = tracker.cast<tracking::TrackerOptions>();
             if (!mapping_options.is_none()) o.mapping = mapping_options.cast<mapping::LocalMapperOptions>();
             if (!loop_options.is_none()) o.loop = loop_options.cast<loop::LoopCloserOptions>();
             if (!background_nice.is_none()) {
               const int nice = background_nice.cast<int>();
               check_background_nice(nice, "background_nice");
               o.mapping.thread_nice = o.loop.thread_nice = nice;
             }
             o.synchronous_mapping = synchronous_mapping;
             o.vocabulary = vocabulary_from(vocabulary);
             o.loop_closing = loop_closing;
             if (!global_ba.is_none()) o.loop.global_ba = global_ba.cast<bool>();
             o.dynamic = dynamic_from(dyn);
             return std::make_unique<System>(s, parse_sensor(sensor), o);
           }),
           py::arg("settings"), py::arg("sensor"), py::arg("synchronous_mapping") = false,
           py::arg("vocabulary") = py::none(), py::arg("loop_closing") = true, py::arg("global_ba") = py::none(),
           py::arg("dynamic") = py::none(), py::arg("tracker") = py::none(),
           py::arg("background_nice") = py::none(), py::arg("mapping") = py::none(), py::arg("loop") = py::none(),
           "synchronous_mapping: map each keyframe before tracking the next frame (repeatable runs).\n"
           "vocabulary: None, a Vocabulary or a path to one (ORBvoc.txt or binary): bag-of-words\n"
           "matching, a keyframe database and relocalisation of lost frames.\n"
           "loop_closing: detect and correct loops (needs the vocabulary); global_ba: a global\n"
           "bundle adjustment after each loop correction (None: the loop options', True by default).\n"
           "dynamic: None (off), a DynamicFilterOptions or a preset file: the dynamic-object front end.\n"
           "tracker, mapping, loop: None (the defaults) or a TrackerOptions, LocalMapperOptions,\n"
           "LoopCloserOptions (each checked here: InputError naming a value out of range).\n"
           "background_nice: None (the default, 10) or 0-19: the nice value of the local mapping, loop\n"
           "closing and global BA threads above the process's (0: tracking's priority).")
      .def("track_mono",
           [](System& s, const py::object& image, double stamp, const py::object& mask, const py::object& labels) {
             cv::Mat i = as_mat(image, "image"), k = as_mat(mask, "mask"), l = as_mat(labels, "labels");
             py::gil_scoped_release release;
             return s.track_mono(i, stamp, k, l);
           },
           py::arg("image"), py::arg("stamp"), py::arg("mask") = py::none(), py::arg("labels") = py::none())
      .def("track_stereo",
           [](System& s, const py::object& left, const py::object& right, double stamp, const py::object& mask,
              const py::object& labels) {
             cv::Mat l = as_mat(left, "left"), r = as_mat(right, "right"), k = as_mat(mask, "mask"),
                     b = as_mat(labels, "labels");
             py::gil_scoped_release release;
             return s.track_stereo(l, r, stamp, k, b);
           },
           py::arg("left"), py::arg("right"), py::arg("stamp"), py::arg("mask") = py::none(),
           py::arg("labels") = py::none())
      .def("track_rgbd",
           [](System& s, const py::object& image, const py::object& depth, double stamp, const py::object& mask,
              const py::object& labels) {
             cv::Mat i = as_mat(image, "image"), d = as_mat(depth, "depth"), k = as_mat(mask, "mask"),
                     l = as_mat(labels, "labels");
             py::gil_scoped_release release;
             return s.track_rgbd(i, d, stamp, k, l);
           },
           py::arg("image"), py::arg("depth"), py::arg("stamp"), py::arg("mask") = py::none(),
           py::arg("labels") = py::none())
      .def("track_frame",
           [](System& s, const Frame& f, const py::object& mask, const py::object& labels) {
             cv::Mat k = as_mat(mask, "mask"), l = as_mat(labels, "labels");
             py::gil_scoped_release release;
             switch (s.sensor()) {
               case Sensor::kMono: return s.track_mono(f.image, f.stamp, k, l);
               case Sensor::kStereo: return s.track_stereo(f.image, f.right, f.stamp, k, l);
               case Sensor::kRGBD: return s.track_rgbd(f.image, f.depth, f.stamp, k, l);
             }
             throw InputError("unknown sensor");
           },
           py::arg("frame"), py::arg("mask") = py::none(), py::arg("labels") = py::none(),
           "Tracks a frame loaded by a DataProvider.")
      .def_property_readonly("sensor", [](const System& s) { return to_string(s.sensor()); })
      .def_property_readonly("settings", &System::settings)
      .def("counters", [](const System& s) {
        const SystemCounters& c = s.counters();
        py::dict d;
        d["frames"] = c.frames;
        d["rejected"] = c.rejected;
        d["tracked"] = c.tracked;
        d["masks_dropped"] = c.masks_dropped;
        d["labels_dropped"] = c.labels_dropped;
        d["dynamic_all_frames"] = c.dynamic_all_frames;
        d["dynamic_stage_failures"] = c.dynamic_stage_failures;
        d["unchecked_kept"] = c.unchecked_kept;
        d["rejected_by_reason"] = c.rejected_by_reason;
        d["lost"] = c.lost;
        d["initializations"] = c.initializations;
        d["maps_dropped"] = c.maps_dropped;
        d["relocalizations"] = c.relocalizations;
        d["loops_closed"] = c.loops_closed;
        d["global_ba_runs"] = c.global_ba_runs;
        return d;
      })
      .def("map_points", [](const System& s) {
        const std::vector<Eigen::Vector3d> pts = s.map_points();
        py::array_t<double> a({static_cast<py::ssize_t>(pts.size()), py::ssize_t(3)});
        auto v = a.mutable_unchecked<2>();
        for (size_t i = 0; i < pts.size(); ++i)
          for (int k = 0; k < 3; ++k) v(i, k) = pts[i](k);
        return a;
      }, "Sparse map points (N, 3) in the world frame.")
      .def("map_summary", [](const System& s) {
        const MapSummary m = s.map_summary();
        py::dict d;
        d["keyframes"] = m.keyframes;
        d["points"] = m.points;
        d["points_created"] = m.mapping.points_created;
        d["points_culled"] = m.mapping.points_culled;
        d["points_fused"] = m.mapping.points_fused;
        d["keyframes_culled"] = m.mapping.keyframes_culled;
        d["local_ba_runs"] = m.mapping.local_ba_runs;
        d["local_ba_aborted"] = m.mapping.local_ba_aborted;
        d["local_ba_window_last"] = m.mapping.local_ba_window_last;
        d["local_ba_fixed_last"] = m.mapping.local_ba_fixed_last;
        d["local_ba_window_max"] = m.mapping.local_ba_window_max;
        d["loop_keyframes_checked"] = m.loop.keyframes;
        d["loop_candidates"] = m.loop.candidates;
        d["loops_closed"] = m.loop.loops_closed;
        d["global_ba_runs"] = m.loop.global_ba_runs;
        d["global_ba_aborted"] = m.loop.global_ba_aborted;
        d["loop_edges"] = m.loop.loop_edges;
        d["last_loop_keyframe"] = m.loop.last_loop_keyframe;
        d["last_loop_match"] = m.loop.last_loop_match;
        d["last_loop_frame"] = m.loop.last_loop_frame;
        d["last_loop_matches"] = m.loop.last_loop_matches;
        d["last_loop_correction_ms"] = m.loop.last_correction_ms;
        d["last_global_ba_ms"] = m.loop.last_global_ba_ms;
        return d;
      })
      .def("trajectory", [](const System& s) { return trajectory_to_numpy(s.trajectory()); },
           "(stamps, poses) of the map with the most tracked frames (all of them without a new map).")
      .def("trajectory_segments", [](const System& s) {
        py::list out;
        for (const TrajectorySegment& seg : s.trajectory_segments()) {
          py::tuple t = trajectory_to_numpy(seg.poses);
          out.append(py::make_tuple(seg.map, t[0], t[1]));
        }
        return out;
      }, "[(map, stamps, poses)] for every map, in order: a lost map given up starts a new segment.")
      .def_property_readonly("dynamic_filter_enabled", &System::dynamic_filter_enabled)
      .def_property_readonly("movable_classes", &System::movable_classes,
                             "The dynamic filter's movable label ids (its semantic stage's; [] without one).")
      .def("set_movable_classes", &System::set_movable_classes, py::arg("ids"),
           "Replaces them between track calls (a label source announcing its own set).")
      .def("last_dynamic_mask", [](const System& s) { return to_numpy(s.last_dynamic_mask()); },
           "The dynamic filter's mask of the last frame (uint8 HxW, 255 = dynamic) in the input image's\n"
           "pixels; None when the filter is off or before a frame.")
      .def("dense_frame", [](const System& s, bool inpaint) -> py::object {
        DenseFrame d;
        {
          py::gil_scoped_release release;
          d = s.dense_frame(inpaint);
        }
        if (d.colour.empty()) return py::none();
        py::dict out;
        out["stamp"] = d.stamp;
        out["colour"] = to_numpy(d.colour);
        out["depth"] = to_numpy(d.depth);
        out["dynamic"] = to_numpy(d.dynamic);
        out["T_wc"] = pose_or_none(d.T_wc);
        out["K"] = py::cast(Eigen::Matrix3d((Eigen::Matrix3d() << d.fx, 0, d.cx, 0, d.fy, d.cy, 0, 0, 1).finished()));
        out["dist"] = to_numpy(d.dist);
        out["inpainted"] = d.inpainted;
        out["inpainted_pixels"] = d.inpainted_pixels;
        out["candidates"] = to_numpy(d.candidates);
        out["motion_checked"] = d.motion_checked;
        return out;
      }, py::arg("inpaint") = false,
         "The last frame for a dense map: dict(stamp, colour BGR, depth (metres or None), dynamic mask,\n"
         "T_wc (4x4 or None when not tracked), K, dist, inpainted, inpainted_pixels, candidates (the\n"
         "labels' movable-class regions or None), motion_checked (False: no previous frame, so the\n"
         "candidates the filter did not mark are unverified)) in the tracked image's pixels (rectified\n"
         "for stereo; stereo depth by semi-global block matching); inpaint: dynamic pixels filled with\n"
         "the background the remembered keyframes saw. None when the filter is off or before a frame.")
      .def("wait_for_mapping", &System::wait_for_mapping, py::call_guard<py::gil_scoped_release>(),
           "Waits until local mapping has mapped the keyframes queued and loop closing (with its global BA)\n"
           "has finished: the trajectory and map are then final for the frames so far (after the last frame).")
      .def("reset", &System::reset, "Drops the map, the keyframe database and the trajectory.")
      .def("save_map", [](System& s, const py::object& path) {
        const std::string p = path_of(path);
        py::gil_scoped_release release;
        s.save_map(p);
      }, py::arg("path"), "Writes the map to a versioned binary file (between frames).")
      .def("load_map", [](System& s, const py::object& path) {
        const std::string p = path_of(path);
        py::gil_scoped_release release;
        s.load_map(p);
      }, py::arg("path"),
         "Replaces the map with a saved one; the next frame is relocalised in it (needs a vocabulary;\n"
         "the file's sensor and calibration must be this system's: InputError otherwise).")
      .def("set_localization_mode", &System::set_localization_mode, py::arg("on"),
           "Localisation only: tracking in the map, no new keyframes or map points.")
      .def_property("localization_mode", &System::localization_mode, &System::set_localization_mode);

  m.def("write_tum", [](const std::string& path, py::array_t<double> stamps, py::array_t<double> poses) {
    io::write_tum(path, trajectory_from_numpy(stamps, poses));
  }, py::arg("path"), py::arg("stamps"), py::arg("poses"));
  m.def("write_kitti", [](const std::string& path, py::array_t<double> stamps, py::array_t<double> poses) {
    io::write_kitti(path, trajectory_from_numpy(stamps, poses));
  }, py::arg("path"), py::arg("stamps"), py::arg("poses"));
  m.def("read_tum", [](const std::string& path) { return trajectory_to_numpy(io::read_tum(path)); });
  m.def("read_kitti", [](const std::string& path) { return trajectory_to_numpy(io::read_kitti(path)); });
}
