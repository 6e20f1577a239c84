#pragma once
// Pose-graph optimisation in Sim(3): ORB-SLAM's essential-graph optimisation after a loop
// closure (Mur-Artal et al., T-RO 2015, Sec. VI-D; ORB-SLAM2 Optimizer::OptimizeEssentialGraph),
// after Strasdat et al. (RSS 2010, "Scale drift-aware large scale monocular SLAM"): a monocular
// map drifts in scale, so keyframe poses are similarities S_iw (world -> camera) and the loop
// error is spread over rotation, translation AND scale. Stereo / RGB-D set fix_scale (SE(3)).
//
// Edges (i, j, S_ij) say S_ij ~ S_iw * S_jw^{-1} (frame j -> frame i), measured from the poses
// BEFORE the correction (spanning tree, covisibility, old loops) or from the corrected poses
// (the new loop links). Residual, as g2o's EdgeSim3 in ORB-SLAM2:
//   r_ij = log(S_ij * S_jw * S_iw^{-1}) in sim(3) = [rho, phi, sigma],   cost = 1/2 r^T Info r.
// Solved with Ceres' Levenberg-Marquardt, 20 iterations (ORB-SLAM2), nodes updated on the left,
// S_iw <- exp(delta) * S_iw (delta in sim(3); sigma = 0 with fix_scale). Fixed nodes (the loop
// keyframe / the origin) fix the gauge; nodes without edges are returned unchanged.
#include <vector>

#include <Eigen/Core>

#include "dynaorb/loop/sim3.h"

namespace dynaorb::optimize {

using Sim3 = loop::Sim3;
using Matrix7d = Eigen::Matrix<double, 7, 7>;

struct Sim3Node {
  Sim3 S_iw;           // world -> camera i
  bool fixed = false;
};

struct Sim3Edge {
  int i = 0, j = 0;    // node indices
  Sim3 S_ij;           // measured S_iw * S_jw^{-1}
  Matrix7d information = Matrix7d::Identity();  // ORB-SLAM2: identity; order [rho, phi, sigma]
};

struct PoseGraphProblem {
  std::vector<Sim3Node> nodes;
  std::vector<Sim3Edge> edges;
};

struct PoseGraphOptions {
  int iterations = 20;     // ORB-SLAM2: optimizer.optimize(20)
  bool fix_scale = false;  // stereo / RGB-D: SE(3) graph, every node keeps its scale
  int num_threads = 1;
};

struct PoseGraphResult {
  std::vector<Sim3> S_iw;  // per node; fixed and unconnected nodes unchanged
  double initial_cost = 0, final_cost = 0;  // 1/2 sum r^T Info r
  int iterations = 0;      // LM steps taken (accepted + rejected)
  bool converged = false;  // Ceres stopped on a tolerance rather than the iteration cap
};

// Throws std::invalid_argument on an edge with a bad or repeated (i == j) node index, or an
// information matrix that is not symmetric positive definite.
PoseGraphResult optimize_pose_graph(const PoseGraphProblem& problem,
                                    const PoseGraphOptions& options = {});

// After the correction (ORB-SLAM2): the keyframe's SE(3) pose T_iw = [R | t / s] of the
// corrected similarity S_iw = [sR | t] ...
Eigen::Isometry3d sim3_to_se3(const Sim3& S_iw);

// ... and a map point moved with its reference keyframe i:
//   x_corrected = S_iw_corrected^{-1} * (S_iw_old * x_w)
// (same camera-frame position before the correction, up to the keyframe's new scale).
Eigen::Vector3d correct_point(const Sim3& S_iw_old, const Sim3& S_iw_corrected,
                              const Eigen::Vector3d& x_w);

}  // namespace dynaorb::optimize
