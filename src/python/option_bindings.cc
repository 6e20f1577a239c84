// dynaorb._core's option classes (option_bindings.h). Each is checked where
// a System is made (its validate(): an InputError naming the option).
#include "option_bindings.h"

#include "dynaorb/loop/loop_closer.h"
#include "dynaorb/mapping/local_mapper.h"
#include "dynaorb/tracking/tracker.h"

namespace py = pybind11;

namespace dynaorb {

void bind_options(py::module_& m) {
  py::class_<tracking::TrackerOptions>(m, "TrackerOptions",
                                      "The tracking thread's options (dynaorb/tracking/tracker.h; defaults\n"
                                      "are ORB-SLAM2's). max_frames is replaced by the settings' Camera.fps when set.")
      .def(py::init<>())
      .def_readwrite("min_init_keypoints", &tracking::TrackerOptions::min_init_keypoints)
      .def_readwrite("min_init_depth_points", &tracking::TrackerOptions::min_init_depth_points)
      .def_readwrite("motion_th_stereo", &tracking::TrackerOptions::motion_th_stereo)
      .def_readwrite("motion_th_mono", &tracking::TrackerOptions::motion_th_mono)
      .def_readwrite("min_motion_matches", &tracking::TrackerOptions::min_motion_matches)
      .def_readwrite("min_reference_matches", &tracking::TrackerOptions::min_reference_matches)
      .def_readwrite("reference_bow_ratio", &tracking::TrackerOptions::reference_bow_ratio)
      .def_readwrite("min_pose_inliers", &tracking::TrackerOptions::min_pose_inliers)
      .def_readwrite("min_local_map_inliers", &tracking::TrackerOptions::min_local_map_inliers)
      .def_readwrite("local_search_th_stereo", &tracking::TrackerOptions::local_search_th_stereo)
      .def_readwrite("local_search_th_rgbd", &tracking::TrackerOptions::local_search_th_rgbd)
      .def_readwrite("local_search_th_mono", &tracking::TrackerOptions::local_search_th_mono)
      .def_readwrite("max_local_keyframes", &tracking::TrackerOptions::max_local_keyframes)
      .def_readwrite("ref_ratio_stereo", &tracking::TrackerOptions::ref_ratio_stereo)
      .def_readwrite("ref_ratio_mono", &tracking::TrackerOptions::ref_ratio_mono)
      .def_readwrite("close_tracked_max", &tracking::TrackerOptions::close_tracked_max)
      .def_readwrite("close_untracked_min", &tracking::TrackerOptions::close_untracked_min)
      .def_readwrite("new_keyframe_close_points", &tracking::TrackerOptions::new_keyframe_close_points)
      .def_readwrite("max_frames", &tracking::TrackerOptions::max_frames)
      .def_readwrite("min_frames", &tracking::TrackerOptions::min_frames)
      .def_readwrite("reset_if_lost_below_keyframes", &tracking::TrackerOptions::reset_if_lost_below_keyframes)
      .def_readwrite("reset_after_lost", &tracking::TrackerOptions::reset_after_lost)
      .def_readwrite("new_map_after_lost_s", &tracking::TrackerOptions::new_map_after_lost_s)
      .def_readwrite("mono_init_feature_factor", &tracking::TrackerOptions::mono_init_feature_factor)
      .def_readwrite("mono_init_feature_frames", &tracking::TrackerOptions::mono_init_feature_frames)
      .def_readwrite("mono_init_release_tracked", &tracking::TrackerOptions::mono_init_release_tracked)
      .def_readwrite("stereo_right_budget_max_factor", &tracking::TrackerOptions::stereo_right_budget_max_factor)
      .def_readwrite("mono_init_min_keypoints", &tracking::TrackerOptions::mono_init_min_keypoints)
      .def_readwrite("mono_init_window", &tracking::TrackerOptions::mono_init_window)
      .def_readwrite("mono_init_nn_ratio", &tracking::TrackerOptions::mono_init_nn_ratio)
      .def_readwrite("mono_init_min_matches", &tracking::TrackerOptions::mono_init_min_matches)
      .def_readwrite("mono_init_ba_iterations", &tracking::TrackerOptions::mono_init_ba_iterations)
      .def_readwrite("mono_init_min_tracked", &tracking::TrackerOptions::mono_init_min_tracked);

  using mapping::LocalMapperOptions;
  py::class_<LocalMapperOptions>(m, "LocalMapperOptions",
                                 "Local mapping's options (dynaorb/mapping/local_mapper.h; defaults are\n"
                                 "ORB-SLAM2's). thread_nice is replaced by System's background_nice when given.")
      .def(py::init<>())
      .def_readwrite("neighbors_stereo", &LocalMapperOptions::neighbors_stereo)
      .def_readwrite("neighbors_mono", &LocalMapperOptions::neighbors_mono)
      .def_readwrite("triangulation_bow_mono", &LocalMapperOptions::triangulation_bow_mono)
      .def_readwrite("triangulation_bow_stereo", &LocalMapperOptions::triangulation_bow_stereo)
      .def_readwrite("min_found_ratio", &LocalMapperOptions::min_found_ratio)
      .def_readwrite("min_observations_stereo", &LocalMapperOptions::min_observations_stereo)
      .def_readwrite("min_observations_mono", &LocalMapperOptions::min_observations_mono)
      .def_readwrite("redundant_ratio", &LocalMapperOptions::redundant_ratio)
      .def_readwrite("redundant_observers", &LocalMapperOptions::redundant_observers)
      .def_readwrite("local_ba", &LocalMapperOptions::local_ba)
      .def_readwrite("ba_threads", &LocalMapperOptions::ba_threads)
      .def_readwrite("thread_nice", &LocalMapperOptions::thread_nice)
      .def("validate", &LocalMapperOptions::validate, "InputError naming a value out of range.");

  using loop::Sim3RansacOptions;
  py::class_<Sim3RansacOptions>(m, "Sim3RansacOptions",
                                "The loop candidates' similarity RANSAC (dynaorb/loop/sim3_ransac.h); its\n"
                                "scale is fixed by the sensor (stereo, RGB-D) or free (mono).")
      .def(py::init<>())
      .def_readwrite("probability", &Sim3RansacOptions::probability)
      .def_readwrite("min_inliers", &Sim3RansacOptions::min_inliers)
      .def_readwrite("max_iterations", &Sim3RansacOptions::max_iterations)
      .def_readwrite("chi2", &Sim3RansacOptions::chi2)
      .def_readwrite("seed", &Sim3RansacOptions::seed);

  using loop::LoopCloserOptions;
  py::class_<LoopCloserOptions>(m, "LoopCloserOptions",
                                "Loop closing's options (dynaorb/loop/loop_closer.h; defaults are ORB-SLAM2's).\n"
                                "global_ba and thread_nice are replaced by System's global_ba and background_nice\n"
                                "when those are given.")
      .def(py::init<>())
      .def_readwrite("consistency", &LoopCloserOptions::consistency)
      .def_readwrite("min_map_keyframes", &LoopCloserOptions::min_map_keyframes)
      .def_readwrite("min_keyframes_after_loop", &LoopCloserOptions::min_keyframes_after_loop)
      .def_readwrite("min_bow_matches", &LoopCloserOptions::min_bow_matches)
      .def_readwrite("bow_nn_ratio", &LoopCloserOptions::bow_nn_ratio)
      .def_readwrite("ransac", &LoopCloserOptions::ransac)
      .def_readwrite("projection_radius", &LoopCloserOptions::projection_radius)
      .def_readwrite("projection_max_distance", &LoopCloserOptions::projection_max_distance)
      .def_readwrite("min_projection_matches", &LoopCloserOptions::min_projection_matches)
      .def_readwrite("fuse_radius", &LoopCloserOptions::fuse_radius)
      .def_readwrite("essential_min_weight", &LoopCloserOptions::essential_min_weight)
      .def_readwrite("pose_graph_iterations", &LoopCloserOptions::pose_graph_iterations)
      .def_readwrite("global_ba", &LoopCloserOptions::global_ba)
      .def_readwrite("global_ba_iterations", &LoopCloserOptions::global_ba_iterations)
      .def_readwrite("threads", &LoopCloserOptions::threads)
      .def_readwrite("thread_nice", &LoopCloserOptions::thread_nice)
      .def("validate", &LoopCloserOptions::validate, "InputError naming a value out of range.");
}

}  // namespace dynaorb
