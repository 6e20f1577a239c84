#pragma once
// Camera pose from 2-D / 3-D matches with RANSAC: the geometric check of a
// relocalisation candidate (ORB-SLAM Sec. V-C; ORB-SLAM2's PnPsolver).
// Minimal sets of 4 matches are solved by OpenCV's EPnP; a match is an inlier
// when its reprojection error passes the chi2 test at its keypoint's pyramid-
// level sigma (5.991: 2 dof, 95 %). OpenCV's solvePnPRansac takes one pixel
// threshold for every match, so the loop is ours and only the solver is
// OpenCV's. The best hypothesis is refined by EPnP on all its inliers.
#include <Eigen/Geometry>
#include <vector>

namespace dynaorb::place {

struct PnpRansacOptions {
  double probability = 0.99;  // stop once an all-inlier minimal set was drawn with this probability
  int min_inliers = 10;       // a pose needs at least this many (ORB-SLAM2: 10)
  int max_iterations = 300;   // ORB-SLAM2: 300
  double chi2 = 5.991;        // reprojection test, times the keypoint's level sigma^2
  unsigned seed = 0;          // sampling is deterministic for a given seed
};

// Its fields by name (dynaorb/core/option_fields.h).
template <class F>
void option_fields(const PnpRansacOptions*, F&& f) {
  f("probability", &PnpRansacOptions::probability);
  f("min_inliers", &PnpRansacOptions::min_inliers);
  f("max_iterations", &PnpRansacOptions::max_iterations);
  f("chi2", &PnpRansacOptions::chi2);
  f("seed", &PnpRansacOptions::seed);
}

struct PnpMatch {
  Eigen::Vector3d point_world;
  Eigen::Vector2d pixel;  // undistorted
  double sigma2 = 1;      // keypoint level sigma^2 (scale_factor^(2 level))
};

struct PnpRansacResult {
  bool ok = false;  // a pose with >= min_inliers inliers
  Eigen::Isometry3d T_cw = Eigen::Isometry3d::Identity();
  std::vector<bool> inlier;  // per match
  int inliers = 0;
  int iterations = 0;
};

struct PinholeK {
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

PnpRansacResult pnp_ransac(const std::vector<PnpMatch>& matches, const PinholeK& K,
                           const PnpRansacOptions& options = {});

}  // namespace dynaorb::place
