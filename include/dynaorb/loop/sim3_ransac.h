#pragma once
// RANSAC for the similarity between two keyframes from matched map points (ORB-SLAM, Mur-Artal
// et al., T-RO 2015, Sec. VI-B "Compute the similarity transformation"; ORB-SLAM2 Sim3Solver):
// hypotheses S12 from minimal sets of 3 matches by Horn's closed form, scored by the
// reprojection error in BOTH images
//   |uv1 - pi(K1, S12 X2)|^2 < chi2 * sigma2_1   and   |uv2 - pi(K2, S21 X1)|^2 < chi2 * sigma2_2,
// and the best one refined by Horn on all its inliers.
//
// Iterations: ceil(log(1 - p) / log(1 - w^3)), capped at max_iterations, with the inlier ratio
// w starting at min_inliers / N (ORB-SLAM's initial guess) and raised to the best hypothesis'
// ratio as it improves (standard adaptive RANSAC). ORB-SLAM2 instead stops at the first
// hypothesis with more than min_inliers inliers and leaves refinement to a nonlinear Sim3
// optimisation; here the full loop runs and the winner is refined by Horn (LO-RANSAC style:
// re-fit on the inliers and re-score while the inlier count does not drop, up to 3 times).
// ORB-SLAM2 compares against the projections of X1 / X2 rather than the keypoints; pass those
// as uv1 / uv2 to get its behaviour.
#include <vector>

#include "dynaorb/loop/sim3.h"

namespace dynaorb::loop {

struct Sim3Match {
  Eigen::Vector3d X1 = Eigen::Vector3d::Zero();  // the point in keyframe 1's camera frame
  Eigen::Vector3d X2 = Eigen::Vector3d::Zero();  // its match in keyframe 2's camera frame
  Eigen::Vector2d uv1 = Eigen::Vector2d::Zero();  // keypoint in image 1 (pixels)
  Eigen::Vector2d uv2 = Eigen::Vector2d::Zero();  // keypoint in image 2
  double sigma2_1 = 1.0;  // (scale_factor^level)^2 of the keypoint in image 1
  double sigma2_2 = 1.0;  // ... in image 2
};

struct Sim3RansacOptions {
  double probability = 0.99;  // ORB-SLAM2 LoopClosing: SetRansacParameters(0.99, 20, 300)
  int min_inliers = 20;
  int max_iterations = 300;
  double chi2 = 9.21;         // 2 dof, 99 %; scaled by sigma2 of the keypoint's level
  bool fix_scale = false;     // true for stereo / RGB-D: SE(3)
  unsigned seed = 0;          // the result is a function of the input and the seed
};

// fix_scale is not a setting: the loop closer sets it from the sensor.
// Its fields by name (dynaorb/core/option_fields.h).
template <class F>
void option_fields(const Sim3RansacOptions*, F&& f) {
  f("probability", &Sim3RansacOptions::probability);
  f("min_inliers", &Sim3RansacOptions::min_inliers);
  f("max_iterations", &Sim3RansacOptions::max_iterations);
  f("chi2", &Sim3RansacOptions::chi2);
  f("seed", &Sim3RansacOptions::seed);
}

struct Sim3RansacResult {
  bool ok = false;            // inliers >= min_inliers
  Sim3 S12;                   // X1 ~ S12 * X2: the best (refined) hypothesis, even if !ok
  std::vector<bool> inlier;   // per match, of S12 (all false if no hypothesis was drawn)
  int inliers = 0;
  int iterations = 0;         // hypotheses drawn
};

// K1, K2: pinhole intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] of the two keyframes.
Sim3RansacResult sim3_ransac(const std::vector<Sim3Match>& matches, const Eigen::Matrix3d& K1,
                             const Eigen::Matrix3d& K2, const Sim3RansacOptions& options = {});

// Inlier flags of S12 under the two-image test above; returns the count.
int sim3_inliers(const std::vector<Sim3Match>& matches, const Eigen::Matrix3d& K1,
                 const Eigen::Matrix3d& K2, const Sim3& S12, double chi2,
                 std::vector<bool>* inlier);

}  // namespace dynaorb::loop
