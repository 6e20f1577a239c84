#include "dynaorb/dynamic/li_options.h"

#include <cmath>
#include <string>

#include "dynaorb/io/errors.h"
#include "file_node_options.h"
#include "../core/option_checks.h"

namespace dynaorb::dynamic {

void LiOptions::read(const cv::FileNode& node) {
  using detail::read_option;
  read_option(node, "sgbm_scale", sgbm_scale);
  read_option(node, "sgbm_num_disparities", sgbm_num_disparities);
  read_option(node, "sgbm_block_size", sgbm_block_size);
  read_option(node, "sgbm_p1_per_pixel", sgbm_p1_per_pixel);
  read_option(node, "sgbm_p2_per_pixel", sgbm_p2_per_pixel);
  read_option(node, "sgbm_uniqueness_ratio", sgbm_uniqueness_ratio);
  read_option(node, "sgbm_speckle_window", sgbm_speckle_window);
  read_option(node, "sgbm_speckle_range", sgbm_speckle_range);
  read_option(node, "sgbm_disp12_max_diff", sgbm_disp12_max_diff);
  read_option(node, "sgbm_three_way", sgbm_three_way);
  read_option(node, "n_points", n_points);
  read_option(node, "fast_cell_px", fast_cell_px);
  read_option(node, "fast_threshold", fast_threshold);
  read_option(node, "fast_min_threshold", fast_min_threshold);
  read_option(node, "border_px", border_px);
  read_option(node, "lk_window", lk_window);
  read_option(node, "lk_levels", lk_levels);
  read_option(node, "lk_forward_backward_max", lk_forward_backward_max);
  read_option(node, "f_ransac_threshold_px", f_ransac_threshold_px);
  read_option(node, "f_ransac_confidence", f_ransac_confidence);
  read_option(node, "f_ransac_iterations", f_ransac_iterations);
  read_option(node, "f_exclude_previous_dynamic", f_exclude_previous_dynamic);
  read_option(node, "min_points", min_points);
  read_option(node, "alpha_epi", alpha_epi);
  read_option(node, "beta_epi", beta_epi);
  read_option(node, "disparity_patch_radius", disparity_patch_radius);
  read_option(node, "rigid_check", rigid_check);
  read_option(node, "rigid_threshold_px", rigid_threshold_px);
  read_option(node, "rigid_gate_px", rigid_gate_px);
  read_option(node, "rigid_disparity_sigma_px", rigid_disparity_sigma_px);
  read_option(node, "rigid_ransac_iterations", rigid_ransac_iterations);
  read_option(node, "rigid_min_agreeing", rigid_min_agreeing);
  read_option(node, "rigid_max_angle_deg", rigid_max_angle_deg);
  read_option(node, "rigid_max_ratio", rigid_max_ratio);
  read_option(node, "alpha_s", alpha_s);
  read_option(node, "beta_s", beta_s);
  read_option(node, "t_disp", t_disp);
  read_option(node, "min_cluster_points", min_cluster_points);
  read_option(node, "roi_margin_factor", roi_margin_factor);
  read_option(node, "slic_k", slic_k);
  read_option(node, "slic_nc", slic_nc);
  read_option(node, "slic_max_iterations", slic_max_iterations);
  read_option(node, "fill_occlusions", fill_occlusions);
  read_option(node, "plane_inlier_px", plane_inlier_px);
  read_option(node, "plane_ransac_iterations", plane_ransac_iterations);
  read_option(node, "plane_min_pixels", plane_min_pixels);
  read_option(node, "plane_max_samples", plane_max_samples);
  read_option(node, "lambda_occ", lambda_occ);
  read_option(node, "lambda_hinge", lambda_hinge);
  read_option(node, "lambda_pen", lambda_pen);
  read_option(node, "min_hit_directions", min_hit_directions);
  read_option(node, "foreground_only", foreground_only);
  read_option(node, "foreground_margin_px", foreground_margin_px);
  read_option(node, "foreground_band_px", foreground_band_px);
  read_option(node, "keep_frames", keep_frames);
  read_option(node, "keep_covered_fraction", keep_covered_fraction);
  read_option(node, "keep_min_hits", keep_min_hits);
  validate();
}

void LiOptions::validate() const {
  const dynaorb::detail::OptionChecks c("Dynamic.li");
  c.between("sgbm_scale", sgbm_scale, 0, 1, true);
  c.at_least("sgbm_num_disparities", sgbm_num_disparities, 1);
  c.at_least("sgbm_block_size", sgbm_block_size, 1);
  if (sgbm_block_size % 2 == 0) c.fail("sgbm_block_size", sgbm_block_size, "odd");
  c.non_negative("sgbm_p1_per_pixel", sgbm_p1_per_pixel, "no penalty for disparity steps of 1");
  c.finite("sgbm_p2_per_pixel", sgbm_p2_per_pixel, "a finite number");
  if (!(sgbm_p2_per_pixel > sgbm_p1_per_pixel))
    c.fail("sgbm_p2_per_pixel", sgbm_p2_per_pixel, "> sgbm_p1_per_pixel (" + std::to_string(sgbm_p1_per_pixel) + ")");
  c.at_least("sgbm_uniqueness_ratio", sgbm_uniqueness_ratio, 0);
  c.at_least("sgbm_speckle_window", sgbm_speckle_window, 0);
  c.at_least("sgbm_speckle_range", sgbm_speckle_range, 0);
  c.at_least("n_points", n_points, 8);
  c.at_least("fast_cell_px", fast_cell_px, 8);
  c.at_least("fast_threshold", fast_threshold, 1);
  c.at_least("fast_min_threshold", fast_min_threshold, 1);
  c.at_least("border_px", border_px, 0);
  c.at_least("lk_window", lk_window, 3);
  c.at_least("lk_levels", lk_levels, 0);
  c.non_negative("lk_forward_backward_max", lk_forward_backward_max, "no backward check");
  c.positive("f_ransac_threshold_px", f_ransac_threshold_px);
  c.between("f_ransac_confidence", f_ransac_confidence, 0, 1, false);
  c.at_least("f_ransac_iterations", f_ransac_iterations, 1);
  if (min_points < 8) c.fail("min_points", min_points, ">= 8 (the 8-point algorithm)");
  c.non_negative("alpha_epi", alpha_epi, "no fixed part in eq. 3");
  c.non_negative("beta_epi", beta_epi, "no disparity part in eq. 3");
  c.at_least("disparity_patch_radius", disparity_patch_radius, 0);
  c.positive("rigid_threshold_px", rigid_threshold_px);
  c.positive("rigid_gate_px", rigid_gate_px);
  c.non_negative("rigid_disparity_sigma_px", rigid_disparity_sigma_px, "no disparity error");
  c.at_least("rigid_ransac_iterations", rigid_ransac_iterations, 1);
  c.at_least("rigid_min_agreeing", rigid_min_agreeing, 0);
  c.between("rigid_max_angle_deg", rigid_max_angle_deg, 0, 180, true);
  if (!(rigid_max_ratio >= 1) || std::isinf(rigid_max_ratio))
    c.fail("rigid_max_ratio", rigid_max_ratio, "a finite number >= 1");
  c.non_negative("alpha_s", alpha_s, "no area term in eq. 4");
  c.non_negative("beta_s", beta_s, "no disparity term in eq. 4");
  c.non_negative("t_disp", t_disp, "every disparity difference splits");
  c.at_least("min_cluster_points", min_cluster_points, 1);
  c.non_negative("roi_margin_factor", roi_margin_factor, "the cluster's box alone");
  c.at_least("slic_k", slic_k, 1);
  c.positive("slic_nc", slic_nc);
  c.at_least("slic_max_iterations", slic_max_iterations, 1);
  c.positive("plane_inlier_px", plane_inlier_px);
  c.at_least("plane_ransac_iterations", plane_ransac_iterations, 1);
  c.at_least("plane_min_pixels", plane_min_pixels, 3);
  c.at_least("plane_max_samples", plane_max_samples, 3);
  c.positive("lambda_hinge", lambda_hinge);
  c.finite("lambda_occ", lambda_occ, "a finite number");
  if (!(lambda_occ > lambda_hinge))
    c.fail("lambda_occ", lambda_occ, "> lambda_hinge (" + std::to_string(lambda_hinge) + "; eq. 11)");
  c.non_negative("lambda_pen", lambda_pen, "no penalty");
  c.at_least("min_hit_directions", min_hit_directions, 0);
  if (min_hit_directions > 4) c.fail("min_hit_directions", min_hit_directions, "in [0, 4]");
  c.non_negative("foreground_margin_px", foreground_margin_px, "the object's own disparity");
  c.at_least("foreground_band_px", foreground_band_px, 0);
  c.at_least("keep_frames", keep_frames, 0);
  c.between("keep_covered_fraction", keep_covered_fraction, 0, 1, true);
  c.at_least("keep_min_hits", keep_min_hits, 1);
}

}  // namespace dynaorb::dynamic
