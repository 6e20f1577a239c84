// Motion-only bundle adjustment, following ORB-SLAM2's PoseOptimization (Mur-Artal & Tardos,
// T-RO 2017, Sec. V-B / VI): the 3-D points are fixed; the camera pose minimises the robust sum
// of reprojection errors over several rounds. After every round each observation is classified
// at the current estimate by its chi2 (information inv_sigma2 * I, no robust kernel):
// chi2 > threshold (95 % for 2 / 3 DoF) -> outlier, excluded from the next round's problem;
// otherwise inlier. Outliers are re-classified every round, so a match rejected early under a
// bad estimate can come back.
//
// Robust kernel: ORB-SLAM2 drops the Huber kernel in the classification loop that follows the
// optimisation of round index 2, so with its 4 rounds Huber is used in rounds 0, 1, 2 and the
// final round 3 is plain least squares on the inliers. We follow that code (see
// robust_in_round); for other round counts only the last round runs without Huber.
//
// Differences from ORB-SLAM2, on purpose:
//  - each round continues from the previous round's estimate (ORB-SLAM2 restarts every round
//    from the frame's initial pose); with 10 LM iterations per round this gives at least the
//    same result and is never worse when the initial pose is far off;
//  - an observation whose point lies at depth <= 0 in the camera is also an outlier, and
//    the first round leaves out those at depth <= 0 in the initial pose (ORB-SLAM2's g2o
//    edges project them mirrored through the camera plane; here they would be projected at
//    kMinDepth, with a residual that outweighs every other);
//  - a round with fewer than 3 active observations is not solved: the previous estimate and its
//    classification are kept.
//
// Cost: one 7-double pose block with the left-perturbation PoseManifold and analytic Jacobians
// (reprojection_cost.h). The cost functions are built once and shared, unowned, by the per-round
// problems; the normal equations are 6x6, solved by dense Cholesky.
#include "dynaorb/optimize/pose_optimizer.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "reprojection_cost.h"

namespace dynaorb::optimize {

namespace {

// Huber in round `round` of `rounds` (see the file comment).
bool robust_in_round(int round, int rounds) {
  if (rounds <= 1) return true;
  return round <= std::min(2, rounds - 2);
}

ceres::Solver::Options pose_solver_options(int iterations) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;  // 6 unknowns: J^T J is 6x6
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.max_num_iterations = iterations;
  o.num_threads = 1;
  o.minimizer_progress_to_stdout = false;
  o.logging_type = ceres::SILENT;
  // The ~1e-6 relative defaults stop a converged round early; keep them.
  return o;
}

}  // namespace

PoseOptimizerResult optimize_pose(const Intrinsics& K, const Eigen::Isometry3d& T_cw_init,
                                  const std::vector<PoseObservation>& observations,
                                  const PoseOptimizerOptions& options) {
  const size_t n = observations.size();
  PoseOptimizerResult result;
  result.T_cw = T_cw_init;
  result.inlier.assign(n, false);
  result.inliers = 0;
  if (n < 3 || options.rounds <= 0) return result;

  double pose[7];
  detail::pose_to_params(T_cw_init, pose);

  // Cost functions, loss functions and the manifold live here and are shared by every round's
  // problem (which owns none of them).
  std::vector<std::unique_ptr<ceres::CostFunction>> costs(n);
  for (size_t i = 0; i < n; ++i) {
    const PoseObservation& o = observations[i];
    if (o.obs.stereo())
      costs[i] = std::make_unique<detail::PoseOnlyCost<3>>(K, o.point_world, o.obs);
    else
      costs[i] = std::make_unique<detail::PoseOnlyCost<2>>(K, o.point_world, o.obs);
  }
  ceres::HuberLoss huber_mono(std::sqrt(options.chi2_mono));
  ceres::HuberLoss huber_stereo(std::sqrt(options.chi2_stereo));
  detail::PoseManifold manifold;

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  const ceres::Solver::Options solver_options =
      pose_solver_options(std::max(1, options.iterations_per_round));

  // The first round leaves out the points behind the initial pose (outliers whatever the
  // solver does; projected at kMinDepth their residual would outweigh all the others).
  std::vector<bool> outlier(n, false);
  for (size_t i = 0; i < n; ++i)
    outlier[i] = !(detail::transform_point(pose, observations[i].point_world).z() > 0);
  bool classified = false;
  for (int round = 0; round < options.rounds; ++round) {
    const bool robust = robust_in_round(round, options.rounds);
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(pose, 7, &manifold);
    int active = 0;
    for (size_t i = 0; i < n; ++i) {
      if (outlier[i]) continue;
      ceres::LossFunction* loss = nullptr;
      if (robust) loss = observations[i].obs.stereo() ? &huber_stereo : &huber_mono;
      problem.AddResidualBlock(costs[i].get(), loss, pose);
      ++active;
    }
    if (active < 3) break;  // keep the previous estimate and classification

    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);

    // Classify every observation (inliers and outliers) at the new estimate.
    for (size_t i = 0; i < n; ++i) {
      const Observation& obs = observations[i].obs;
      const Eigen::Vector3d Xc = detail::transform_point(pose, observations[i].point_world);
      const double chi2 = detail::observation_chi2(K, obs, Xc);
      const double threshold = obs.stereo() ? options.chi2_stereo : options.chi2_mono;
      outlier[i] = !(chi2 <= threshold) || Xc.z() <= 0;  // NaN-safe
    }
    classified = true;
  }

  result.T_cw = detail::params_to_pose(pose);
  if (!classified) return result;
  for (size_t i = 0; i < n; ++i) {
    result.inlier[i] = !outlier[i];
    if (result.inlier[i]) ++result.inliers;
  }
  return result;
}

}  // namespace dynaorb::optimize
