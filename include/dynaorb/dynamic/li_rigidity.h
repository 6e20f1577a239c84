#pragma once
// Ours, added to Li et al.'s step 2 (LiOptions::rigid_check): the LK pairs
// judged against the camera's motion in 3-D, with the previous frame's SGBM
// depth. Eq. 2-3 only see motion across the epipolar lines; an object
// travelling parallel to the camera's translation (a vehicle driving beside
// a forward-moving camera) keeps its points on them, yet its points do not
// land where the camera's motion puts their previous 3-D positions.
//
// The camera's motion T_cur_prev comes from PnP RANSAC (EPnP, then
// Levenberg-Marquardt on the inliers) on the pairs with a previous depth:
// those within rigid_gate_px of where SLAM's constant-velocity prediction
// puts them when there is one (so that a large rigid mover cannot win the
// consensus, as a crossing person can win eq. 2-3's F), else those eq. 3
// left static (also when the prediction explains fewer than min_points
// pairs). A pair whose reprojection error under that motion exceeds
// rigid_threshold_px becomes dynamic (eq. 3's dynamic ones stay dynamic).
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "dynaorb/dynamic/li_epipolar.h"
#include "dynaorb/dynamic/li_options.h"
#include "dynaorb/map/calibration.h"

namespace dynaorb::dynamic {

struct LiRigidityResult {
  bool has_motion = false;
  Eigen::Isometry3d T_cur_prev = Eigen::Isometry3d::Identity();
  bool used_prior = false;  // the candidates were gated by the prediction
  int candidates = 0;       // pairs the PnP ran on
  int inliers = 0;
  int judged = 0;           // pairs with a previous depth that were checked
  int over_threshold = 0;   // pairs eq. 3 left static whose residual exceeds their threshold
  int added = 0;            // of those, made dynamic (enough agreeing neighbours)
  std::string failure;      // "" or "no_previous_depth" / "too_few_points" / "pnp_failed"
};

// Sets LiTrack::rigid_residual of every pair eq. 3 judged that has a
// previous depth (prev_depth: CV_32FC1 metres, 0 = none) and ORs the
// residual test into LiTrack::dynamic. prior_T_cur_prev: SLAM's prediction
// of the motion, if any. Never throws: a failed estimate changes nothing.
LiRigidityResult li_rigidity_check(LiEpipolarResult& epipolar, const cv::Mat& prev_depth,
                                   const map::Calibration& calib,
                                   const std::optional<Eigen::Isometry3d>& prior_T_cur_prev,
                                   const LiOptions& o);

}  // namespace dynaorb::dynamic
