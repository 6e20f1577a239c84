// Essential-graph optimisation in Sim(3) (see pose_graph.h and sim3_manifold.h).
//
// Problem: one 8-double block per node that some edge touches (others are returned as given);
// fixed nodes are constant blocks. Without any fixed node the problem keeps its 7-dof gauge
// freedom (6 with fix_scale); LM's damping still gives a step, but the result then floats, so
// callers fix at least one node as ORB-SLAM2 does (the loop keyframe).
//
// Linear solver: sparse normal Cholesky when Ceres has a sparse backend (graphs of thousands of
// keyframes are sparse, each node linked to a few neighbours), dense otherwise.
#include "dynaorb/optimize/pose_graph.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <memory>
#include <stdexcept>
#include <string>

#include "sim3_manifold.h"

namespace dynaorb::optimize {

namespace {

// Upper Cholesky factor U (U^T U = information), after checking the matrix.
Matrix7d sqrt_information(const Matrix7d& information, size_t edge) {
  const std::string where = "optimize_pose_graph: edge " + std::to_string(edge) + ": ";
  if (!information.allFinite() || !information.isApprox(information.transpose(), 1e-9))
    throw std::invalid_argument(where + "information is not symmetric");
  const Eigen::LLT<Matrix7d> llt(information);
  if (llt.info() != Eigen::Success)
    throw std::invalid_argument(where + "information is not positive definite");
  return llt.matrixU();
}

void choose_linear_solver(ceres::Solver::Options* o) {
  for (auto lib : {ceres::SUITE_SPARSE, ceres::EIGEN_SPARSE, ceres::CX_SPARSE}) {
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(lib)) {
      o->linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
      o->sparse_linear_algebra_library_type = lib;
      return;
    }
  }
  o->linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
}

}  // namespace

PoseGraphResult optimize_pose_graph(const PoseGraphProblem& problem,
                                    const PoseGraphOptions& options) {
  const size_t n = problem.nodes.size();
  PoseGraphResult result;
  result.S_iw.reserve(n);
  for (const Sim3Node& node : problem.nodes) result.S_iw.push_back(node.S_iw);

  std::vector<Matrix7d> sqrt_info;
  sqrt_info.reserve(problem.edges.size());
  for (size_t e = 0; e < problem.edges.size(); ++e) {
    const Sim3Edge& edge = problem.edges[e];
    if (edge.i < 0 || edge.j < 0 || static_cast<size_t>(edge.i) >= n ||
        static_cast<size_t>(edge.j) >= n || edge.i == edge.j)
      throw std::invalid_argument("optimize_pose_graph: edge " + std::to_string(e) +
                                  " has bad node indices");
    sqrt_info.push_back(sqrt_information(edge.information, e));
  }
  if (problem.edges.empty()) return result;

  std::vector<std::array<double, 8>> blocks(n);
  for (size_t k = 0; k < n; ++k) loop::detail::to_array(problem.nodes[k].S_iw, blocks[k].data());

  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem ceres_problem(problem_options);
  std::unique_ptr<ceres::Manifold> manifold;
  if (options.fix_scale)
    manifold = std::make_unique<detail::Se3ScaleFixedManifold>();
  else
    manifold = std::make_unique<detail::Sim3Manifold>();

  std::vector<bool> used(n, false);
  for (size_t e = 0; e < problem.edges.size(); ++e) {
    const Sim3Edge& edge = problem.edges[e];
    ceres_problem.AddResidualBlock(detail::Sim3EdgeCost::create(edge.S_ij, sqrt_info[e]), nullptr,
                                   blocks[edge.i].data(), blocks[edge.j].data());
    used[edge.i] = used[edge.j] = true;
  }
  for (size_t k = 0; k < n; ++k) {
    if (!used[k]) continue;
    ceres_problem.SetManifold(blocks[k].data(), manifold.get());
    if (problem.nodes[k].fixed) ceres_problem.SetParameterBlockConstant(blocks[k].data());
  }

  ceres::Solver::Options solver_options;
  solver_options.minimizer_type = ceres::TRUST_REGION;
  solver_options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver_options.max_num_iterations = options.iterations;
  solver_options.num_threads = options.num_threads;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  choose_linear_solver(&solver_options);

  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &ceres_problem, &summary);

  for (size_t k = 0; k < n; ++k)
    if (used[k] && !problem.nodes[k].fixed)
      result.S_iw[k] = loop::detail::from_array(blocks[k].data());
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  // summary.iterations holds iteration 0 (the initial state) and one entry per LM step.
  result.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  return result;
}

Eigen::Isometry3d sim3_to_se3(const Sim3& S_iw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = S_iw.rotation();
  T.translation() = S_iw.t / S_iw.s;
  return T;
}

Eigen::Vector3d correct_point(const Sim3& S_iw_old, const Sim3& S_iw_corrected,
                              const Eigen::Vector3d& x_w) {
  return S_iw_corrected.inverse() * (S_iw_old * x_w);
}

}  // namespace dynaorb::optimize
