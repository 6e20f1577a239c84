#include "dynaorb/dynamic/li_options.h"

#include <string>

#include "dynaorb/io/errors.h"
#include "file_node_options.h"

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
  read_option(node, "min_points", min_points);
  read_option(node, "alpha_epi", alpha_epi);
  read_option(node, "beta_epi", beta_epi);
  read_option(node, "disparity_patch_radius", disparity_patch_radius);
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
  read_option(node, "keep_frames", keep_frames);
  read_option(node, "keep_covered_fraction", keep_covered_fraction);
  read_option(node, "keep_min_hits", keep_min_hits);
  validate();
}

void LiOptions::validate() const {
  auto fail = [](const std::string& what) { throw InputError("li option " + what); };
  if (!(sgbm_scale > 0 && sgbm_scale <= 1)) fail("'sgbm_scale' must be in (0, 1]");
  if (sgbm_num_disparities < 1) fail("'sgbm_num_disparities' must be >= 1");
  if (sgbm_block_size < 1 || sgbm_block_size % 2 == 0) fail("'sgbm_block_size' must be odd and >= 1");
  if (!(sgbm_p2_per_pixel > sgbm_p1_per_pixel && sgbm_p1_per_pixel >= 0))
    fail("'sgbm_p2_per_pixel' must exceed 'sgbm_p1_per_pixel' >= 0");
  if (n_points < 8) fail("'n_points' must be >= 8");
  if (fast_cell_px < 8) fail("'fast_cell_px' must be >= 8");
  if (fast_threshold < 1 || fast_min_threshold < 1 || border_px < 0)
    fail("'fast_threshold' and 'fast_min_threshold' must be >= 1 and 'border_px' >= 0");
  if (disparity_patch_radius < 0 || roi_margin_factor < 0)
    fail("'disparity_patch_radius' and 'roi_margin_factor' must be >= 0");
  if (lk_window < 3 || lk_levels < 0) fail("'lk_window' must be >= 3 and 'lk_levels' >= 0");
  if (!(f_ransac_threshold_px > 0) || !(f_ransac_confidence > 0 && f_ransac_confidence < 1))
    fail("'f_ransac_threshold_px' must be > 0 and 'f_ransac_confidence' in (0, 1)");
  if (f_ransac_iterations < 1) fail("'f_ransac_iterations' must be >= 1");
  if (min_points < 8) fail("'min_points' must be >= 8 (the 8-point algorithm)");
  if (alpha_epi < 0 || beta_epi < 0) fail("'alpha_epi' and 'beta_epi' must be >= 0");
  if (alpha_s < 0 || beta_s < 0 || t_disp < 0) fail("'alpha_s', 'beta_s', 't_disp' must be >= 0");
  if (min_cluster_points < 1) fail("'min_cluster_points' must be >= 1");
  if (slic_k < 1 || !(slic_nc > 0) || slic_max_iterations < 1)
    fail("'slic_k', 'slic_nc' and 'slic_max_iterations' must be positive");
  if (!(plane_inlier_px > 0) || plane_ransac_iterations < 1 || plane_min_pixels < 3 || plane_max_samples < 3)
    fail("plane options must be positive ('plane_min_pixels', 'plane_max_samples' >= 3)");
  if (!(lambda_occ > lambda_hinge && lambda_hinge > 0) || lambda_pen < 0)
    fail("needs lambda_occ > lambda_hinge > 0 (eq. 11) and lambda_pen >= 0");
  if (min_hit_directions < 0 || min_hit_directions > 4) fail("'min_hit_directions' must be in [0, 4]");
  if (keep_frames < 0 || keep_min_hits < 1) fail("'keep_frames' must be >= 0 and 'keep_min_hits' >= 1");
  if (!(keep_covered_fraction > 0 && keep_covered_fraction <= 1)) fail("'keep_covered_fraction' must be in (0, 1]");
}

}  // namespace dynaorb::dynamic
