// TrackerOptions::validate: its numbers, reloc's (with reloc.pnp's) and
// two_view's checked, the bad one named. The
// options come from Python (`dynaorb run --tracker KEY=VALUE`), ROS
// parameters and C++ callers; a negative count, a ratio outside (0, 1] or a
// non-finite number would otherwise change tracking silently (a NaN
// new_map_after_lost_s, say, would mean "never" without a word).
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "dynaorb/io/errors.h"
#include "dynaorb/tracking/tracker.h"

namespace dynaorb::tracking {

namespace {

[[noreturn]] void refuse(const std::string& name, const std::string& value, const std::string& rule) {
  throw InputError("tracker option '" + name + "' is " + value + "; it must be " + rule);
}

std::string number(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

void at_least(const std::string& name, int v, int min) {
  if (v < min) refuse(name, std::to_string(v), "an integer >= " + std::to_string(min));
}

void positive(const std::string& name, double v) {
  if (!std::isfinite(v) || v <= 0) refuse(name, number(v), "a finite number > 0");
}

void ratio(const std::string& name, double v) {
  if (!std::isfinite(v) || v <= 0 || v > 1) refuse(name, number(v), "a ratio in (0, 1]");
}

}  // namespace

TrackerOptions TrackerOptions::with_camera_fps(double fps) const {
  TrackerOptions o = *this;
  if (o.max_frames < 0) o.max_frames = fps > 0 && std::isfinite(fps) ? static_cast<int>(std::lround(fps)) : 30;
  return o;
}

void TrackerOptions::validate() const {
  for (const auto& [name, v] : {std::pair<const char*, int>{"min_init_keypoints", min_init_keypoints},
                                {"min_init_depth_points", min_init_depth_points},
                                {"min_motion_matches", min_motion_matches},
                                {"min_reference_matches", min_reference_matches},
                                {"min_pose_inliers", min_pose_inliers},
                                {"min_local_map_inliers", min_local_map_inliers},
                                {"close_tracked_max", close_tracked_max},
                                {"close_untracked_min", close_untracked_min},
                                {"new_keyframe_close_points", new_keyframe_close_points},
                                {"min_frames", min_frames},
                                {"reset_if_lost_below_keyframes", reset_if_lost_below_keyframes},
                                {"reset_after_lost", reset_after_lost},
                                {"mono_init_feature_frames", mono_init_feature_frames},
                                {"mono_init_release_tracked", mono_init_release_tracked},
                                {"mono_init_min_keypoints", mono_init_min_keypoints},
                                {"mono_init_min_matches", mono_init_min_matches},
                                {"mono_init_ba_iterations", mono_init_ba_iterations},
                                {"mono_init_min_tracked", mono_init_min_tracked},
                                {"reloc.min_bow_matches", reloc.min_bow_matches},
                                {"reloc.min_pose_inliers", reloc.min_pose_inliers},
                                {"reloc.min_inliers", reloc.min_inliers},
                                {"reloc.wide_max_distance", reloc.wide_max_distance},
                                {"reloc.narrow_after", reloc.narrow_after},
                                {"reloc.narrow_max_distance", reloc.narrow_max_distance},
                                {"reloc.local_map_inliers", reloc.local_map_inliers}})
    at_least(name, v, 0);
  at_least("max_frames", max_frames, -1);  // -1: Camera.fps
  at_least("max_local_keyframes", max_local_keyframes, 1);
  at_least("mono_init_feature_factor", mono_init_feature_factor, 1);
  for (const auto& [name, v] : {std::pair<const char*, double>{"motion_th_stereo", motion_th_stereo},
                                {"motion_th_mono", motion_th_mono},
                                {"local_search_th_stereo", local_search_th_stereo},
                                {"local_search_th_rgbd", local_search_th_rgbd},
                                {"local_search_th_mono", local_search_th_mono},
                                {"mono_init_window", mono_init_window},
                                {"reloc.wide_window", reloc.wide_window},
                                {"reloc.narrow_window", reloc.narrow_window}})
    positive(name, v);
  for (const auto& [name, v] : {std::pair<const char*, double>{"reference_bow_ratio", reference_bow_ratio},
                                {"ref_ratio_stereo", ref_ratio_stereo},
                                {"ref_ratio_mono", ref_ratio_mono},
                                {"mono_init_nn_ratio", mono_init_nn_ratio},
                                {"reloc.bow_ratio", reloc.bow_ratio}})
    ratio(name, v);
  // The monocular initialisation's two-view reconstruction.
  for (const auto& [name, v] : {std::pair<const char*, double>{"two_view.sigma", two_view.sigma},
                                {"two_view.chi2_h", two_view.chi2_h},
                                {"two_view.chi2_f", two_view.chi2_f},
                                {"two_view.score_gamma", two_view.score_gamma},
                                {"two_view.reproj_chi2", two_view.reproj_chi2}})
    positive(name, v);
  at_least("two_view.ransac_iterations", two_view.ransac_iterations, 1);
  if (two_view.homography_sample < 4 || two_view.homography_sample > 8)
    refuse("two_view.homography_sample", std::to_string(two_view.homography_sample),
           "4 to 8 (points of each 8-point set the homography is fitted on)");
  at_least("two_view.parallax_rank", two_view.parallax_rank, 0);
  at_least("two_view.min_triangulated", two_view.min_triangulated, 8);
  if (!std::isfinite(two_view.min_parallax_deg) || two_view.min_parallax_deg < 0 || two_view.min_parallax_deg >= 90)
    refuse("two_view.min_parallax_deg", number(two_view.min_parallax_deg), "a finite angle in [0, 90) degrees");
  for (const auto& [name, v] : {std::pair<const char*, double>{"two_view.ratio_h", two_view.ratio_h},
                                {"two_view.min_good_fraction", two_view.min_good_fraction},
                                {"two_view.clear_winner_ratio", two_view.clear_winner_ratio}})
    ratio(name, v);
  // Relocalisation's PnP RANSAC.
  if (!std::isfinite(reloc.pnp.probability) || reloc.pnp.probability <= 0 || reloc.pnp.probability >= 1)
    refuse("reloc.pnp.probability", number(reloc.pnp.probability), "a probability in (0, 1)");
  at_least("reloc.pnp.min_inliers", reloc.pnp.min_inliers, 4);
  at_least("reloc.pnp.max_iterations", reloc.pnp.max_iterations, 1);
  positive("reloc.pnp.chi2", reloc.pnp.chi2);
  if (!std::isfinite(new_map_after_lost_s) || new_map_after_lost_s < 0)
    refuse("new_map_after_lost_s", number(new_map_after_lost_s), "a finite number of seconds >= 0 (0: never)");
  if (!std::isfinite(stereo_right_budget_max_factor) || stereo_right_budget_max_factor < 1)
    refuse("stereo_right_budget_max_factor", number(stereo_right_budget_max_factor),
           "a finite number >= 1 (1: the right image gets nFeatures, as ORB-SLAM2)");
}

}  // namespace dynaorb::tracking
