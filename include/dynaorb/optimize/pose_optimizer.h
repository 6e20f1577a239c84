#pragma once
// Motion-only bundle adjustment (ORB-SLAM2's PoseOptimization): the camera
// pose from 3-D points fixed in the world and their observations, Huber loss,
// several rounds that classify observations as inliers / outliers by their
// chi2 and optimise again on the inliers only. Observations that are not
// usable() or whose point is not finite are outliers from the start.
#include <vector>

#include "dynaorb/optimize/types.h"

namespace dynaorb::optimize {

struct PoseObservation {
  Eigen::Vector3d point_world = Eigen::Vector3d::Zero();
  Observation obs;
};

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations_per_round = 10;
  double chi2_mono = kChi2Mono;
  double chi2_stereo = kChi2Stereo;
  // Huber threshold of the last round, in standard deviations (the residual
  // in pixels times sqrt(inv_sigma2)). 0: the last round is plain least
  // squares on the inliers, as ORB-SLAM2's. The rounds before it use the
  // chi2 thresholds above as Huber's, as ORB-SLAM2 does.
  double final_huber = 0;
};

struct PoseOptimizerResult {
  Eigen::Isometry3d T_cw = Eigen::Isometry3d::Identity();
  std::vector<bool> inlier;  // per observation, after the last round
  int inliers = 0;
};

PoseOptimizerResult optimize_pose(const Intrinsics& K, const Eigen::Isometry3d& T_cw_init,
                                  const std::vector<PoseObservation>& observations,
                                  const PoseOptimizerOptions& options = {});

}  // namespace dynaorb::optimize
