// Local bundle adjustment, following ORB-SLAM2's LocalBundleAdjustment (Mur-Artal & Tardos,
// T-RO 2017, Sec. VI-D): keyframe poses (some fixed, the gauge) and points are refined jointly
// on their reprojection errors (2-D mono, 3-D stereo, information inv_sigma2 * I):
//   1. iterations_first LM iterations with a Huber kernel (delta^2 = the chi2 threshold) on
//      the observations whose point is in front of the camera at the input (ORB-SLAM2's
//      g2o edges take those behind it into the first pass too, mirrored through the camera
//      plane; here they would be projected at kMinDepth, see Workspace::in_front);
//   2. unless aborted, the observations with chi2 > threshold or whose point lies at depth <= 0
//      are excluded and iterations_second iterations are run on the rest WITHOUT the kernel
//      (none when it is 0: ORB-SLAM3's schedule, one pass of 10, the outliers only flagged);
//   3. the outlier flags are recomputed on the final estimate (chi2 > threshold or depth <= 0).
// An abort flag (tracking wants a new keyframe) is polled by an IterationCallback at the end of
// every LM iteration and between the passes; on abort the latest accepted iterate is returned
// (update_state_every_iteration) with flags computed on it. A point whose observations are all
// excluded is simply not in the second problem and keeps its value.
//
// Reported costs: initial_cost / final_cost are both 1/2 * sum of Huber(chi2) over the valid
// observations in front of the camera (Ceres' convention, the objective of pass 1) at the
// input and at the returned estimate, so they are comparable even though pass 2 drops the
// outliers and the kernel.
//
// Structure: the points are eliminated first (Schur). Keyframe poses have one of two layouts,
// chosen per call so that Ceres' Schur eliminator can use one of its fixed-size kernels
// (<residual rows, point size, camera block size>); without one it runs its dynamic-size code.
//  - only monocular observations: one 7-double block per keyframe (PoseManifold) and 2-row
//    residuals, kernel <2, 3, 6>;
//  - any stereo / RGB-D observation: a rotation block (4, RotationManifold) and a translation
//    block (3) per keyframe and every residual with 3 rows (a monocular one padded with a zero
//    row, which changes neither cost nor step), kernel <3, 3, 3>. Ceres has no <3, 3, 6> kernel,
//    and a mix of 2- and 3-row residuals has none at all.
// Measured with callgrind on synchronous runs of the static synthetic sequences, all local BAs of
// a run, against one 7-double block per pose for every sensor: stereo 9.1 -> 7.8 G instructions,
// RGB-D 15.6 -> 13.6 G, the same ATE to 1e-6 m; monocular with the split layout (<2, 3, 3>)
// instead of <2, 3, 6>: its linear solves 8.4 -> 13.0 G, so it keeps the single block.
// Both use analytic Jacobians (reprojection_cost.h).
//
// Linear solver. The reduced camera system has 6 * (free keyframes) unknowns and one block per
// pair of free keyframes that see a common point. Ceres' SPARSE_SCHUR (SuiteSparse) pays for
// the sparse bookkeeping of every non-zero block, so it only beats DENSE_SCHUR where most
// blocks are zero. Measured on corridor problems (keyframes 0.25 m apart, two of them fixed,
// each point seen by the next `band` keyframes where in view, stereo; the whole bundle_adjust
// call, this 2-core machine; the test's make_corridor builds the same kind):
//   keyframes x band   dense    sparse     fill (share of non-zero blocks)
//   60 x 60            399 ms   653 ms     1.00
//   100 x 100         1443     2904        1.00
//   100 x 20           331      414        0.37
//   250 x 30          1101     1169        0.23
//   300 x 20          1173      968        0.13
//   400 x 60          3362     4331        0.28
// monocular (one block per pose): 150 x 40 611 / 730 ms (0.47), 300 x 40 1321 / 1142 (0.25),
// 300 x 20 922 / 563 (0.13). Hence BaOptions: dense up to dense_schur_max_keyframes free
// keyframes whatever the fill, and up to dense_schur_cap_keyframes while the fill is at least
// dense_schur_min_fill (0.2; monocular dense_schur_min_fill_mono, 0.4); else sparse where Ceres
// has a sparse library. Local BAs down a corridor (60-80 free keyframes that all see each
// other) had gone sparse above 60: on the first 500 frames of the long synthetic walk
// (synchronous) their linear solves took 47 ms per iteration sparse against 27 dense, the run
// 61 -> 47 s, the same ATE to 1e-15 m.
#include "dynaorb/optimize/bundle_adjuster.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

#include "reprojection_cost.h"

namespace dynaorb::optimize {

namespace {

using PoseBlock = std::array<double, 7>;

class AbortCallback final : public ceres::IterationCallback {
 public:
  explicit AbortCallback(const std::atomic<bool>* abort) : abort_(abort) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& /*summary*/) override {
    if (abort_ && abort_->load(std::memory_order_relaxed)) {
      fired_ = true;
      return ceres::SOLVER_ABORT;
    }
    return ceres::SOLVER_CONTINUE;
  }
  bool fired() const { return fired_; }

 private:
  const std::atomic<bool>* abort_;
  bool fired_ = false;
};

bool abort_requested(const std::atomic<bool>* abort) {
  return abort && abort->load(std::memory_order_relaxed);
}

// The share of the reduced camera matrix's keyframe-by-keyframe blocks that are non-zero: ordered
// pairs of free keyframes that observe a common point, the diagonal included, over n^2.
// kfs_of_point: per point, the free keyframes (0..n-1) observing it. Counting stops at `enough`.
double camera_block_fill(const std::vector<std::vector<int>>& kfs_of_point, int n, double enough) {
  if (n <= 0) return 0;
  const size_t nn = static_cast<size_t>(n) * static_cast<size_t>(n);
  const size_t target = static_cast<size_t>(std::ceil(enough * static_cast<double>(nn)));
  std::vector<unsigned char> seen(nn, 0);
  size_t nonzero = 0;
  for (const std::vector<int>& ks : kfs_of_point)
    for (int a : ks)
      for (int b : ks) {
        unsigned char& s = seen[static_cast<size_t>(a) * n + b];
        if (s) continue;
        s = 1;
        if (++nonzero >= target) return enough;
      }
  return static_cast<double>(nonzero) / static_cast<double>(nn);
}

// DENSE_SCHUR up to options.dense_schur_max_keyframes free keyframes; above it, up to
// dense_schur_cap_keyframes, while the reduced camera matrix is at least dense_schur_min_fill
// (split pose layout) or dense_schur_min_fill_mono (one block per pose) full; else SPARSE_SCHUR
// where Ceres has a sparse library. fill(min_fill) computes the fill, counting up to min_fill.
template <typename Fill>
ceres::LinearSolverType choose_linear_solver(int free_keyframes, bool split_pose,
                                             const BaOptions& options, Fill fill,
                                             ceres::SparseLinearAlgebraLibraryType* sparse_lib) {
  if (free_keyframes <= options.dense_schur_max_keyframes) return ceres::DENSE_SCHUR;
  const double min_fill = split_pose ? options.dense_schur_min_fill : options.dense_schur_min_fill_mono;
  if (free_keyframes <= options.dense_schur_cap_keyframes && fill(min_fill) >= min_fill)
    return ceres::DENSE_SCHUR;
  for (auto lib : {ceres::SUITE_SPARSE, ceres::EIGEN_SPARSE, ceres::CX_SPARSE}) {
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(lib)) {
      *sparse_lib = lib;
      return ceres::SPARSE_SCHUR;
    }
  }
  return ceres::DENSE_SCHUR;
}

// Everything one call works on: the data, the parameter blocks (poses as 7-vectors, points in
// result.points) and the per-observation cost functions shared by both passes.
struct Workspace {
  const BaProblem& in;
  const BaOptions& options;
  std::vector<PoseBlock> poses;
  std::vector<Eigen::Vector3d>& points;
  std::vector<bool> valid;  // indices in range, finite data (else an outlier, never solved)
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  ceres::HuberLoss huber_mono, huber_stereo;
  detail::PoseManifold manifold;               // whole pose (monocular problems)
  detail::RotationManifold rotation_manifold;  // rotation block of a split pose
  bool split_pose = false;                     // any stereo observation (see the file comment)

  Workspace(const BaProblem& p, const BaOptions& o, std::vector<Eigen::Vector3d>& pts)
      : in(p), options(o), points(pts), huber_mono(std::sqrt(o.chi2_mono)),
        huber_stereo(std::sqrt(o.chi2_stereo)) {
    poses.resize(p.keyframes.size());
    for (size_t k = 0; k < poses.size(); ++k)
      detail::pose_to_params(p.keyframes[k].T_cw, poses[k].data());
    const int nk = static_cast<int>(p.keyframes.size()), np = static_cast<int>(p.points.size());
    valid.resize(p.observations.size());
    // One NaN residual makes Ceres refuse every step of the whole window, so an observation of
    // a non-finite pose or point, or one not usable() itself, is left out (its point and pose
    // are returned as given when nothing else observes them).
    for (size_t i = 0; i < valid.size(); ++i) {
      const BaObservation& ob = p.observations[i];
      valid[i] = ob.keyframe >= 0 && ob.keyframe < nk && ob.point >= 0 && ob.point < np && ob.obs.usable() &&
                 p.points[ob.point].allFinite() && p.keyframes[ob.keyframe].T_cw.matrix().allFinite();
      split_pose |= valid[i] && ob.obs.stereo();
    }
  }

  void build_costs() {
    costs.resize(in.observations.size());
    for (size_t i = 0; i < costs.size(); ++i) {
      if (!valid[i]) continue;
      const Observation& obs = in.observations[i].obs;
      if (!split_pose)
        costs[i] = std::make_unique<detail::BaCost<2>>(in.K, obs);
      else if (obs.stereo())
        costs[i] = std::make_unique<detail::BaSplitCost<3, 3>>(in.K, obs);
      else
        costs[i] = std::make_unique<detail::BaSplitCost<3, 2>>(in.K, obs);
    }
  }

  // Outlier flags (chi2 > threshold or depth <= 0; invalid observations are outliers) at the
  // current estimate; returns the robust cost 1/2 * sum Huber(chi2) over the valid ones in
  // front of the camera (behind it, a projection at kMinDepth has no meaningful cost).
  double classify(std::vector<bool>* outlier) const {
    outlier->assign(in.observations.size(), true);
    double cost = 0;
    for (size_t i = 0; i < in.observations.size(); ++i) {
      if (!valid[i]) continue;
      const BaObservation& o = in.observations[i];
      const Eigen::Vector3d Xc = detail::transform_point(poses[o.keyframe].data(), points[o.point]);
      const double chi2 = detail::observation_chi2(in.K, o.obs, Xc);
      const double threshold = o.obs.stereo() ? options.chi2_stereo : options.chi2_mono;
      (*outlier)[i] = !(chi2 <= threshold) || Xc.z() <= 0;  // NaN-safe
      if (Xc.z() > 0) cost += 0.5 * detail::huber(chi2, threshold);
    }
    return cost;
  }

  // The valid observations whose point lies in front of the camera at the current estimate.
  // One behind it is an outlier whatever the solver does: projected at kMinDepth its
  // residual is astronomically large (a point 8 m behind a KITTI keyframe: a Huber cost
  // of 1.7e9 against about 1700 for the rest of the window), and the first pass moved
  // that keyframe 2 m to shrink it, which made all its 695 other observations outliers.
  std::vector<bool> in_front() const {
    std::vector<bool> include(valid);
    for (size_t i = 0; i < include.size(); ++i) {
      if (!include[i]) continue;
      const BaObservation& o = in.observations[i];
      include[i] = detail::transform_point(poses[o.keyframe].data(), points[o.point]).z() > 0;
    }
    return include;
  }

  // The parameter block(s) of one keyframe's 7-double pose, eliminated after the points.
  void add_pose(ceres::Problem* problem, ceres::ParameterBlockOrdering* ordering, double* pose,
                bool fixed) {
    std::vector<double*> blocks;
    if (split_pose) {
      problem->AddParameterBlock(pose, 4, &rotation_manifold);
      problem->AddParameterBlock(pose + 4, 3);
      blocks = {pose, pose + 4};
    } else {
      problem->AddParameterBlock(pose, 7, &manifold);
      blocks = {pose};
    }
    for (double* b : blocks) {
      if (fixed) problem->SetParameterBlockConstant(b);
      ordering->AddElementToGroup(b, 1);
    }
  }

  bool dense_schur = false;  // the last solve's linear solver

  // One LM pass over the observations with include[i]; returns true if the abort flag stopped it.
  bool solve(const std::vector<bool>& include, bool robust, int iterations,
             const std::atomic<bool>* abort) {
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    std::vector<char> pose_used(poses.size(), 0), point_used(points.size(), 0);
    std::vector<int> free_index(poses.size(), -1);  // free keyframe -> 0..free_keyframes-1
    int free_keyframes = 0;
    for (size_t i = 0; i < include.size(); ++i) {
      if (!include[i]) continue;
      const BaObservation& o = in.observations[i];
      double* pose = poses[o.keyframe].data();
      double* point = points[o.point].data();
      if (!pose_used[o.keyframe]) {
        pose_used[o.keyframe] = 1;
        add_pose(&problem, ordering.get(), pose, in.keyframes[o.keyframe].fixed);
        if (!in.keyframes[o.keyframe].fixed) free_index[o.keyframe] = free_keyframes++;
      }
      if (!point_used[o.point]) {
        point_used[o.point] = 1;
        problem.AddParameterBlock(point, 3);
        ordering->AddElementToGroup(point, 0);  // eliminated first
      }
      ceres::LossFunction* loss = nullptr;
      if (robust) loss = o.obs.stereo() ? &huber_stereo : &huber_mono;
      if (split_pose)
        problem.AddResidualBlock(costs[i].get(), loss, pose, pose + 4, point);
      else
        problem.AddResidualBlock(costs[i].get(), loss, pose, point);
    }
    if (problem.NumResidualBlocks() == 0 || iterations <= 0) return false;

    AbortCallback callback(abort);
    ceres::Solver::Options so;
    so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
    auto fill = [&](double enough) {
      std::vector<std::vector<int>> kfs_of_point(points.size());
      for (size_t i = 0; i < include.size(); ++i) {
        if (!include[i]) continue;
        const int f = free_index[in.observations[i].keyframe];
        if (f >= 0) kfs_of_point[in.observations[i].point].push_back(f);
      }
      return camera_block_fill(kfs_of_point, free_keyframes, enough);
    };
    so.linear_solver_type = choose_linear_solver(free_keyframes, split_pose, options, fill,
                                                 &so.sparse_linear_algebra_library_type);
    dense_schur = so.linear_solver_type == ceres::DENSE_SCHUR;
    so.linear_solver_ordering = ordering;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.max_num_iterations = iterations;
    so.num_threads = std::max(1, options.num_threads);
    so.minimizer_progress_to_stdout = false;
    so.logging_type = ceres::SILENT;
    so.update_state_every_iteration = true;  // an aborted solve leaves the latest iterate
    so.callbacks.push_back(&callback);
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    return callback.fired();
  }
};

}  // namespace

BaResult bundle_adjust(const BaProblem& problem, const BaOptions& options,
                       const std::atomic<bool>* abort) {
  BaResult result;
  result.points = problem.points;
  Workspace ws(problem, options, result.points);

  result.initial_cost = ws.classify(&result.outlier);
  result.final_cost = result.initial_cost;
  result.aborted = abort_requested(abort);
  if (!result.aborted) {
    ws.build_costs();
    // Pass 1: the valid observations whose point is in front of the camera, Huber.
    result.aborted = ws.solve(ws.in_front(), /*robust=*/true, options.iterations_first, abort);
    if (!result.aborted) result.aborted = abort_requested(abort);
    if (!result.aborted && options.iterations_second > 0) {
      // Pass 2: inliers of pass 1 only, plain least squares.
      std::vector<bool> outlier;
      ws.classify(&outlier);
      std::vector<bool> include(outlier.size());
      for (size_t i = 0; i < include.size(); ++i) include[i] = ws.valid[i] && !outlier[i];
      result.aborted = ws.solve(include, /*robust=*/false, options.iterations_second, abort);
    }
    result.final_cost = ws.classify(&result.outlier);
    result.dense_schur = ws.dense_schur;
  }

  result.T_cw.resize(problem.keyframes.size());
  for (size_t k = 0; k < problem.keyframes.size(); ++k) {
    // Fixed keyframes are returned bit-identical (no quaternion round trip).
    result.T_cw[k] = problem.keyframes[k].fixed ? problem.keyframes[k].T_cw
                                                : detail::params_to_pose(ws.poses[k].data());
  }
  return result;
}

}  // namespace dynaorb::optimize
