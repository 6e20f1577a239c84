#pragma once
// Options of Li et al.'s network-free stereo dynamic-region detection
// (G. Li, X. Liao, H. Huang, S. Song, B. Liu, Y. Zeng, "Robust Stereo Visual
// SLAM for Dynamic Environments With Moving Object", IEEE Access 9, 2021;
// /work/shared/papers/li2021-robust-stereo-dynamic.txt).
//
// The paper names its constants (alpha_epi, beta_epi, alpha_s, beta_s, T_disp,
// lambda_occ, lambda_hinge, lambda_pen, K, N ...) but prints none of their
// values, and no code was released. Each default below says where it comes
// from: the paper when it gives a value, the work the paper builds on when
// that work has one, else our choice with the reason. Pixel and disparity
// values are in pixels of the full-resolution tracked image.
#include <opencv2/core.hpp>

namespace dynaorb::dynamic {

struct LiOptions {
  // --- SGBM disparity (Sec. III, Hirschmueller [24], cv::StereoSGBM). The
  // paper gives no SGBM parameters; ours are OpenCV's documented ones.
  // Ours: SGBM runs on the pair scaled by this factor (0.5: a quarter of the
  // pixels, ~5x faster) and the disparity is scaled back to full-resolution
  // pixels; 1 = the paper's full-resolution SGBM. Measured on three synthetic
  // sequences (640x480): keypoint precision / recall 0.703 / 0.673 at 0.5 vs
  // 0.709 / 0.683 at 1, SGBM 6 ms vs 32 ms of single-thread CPU; against the
  // rendered truth of the test scene, mean |error| 0.47 px vs 0.29 px.
  double sgbm_scale = 0.5;
  int sgbm_num_disparities = 64;    // full-resolution px (rounded up to 16 at the scale)
  int sgbm_block_size = 5;          // px at the scale, odd
  double sgbm_p1_per_pixel = 8;     // P1 = 8 * block^2 (OpenCV's recommendation, grey input)
  double sgbm_p2_per_pixel = 32;    // P2 = 32 * block^2
  int sgbm_uniqueness_ratio = 10;   // % (OpenCV sample: 5-15)
  int sgbm_speckle_window = 100;    // px (OpenCV sample: 50-200)
  int sgbm_speckle_range = 2;       // disparity levels (OpenCV sample: 1-2)
  int sgbm_disp12_max_diff = 1;     // left-right check, px
  bool sgbm_three_way = true;       // MODE_SGBM_3WAY (same cost function, 1.4x faster than MODE_SGBM)

  // --- Quadtree-distributed FAST on the previous left image (Sec. III-A,
  // steps 1-4; the ORB-SLAM distribution the paper describes).
  int n_points = 500;               // N, the wanted number of points (paper: "N", no value)
  int fast_cell_px = 30;            // the "square regions" of step 1 (ORB-SLAM's 30 px cells)
  int fast_threshold = 20;          // ORB-SLAM's iniThFAST
  int fast_min_threshold = 7;       // ORB-SLAM's minThFAST, retried in a cell that found nothing
  int border_px = 16;               // corners and tracks this close to the edge are dropped (ours)
  // --- Lucas-Kanade [28] (no parameters in the paper; OpenCV's defaults).
  int lk_window = 21;
  int lk_levels = 3;
  // Ours, off by default as in the paper: track the current point back and
  // drop the pair when it lands further than this (px) from where it started.
  // Measured on three synthetic sequences (before the rigidity check) it
  // removes mis-tracks but also points on the movers, and lowers the persons'
  // recall (0.79 -> 0.73) at 1 px. The li preset sets 3 px: on KITTI 06 a
  // quarter of the pairs are mis-tracks that eq. 3 would mark (config/dynamic/li.yaml).
  double lk_forward_backward_max = 0.0;

  // --- Fundamental matrix, "9-point algorithm ... refined by RANSAC" (Sec.
  // III-A; OpenCV's FM_RANSAC: 7-point samples, 8-point refit on the inliers).
  // No value in the paper. 0.1 px is DS-SLAM's released value for the same
  // LK + RANSAC-F step. A wide band lets a large mover's coherent flow win the
  // consensus: with a forward-moving camera the static flow is small, so a
  // 1 px band also holds most static points and the F of a crossing person
  // (epipole far to the side) out-votes the true one (measured on a
  // synthetic sequence, dynaorb synth --movers 3 --seed 0: the persons'
  // points judged dynamic 85 % at 0.1 px, 46 % at 0.3, 25 % at 0.5, 13 % at 1).
  double f_ransac_threshold_px = 0.1;
  double f_ransac_confidence = 0.99;
  int f_ransac_iterations = 1000;     // OpenCV's default cap
  int min_points = 15;                // fewer tracked pairs: no F, nothing marked (ours)
  // Ours, off as in the paper: F is fitted to the pairs that start outside
  // the previous frame's dynamic mask (what the filter marked there), when
  // at least min_points of them are left; every pair is still judged by it.
  // Movers filling a third of the image otherwise pull the 0.1 px consensus
  // their way in some frames, and the far static points, whose eq. 3
  // threshold is the tightest, are marked by the dozen (`dynaorb synth
  // --movers 3 --seed 1`, one frame: 69 of 120 far pairs, whose cluster made
  // a rectangle over the static background).
  bool f_exclude_previous_dynamic = false;

  // --- Eq. 3: T_epi = alpha_epi + beta_epi * d (px). Ours: 1 px of tracking
  // noise at any depth plus 2 % of the disparity (near points move more
  // between frames, so their track error grows with d).
  double alpha_epi = 1.0;
  double beta_epi = 0.02;
  // A point whose pixel has no SGBM disparity takes the median of the valid
  // disparities within this radius (ours); none there: the point is not judged.
  int disparity_patch_radius = 2;

  // Ours, off as in the paper (li_rigidity.h): also judge each LK pair by its
  // reprojection error under the camera's motion from PnP on the previous
  // frame's SGBM depth, so that an object travelling along its epipolar
  // lines (which eq. 2-3 cannot see) is found. The PnP (EPnP RANSAC,
  // rigid_ransac_iterations, inliers within rigid_threshold_px) runs on the
  // pairs within rigid_gate_px of SLAM's constant-velocity prediction (else
  // on those eq. 3 left static). A pair is over its threshold when its
  // residual exceeds rigid_threshold_px plus how far its reprojection moves
  // for a disparity error of rigid_disparity_sigma_px; it becomes dynamic
  // when at least rigid_min_agreeing others over theirs, near it by eq. 4's
  // relation, are off within rigid_max_angle_deg of its direction and by
  // at most rigid_max_ratio times (or 1 / that) its length.
  // Values measured on stereo seeds 0-11 (`dynaorb bench --suite seeds
  // --sensors stereo --conditions static,full --preset FILE`) and KITTI 06;
  // see config/dynamic/li.yaml for what the check gains and costs.
  bool rigid_check = false;
  double rigid_threshold_px = 1.0;
  double rigid_disparity_sigma_px = 2.0;
  double rigid_gate_px = 3.0;
  int rigid_ransac_iterations = 100;
  int rigid_min_agreeing = 2;
  double rigid_max_angle_deg = 30.0;
  double rigid_max_ratio = 2.0;

  // --- Eq. 4: two dynamic points are one object when their distance is at most
  // T_s = alpha_s + beta_s * d (d: the pair's mean disparity) and their
  // disparities differ by at most T_disp. Ours: 30 px (the spacing of N = 500
  // spread points on 640x480 is ~25 px) plus 1 px per pixel of disparity.
  double alpha_s = 30.0;
  double beta_s = 1.0;
  double t_disp = 3.0;
  // Paper: "an object is considered to be moving when there are more than four
  // dynamic features on the object".
  int min_cluster_points = 5;
  // Ours: the ROI is the points' bounding box grown by this factor times T_s
  // of the cluster's mean disparity, so that the object's outline (which lies
  // beyond its outermost tracked points) is inside the segmented area.
  double roi_margin_factor = 1.0;

  // --- Improved SLIC (eq. 5-7) on the ROIs, on the grey image (C = [gray]).
  // K of eq. 6 for the whole image: S_step = sqrt(W * H / K); the ROIs use the
  // same S_step, so superpixels do not grow with the ROI. Ours: ~17 px at 640x480.
  int slic_k = 1000;
  // N_c of eq. 5. The paper: "determined from the image" without saying how;
  // SLIC [29] Sec. 3.1 fixes it to a constant m. Ours: 20 grey levels (m = 10
  // of Lab L in [0, 100] is ~25 grey levels).
  double slic_nc = 20.0;
  // Paper: "repeated until convergence (typically 10 repetitions)". On a
  // finely textured object the unstable pixels keep flipping and never settle;
  // ours: 3 passes. Measured on three synthetic sequences: keypoint precision
  // / recall 0.703 / 0.673 after 3 passes vs 0.698 / 0.673 after 10, SLIC
  // 5.6 ms vs 27 ms.
  int slic_max_iterations = 3;

  // Ours: SGBM leaves no disparity in the half-occluded band beside every
  // foreground edge (background the right camera cannot see), so the
  // superpixels there get no plane and the occlusion boundary would go
  // unlabelled. As Yamaguchi et al.'s SPS-Stereo does before its plane fits
  // (the energy of eq. 9-11 is theirs), each run of pixels without disparity
  // along a row takes the smaller of the disparities at its two ends (the
  // background's). Used for the planes only; the depth output keeps 0 there.
  bool fill_occlusions = true;

  // --- Disparity plane per superpixel (eq. 8), RANSAC then least squares on
  // the inliers. Ours: no values in the paper.
  double plane_inlier_px = 1.0;     // |d - d_hat| of an inlier, full-resolution px
  int plane_ransac_iterations = 100;  // cap; stops early at 99 % confidence
  int plane_min_pixels = 12;        // fewer pixels with disparity: no plane, its boundaries unlabelled
  int plane_max_samples = 200;      // RANSAC scores on at most this many of the pixels (speed)

  // --- Boundary energy (eq. 9-11). The paper requires lambda_occ >
  // lambda_hinge > 0 and gives no values; its energy is Yamaguchi et al.'s
  // (SPS-Stereo, ECCV 2014), whose released defaults (squared disparity px)
  // we take: hinge 5, occlusion 15, impossible (lambda_pen) 30.
  double lambda_occ = 15.0;
  double lambda_hinge = 5.0;
  double lambda_pen = 30.0;

  // --- Dynamic rectangles (Sec. III-B, last paragraph). Ours: "surrounded by
  // boundaries labeled as occlusion" read as occlusion boundaries found in at
  // least this many of the four search directions over the cluster's points;
  // fewer: the cluster is a false alarm (the paper's Fig. 7/8 discussion).
  int min_hit_directions = 2;
  // Ours, off as in the paper (which marks the whole rectangle): mark only
  // the rectangle's pixels that are at least as near as its object, those
  // whose SGBM disparity is at least the smallest disparity of the cluster's
  // dynamic points less foreground_margin_px (pixels without a disparity
  // count as near), and those within foreground_band_px of them (the edge
  // the SGBM disparity blurs, and the corners right at the outline). The
  // background the rectangle encloses, behind the mover and beside it, then
  // keeps its features. A kept rectangle (keep_frames) keeps its object's
  // disparity and is cut by each new frame's disparity.
  // Measured (config/dynamic/li.yaml): seed 0 keypoint precision 0.76 ->
  // 0.90 at 5 px (0.87 at 15 px, an ORB patch's radius; 0.92 with no band);
  // seeds 0-11 li / static median 1.25 at 5 px, 1.34 at 15, 1.43 with none.
  bool foreground_only = false;
  double foreground_margin_px = 2.0;
  int foreground_band_px = 5;

  // Ours, 0 (the paper, which judges every frame on its own): a dynamic
  // rectangle found in keep_min_hits frames stays dynamic for up to this many
  // frames after the last frame that found it, moved each frame by the
  // median flow of the LK tracks that start inside it, until new rectangles
  // cover keep_covered_fraction of it (then they are what is kept). An object
  // travelling parallel to the camera's translation passes eq. 2-3 in some
  // frames and not in others; a moving object does not stop from one frame
  // to the next (the same reasoning as Dynamic.dm.keep_moving_frames_mono).
  int keep_frames = 0;
  // A kept rectangle counts as found anew (and is dropped, the new one kept
  // instead) when this frame's new rectangles cover at least this share of it.
  double keep_covered_fraction = 0.5;
  // Only a rectangle found in at least this many frames is kept: a new
  // rectangle counts the frames of the kept ones it covers or is covered by
  // (keep_covered_fraction either way), plus its own. 1: every rectangle. A
  // false alarm of one frame (a static surface whose flow passed T_epi
  // once) then is not carried.
  int keep_min_hits = 2;

  // Missing keys keep their defaults; keys are the member names. Wrong types
  // and out-of-range values throw InputError naming the key.
  void read(const cv::FileNode& node);
  void validate() const;
};

}  // namespace dynaorb::dynamic
