#pragma once
// Plain data for the least-squares problems (Ceres). Poses are T_cw
// (world -> camera), as in ORB-SLAM; observations carry the pixel, the
// virtual right coordinate for stereo / RGB-D (u_right < 0: monocular) and
// the inverse variance of the keypoint's pyramid level.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace dynaorb::optimize {

struct Intrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double bf = 0;  // baseline * fx; 0 for monocular
};

struct Observation {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();
  double u_right = -1;     // < 0: monocular observation
  double inv_sigma2 = 1;   // 1 / (scale_factor^level)^2
  bool stereo() const { return u_right >= 0; }
  // Finite pixel, positive finite information and a finite right coordinate
  // when stereo. The optimisers leave any other observation out as an outlier:
  // one NaN residual makes Ceres refuse every step of its problem.
  bool usable() const {
    return std::isfinite(uv.x()) && std::isfinite(uv.y()) && std::isfinite(inv_sigma2) && inv_sigma2 > 0 &&
           (u_right < 0 || std::isfinite(u_right));
  }
};

// chi2 thresholds at 95 % for 2 and 3 degrees of freedom.
constexpr double kChi2Mono = 5.991;
constexpr double kChi2Stereo = 7.815;

}  // namespace dynaorb::optimize
