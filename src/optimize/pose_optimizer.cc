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
// robust_in_round); for other round counts only the last round runs without Huber. With
// options.final_huber > 0 the last round keeps a Huber kernel of that many standard deviations
// (TrackerOptions::pose_final_huber holds why tracking sets one).
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
// Cost: each round is one Ceres problem with one residual block that holds every active
// observation (PoseRoundCost below), on a plain 6-vector: the left-perturbation delta [w, v] from
// the round's start pose, applied after the solve by PoseManifold::Plus (reprojection_cost.h).
// Analytic Jacobians; the normal equations are 6x6, solved by dense Cholesky. The earlier
// formulation, a residual block per observation with ceres::HuberLoss on a 7-double pose block
// with PoseManifold (as bundle adjustment has; the gtest PoseOptimizer.SameAnswerAsPer-
// ObservationHuberBlocks keeps it as the reference), spent several times the reprojection
// arithmetic in Ceres' per-block bookkeeping (invalidating and validating every block's
// buffers, the loss corrector, the lifted Jacobian's product with the manifold's). Tracking
// stage median per run, two pose optimisations a frame, `dynaorb bench --suite seeds --sensors
// stereo,mono --conditions static,masks --seeds 12 --jobs 2` (24 runs per sensor): stereo
// 5.43 -> 2.66 ms, monocular 5.43 -> 3.06 ms, the same ATE on every run to 0.05 mm.
//
// Huber per observation inside the one block: Ceres applies a LossFunction to a residual block's
// whole squared norm, so the cost robustifies each observation's residual r itself, to
// r' = sqrt(rho(s) / s) * r with s = |r|^2, whose squared norm is exactly Huber's rho(s): the
// same cost Ceres' HuberLoss gives, with the exact Jacobian of r'. (Ceres' own corrector keeps
// the cost rho(s) but steps with sqrt(rho'(s)) * r and a Jacobian scaled alike, so the LM steps
// of the two differ a little in the Huber region; the minimum is the same.)
#include "dynaorb/optimize/pose_optimizer.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>

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

// Replaces the weighted residual r (N rows) of one observation and, if J is given, its N x 6
// row-major Jacobian by those of r' = sqrt(rho(s) / s) * r, s = |r|^2, rho Huber's with
// threshold delta2 (Ceres' HuberLoss(sqrt(delta2))): |r'|^2 = rho(s). Inside the threshold
// r' = r. Outside, with w = sqrt(rho / s): dr'/dp = w J + 2 (dw/ds) r (r^T J), where
// dw/ds = (rho'(s) s - rho) / (2 w s^2) and rho'(s) s - rho = delta2 - sqrt(delta2 s).
template <int N>
void robustify(double delta2, double* r, double* J) {
  double s = 0;
  for (int i = 0; i < N; ++i) s += r[i] * r[i];
  if (!(s > delta2)) return;
  const double rho = detail::huber(s, delta2);
  const double root = 0.5 * (rho + delta2);  // sqrt(delta2 s)
  const double w = std::sqrt(rho / s);
  if (J) {
    const double c = (delta2 - root) / (w * s * s);  // 2 dw/ds
    double g[6] = {0, 0, 0, 0, 0, 0};               // r^T J
    for (int i = 0; i < N; ++i)
      for (int k = 0; k < 6; ++k) g[k] += r[i] * J[6 * i + k];
    for (int i = 0; i < N; ++i)
      for (int k = 0; k < 6; ++k) J[6 * i + k] = w * J[6 * i + k] + c * r[i] * g[k];
  }
  for (int i = 0; i < N; ++i) r[i] *= w;
}

// SO(3)'s left Jacobian J_l(w): Exp(w + dw) = Exp(J_l(w) dw) Exp(w) to first order.
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& w) {
  const double theta2 = w.squaredNorm();
  Eigen::Matrix3d W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  double a, b;  // (1 - cos t) / t^2, (t - sin t) / t^3
  if (theta2 < 1e-8) {
    a = 0.5 - theta2 / 24.0;
    b = 1.0 / 6.0 - theta2 / 120.0;
  } else {
    const double theta = std::sqrt(theta2);
    a = (1.0 - std::cos(theta)) / theta2;
    b = (theta - std::sin(theta)) / (theta2 * theta);
  }
  return Eigen::Matrix3d::Identity() + a * W + b * W * W;
}

// One round's problem: the active observations as one residual block (rows 2 per mono and 3
// per stereo observation, in the order of `active`), Huber-robustified per observation when
// `robust` (see the file comment), on a plain 6-vector delta = [w, v] that moves the round's
// start pose T0 = (R0, t0) to R = Exp(w) R0, t = Exp(w) t0 + v (PoseManifold::Plus(T0, delta)).
// So Xc = Exp(w) Y + v with Y = R0 Xw + t0, fixed for the round, and
// dXc/dw = -[Exp(w) Y]x J_l(w), dXc/dv = I.
class PoseRoundCost final : public ceres::CostFunction {
 public:
  // Huber on every observation with threshold delta2_mono / delta2_stereo (squared standard
  // deviations) when both are > 0; plain least squares otherwise.
  PoseRoundCost(const Intrinsics& K, const std::vector<PoseObservation>& observations,
                const std::vector<int>& active, double delta2_mono, double delta2_stereo,
                const double* pose0)
      : K_(K), robust_(delta2_mono > 0 && delta2_stereo > 0), delta2_mono_(delta2_mono), delta2_stereo_(delta2_stereo) {
    const Eigen::Matrix3d R0 = Eigen::Map<const Eigen::Quaterniond>(pose0).toRotationMatrix();
    const Eigen::Vector3d t0(pose0[4], pose0[5], pose0[6]);
    items_.reserve(active.size());
    int rows = 0;
    for (int i : active) {
      const PoseObservation& o = observations[i];
      items_.push_back({R0 * o.point_world + t0, &o.obs, std::sqrt(o.obs.inv_sigma2)});
      rows += o.obs.stereo() ? 3 : 2;
    }
    set_num_residuals(rows);
    mutable_parameter_block_sizes()->push_back(6);
  }

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const Eigen::Vector3d w(params[0][0], params[0][1], params[0][2]);
    const Eigen::Vector3d v(params[0][3], params[0][4], params[0][5]);
    const Eigen::Matrix3d R = detail::so3_exp(w).toRotationMatrix();
    double* J = jacobians && jacobians[0] ? jacobians[0] : nullptr;
    const Eigen::Matrix3d Jl = J ? so3_left_jacobian(w) : Eigen::Matrix3d::Identity();
    int row = 0;
    for (const Item& it : items_) {
      const Eigen::Vector3d X = R * it.Y;  // Exp(w) Y
      double* r = residuals + row;
      double* Ji = J ? J + 6 * row : nullptr;
      if (it.obs->stereo()) {
        evaluate<3>(it, X, v, Jl, r, Ji, delta2_stereo_);
        row += 3;
      } else {
        evaluate<2>(it, X, v, Jl, r, Ji, delta2_mono_);
        row += 2;
      }
    }
    return true;
  }

 private:
  struct Item {
    Eigen::Vector3d Y;  // R0 Xw + t0
    const Observation* obs;
    double s;  // sqrt(inv_sigma2)
  };

  template <int N>
  void evaluate(const Item& it, const Eigen::Vector3d& X, const Eigen::Vector3d& v,
                const Eigen::Matrix3d& Jl, double* r, double* J, double delta2) const {
    const Eigen::Vector3d Xc = X + v;
    if (J) {
      Eigen::Matrix<double, N, 3> dr_dXc;
      detail::reprojection_residual<N>(K_, *it.obs, it.s, Xc, r, &dr_dXc);
      for (int i = 0; i < N; ++i) {
        double* jrow = J + 6 * i;
        double rot[3];  // dr_dXc.row(i) * -[X]x
        detail::rotation_jacobian_row<N>(dr_dXc, i, X, rot);
        for (int k = 0; k < 3; ++k)
          jrow[k] = rot[0] * Jl(0, k) + rot[1] * Jl(1, k) + rot[2] * Jl(2, k);
        jrow[3] = dr_dXc(i, 0);
        jrow[4] = dr_dXc(i, 1);
        jrow[5] = dr_dXc(i, 2);
      }
    } else {
      detail::reprojection_residual<N>(K_, *it.obs, it.s, Xc, r, nullptr);
    }
    if (robust_) robustify<N>(delta2, r, J);
  }

  const Intrinsics K_;
  std::vector<Item> items_;
  const bool robust_;
  const double delta2_mono_, delta2_stereo_;
};

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

  const detail::PoseManifold manifold;  // moves a round's start pose by its solved delta

  const ceres::Solver::Options solver_options =
      pose_solver_options(std::max(1, options.iterations_per_round));

  // The first round leaves out the points behind the initial pose (outliers whatever the
  // solver does; projected at kMinDepth their residual would outweigh all the others). Non-
  // finite observations and points are outliers in every round: in the round's one residual
  // block a single NaN makes Ceres refuse every step, and the classification at the unmoved
  // pose would then drop the frame's good observations too.
  std::vector<bool> usable(n), outlier(n);
  for (size_t i = 0; i < n; ++i) {
    usable[i] = observations[i].obs.usable() && observations[i].point_world.allFinite();
    outlier[i] = !usable[i] || !(detail::transform_point(pose, observations[i].point_world).z() > 0);
  }
  bool classified = false;
  std::vector<int> active;
  active.reserve(n);
  for (int round = 0; round < options.rounds; ++round) {
    active.clear();
    for (size_t i = 0; i < n; ++i)
      if (!outlier[i]) active.push_back(static_cast<int>(i));
    if (active.size() < 3) break;  // keep the previous estimate and classification
    double delta[6] = {0, 0, 0, 0, 0, 0};
    ceres::Problem problem;
    double delta2_mono = options.chi2_mono, delta2_stereo = options.chi2_stereo;
    if (!robust_in_round(round, options.rounds))
      delta2_mono = delta2_stereo = options.final_huber * options.final_huber;  // 0: plain least squares
    problem.AddResidualBlock(new PoseRoundCost(K, observations, active, delta2_mono, delta2_stereo, pose),
                             nullptr, delta);

    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    double moved[7];
    manifold.Plus(pose, delta, moved);
    std::copy(moved, moved + 7, pose);

    // Classify every observation (inliers and outliers) at the new estimate.
    for (size_t i = 0; i < n; ++i) {
      const Observation& obs = observations[i].obs;
      const Eigen::Vector3d Xc = detail::transform_point(pose, observations[i].point_world);
      const double chi2 = detail::observation_chi2(K, obs, Xc);
      const double threshold = obs.stereo() ? options.chi2_stereo : options.chi2_mono;
      outlier[i] = !usable[i] || !(chi2 <= threshold) || Xc.z() <= 0;  // NaN-safe
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
