// TrackerOptions::validate: its numbers, reloc's (with reloc.pnp's) and
// two_view's checked, the bad one named. The
// options come from Python (`dynaorb run --tracker KEY=VALUE`), ROS
// parameters and C++ callers; a negative count, a ratio outside (0, 1] or a
// non-finite number would otherwise change tracking silently (a NaN
// new_map_after_lost_s, say, would mean "never" without a word).
#include <cmath>
#include <string>
#include <utility>

#include "../core/option_checks.h"
#include "dynaorb/tracking/tracker.h"

namespace dynaorb::tracking {

TrackerOptions TrackerOptions::with_camera_fps(double fps) const {
  TrackerOptions o = *this;
  if (o.max_frames < 0) o.max_frames = fps > 0 && std::isfinite(fps) ? static_cast<int>(std::lround(fps)) : 30;
  return o;
}

void TrackerOptions::validate() const {
  const dynaorb::detail::OptionChecks c("tracker");
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
    c.at_least(name, v, 0);
  c.at_least("max_frames", max_frames, -1);  // -1: Camera.fps
  c.at_least("max_local_keyframes", max_local_keyframes, 1);
  c.at_least("max_sharing_keyframes", max_sharing_keyframes, 0);  // 0: all
  c.at_least("refine_lag_keyframes", refine_lag_keyframes, 0);    // 0: off
  c.at_least("refine_min_points", refine_min_points, 1);
  c.at_least("refine_rounds", refine_rounds, 1);
  c.at_least("refine_max_pending", refine_max_pending, 1);
  c.non_negative("pose_final_huber", pose_final_huber, "plain least squares");  // standard deviations
  c.non_negative("pose_final_huber_mono", pose_final_huber_mono, "plain least squares");
  c.at_least("mono_init_feature_factor", mono_init_feature_factor, 1);
  c.at_least("mask_margin", mask_margin, 0);  // level pixels
  for (const auto& [name, v] : {std::pair<const char*, double>{"motion_th_stereo", motion_th_stereo},
                                {"motion_th_mono", motion_th_mono},
                                {"local_search_th_stereo", local_search_th_stereo},
                                {"local_search_th_rgbd", local_search_th_rgbd},
                                {"local_search_th_mono", local_search_th_mono},
                                {"mono_init_window", mono_init_window},
                                {"reloc.wide_window", reloc.wide_window},
                                {"reloc.narrow_window", reloc.narrow_window}})
    c.positive(name, v);
  for (const auto& [name, v] : {std::pair<const char*, double>{"reference_bow_ratio", reference_bow_ratio},
                                {"ref_ratio_stereo", ref_ratio_stereo},
                                {"ref_ratio_mono", ref_ratio_mono},
                                {"mono_init_nn_ratio", mono_init_nn_ratio},
                                {"reloc.bow_ratio", reloc.bow_ratio}})
    c.between(name, v, 0, 1, true);
  // The monocular initialisation's two-view reconstruction.
  for (const auto& [name, v] : {std::pair<const char*, double>{"two_view.sigma", two_view.sigma},
                                {"two_view.chi2_h", two_view.chi2_h},
                                {"two_view.chi2_f", two_view.chi2_f},
                                {"two_view.score_gamma", two_view.score_gamma},
                                {"two_view.reproj_chi2", two_view.reproj_chi2}})
    c.positive(name, v);
  c.at_least("two_view.ransac_iterations", two_view.ransac_iterations, 1);
  if (two_view.homography_sample < 4 || two_view.homography_sample > 8)
    c.fail("two_view.homography_sample", two_view.homography_sample,
           "4 to 8 (points of each 8-point set the homography is fitted on)");
  c.at_least("two_view.parallax_rank", two_view.parallax_rank, 0);
  c.at_least("two_view.min_triangulated", two_view.min_triangulated, 8);
  if (!std::isfinite(two_view.min_parallax_deg) || two_view.min_parallax_deg < 0 || two_view.min_parallax_deg >= 90)
    c.fail("two_view.min_parallax_deg", two_view.min_parallax_deg, "a finite angle in [0, 90) degrees");
  for (const auto& [name, v] : {std::pair<const char*, double>{"two_view.ratio_h", two_view.ratio_h},
                                {"two_view.min_good_fraction", two_view.min_good_fraction},
                                {"two_view.clear_winner_ratio", two_view.clear_winner_ratio}})
    c.between(name, v, 0, 1, true);
  // Relocalisation's PnP RANSAC.
  if (!std::isfinite(reloc.pnp.probability) || reloc.pnp.probability <= 0 || reloc.pnp.probability >= 1)
    c.fail("reloc.pnp.probability", reloc.pnp.probability, "a probability in (0, 1)");
  c.at_least("reloc.pnp.min_inliers", reloc.pnp.min_inliers, 4);
  c.at_least("reloc.pnp.max_iterations", reloc.pnp.max_iterations, 1);
  c.positive("reloc.pnp.chi2", reloc.pnp.chi2);
  c.non_negative("new_map_after_lost_s", new_map_after_lost_s, "never");  // seconds
  if (!std::isfinite(stereo_right_budget_max_factor) || stereo_right_budget_max_factor < 1)
    c.fail("stereo_right_budget_max_factor", stereo_right_budget_max_factor,
           "a finite number >= 1 (1: the right image gets nFeatures, as ORB-SLAM2)");
}

}  // namespace dynaorb::tracking
