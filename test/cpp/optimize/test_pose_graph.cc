// Essential-graph optimisation (optimize_pose_graph) on a synthetic loop: 40 keyframes on a
// circle of radius 10 m; the odometry is corrupted by a constant bias per step (rotation 0.4 deg,
// translation 2-3 cm and, for Sim(3), scale 1 %) plus noise, so the chained estimate drifts; the
// graph has the odometry edges measured on the drifted poses (as ORB-SLAM's essential graph)
// and one loop edge from the last keyframe to the first with the true relative motion.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "dynaorb/optimize/pose_graph.h"

namespace {

using dynaorb::optimize::optimize_pose_graph;
using dynaorb::optimize::PoseGraphOptions;
using dynaorb::optimize::PoseGraphProblem;
using dynaorb::optimize::PoseGraphResult;
using dynaorb::optimize::Sim3;
using dynaorb::optimize::Sim3Edge;
using dynaorb::optimize::Sim3Node;

constexpr double kDeg = M_PI / 180.0;
constexpr int kPoses = 40;

Sim3 make_sim3(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t, double s) {
  return Sim3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())), t, s);
}

Eigen::Vector3d center(const Sim3& S_iw) { return S_iw.inverse() * Eigen::Vector3d::Zero(); }

double rotation_error_deg(const Sim3& a, const Sim3& b) {
  return Eigen::AngleAxisd(a.rotation() * b.rotation().transpose()).angle() / kDeg;
}

struct LoopScene {
  std::vector<Sim3> truth;  // T_iw, s = 1
  PoseGraphProblem problem;
};

LoopScene make_loop(bool scale_drift, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0, 1);
  LoopScene sc;
  for (int k = 0; k < kPoses; ++k) {  // cameras looking at the circle's centre, height varying
    const double a = 2 * M_PI * k / kPoses;
    const Eigen::Vector3d c(10 * std::cos(a), 0.5 * std::sin(3 * a), 10 * std::sin(a));
    Eigen::Matrix3d R_wc;
    R_wc.col(2) = Eigen::Vector3d(-c.x(), 0, -c.z()).normalized();
    R_wc.col(1) = Eigen::Vector3d(0, 1, 0);
    R_wc.col(0) = R_wc.col(1).cross(R_wc.col(2));
    const Sim3 T_wc(Eigen::Quaterniond(R_wc), c, 1.0);
    sc.truth.push_back(T_wc.inverse());
  }
  const Sim3 bias = make_sim3(0.4 * kDeg, {0.3, 1, 0.2}, {0.02, 0.01, -0.03},
                              scale_drift ? 1.01 : 1.0);
  std::vector<Sim3> drifted{sc.truth[0]};
  for (int k = 0; k + 1 < kPoses; ++k) {
    const Sim3 rel = sc.truth[k + 1] * sc.truth[k].inverse();
    const double angle = 0.05 * kDeg * g(rng);
    const Eigen::Vector3d axis(g(rng), g(rng), g(rng));
    const Sim3 noise = make_sim3(angle, axis, 0.005 * Eigen::Vector3d(g(rng), g(rng), g(rng)), 1);
    drifted.push_back(bias * noise * rel * drifted[k]);
  }
  for (int k = 0; k < kPoses; ++k) sc.problem.nodes.push_back(Sim3Node{drifted[k], k == 0});
  for (int k = 0; k + 1 < kPoses; ++k) {
    Sim3Edge e;
    e.i = k;
    e.j = k + 1;
    e.S_ij = drifted[k] * drifted[k + 1].inverse();
    sc.problem.edges.push_back(e);
  }
  Sim3Edge loop;
  loop.i = kPoses - 1;
  loop.j = 0;
  loop.S_ij = sc.truth[kPoses - 1] * sc.truth[0].inverse();
  sc.problem.edges.push_back(loop);
  return sc;
}

struct Errors {
  double end = 0, end_rot = 0, mean = 0, max_rot = 0, max_scale = 0;
};

Errors errors(const std::vector<Sim3>& est, const std::vector<Sim3>& truth) {
  Errors e;
  for (size_t k = 0; k < est.size(); ++k) {
    const double d = (center(est[k]) - center(truth[k])).norm();
    e.mean += d / est.size();
    e.max_rot = std::max(e.max_rot, rotation_error_deg(est[k], truth[k]));
    e.max_scale = std::max(e.max_scale, std::abs(est[k].s - 1));
  }
  e.end = (center(est.back()) - center(truth.back())).norm();
  e.end_rot = rotation_error_deg(est.back(), truth.back());
  return e;
}

PoseGraphResult check_loop(bool scale_drift, bool fix_scale) {
  const LoopScene sc = make_loop(scale_drift, 4);
  std::vector<Sim3> before;
  for (const Sim3Node& n : sc.problem.nodes) before.push_back(n.S_iw);
  PoseGraphOptions opt;
  opt.fix_scale = fix_scale;
  const PoseGraphResult r = optimize_pose_graph(sc.problem, opt);
  const Errors e0 = errors(before, sc.truth), e1 = errors(r.S_iw, sc.truth);
  std::printf("[ pose graph %s ] end-point error %.3f -> %.5f m, %.2f -> %.2f deg; mean centre "
              "error %.3f -> %.3f m; max rotation error %.2f -> %.2f deg; max |s - 1| %.4f -> "
              "%.4f; cost %.4g -> %.4g in %d iterations%s\n",
              fix_scale ? "SE3" : "Sim3", e0.end, e1.end, e0.end_rot, e1.end_rot, e0.mean,
              e1.mean, e0.max_rot, e1.max_rot, e0.max_scale, e1.max_scale, r.initial_cost,
              r.final_cost, r.iterations, r.converged ? " (converged)" : "");
  EXPECT_GT(e0.end, 1.0);  // the drift is real
  EXPECT_LT(e1.end * 5, e0.end);
  EXPECT_LT(e1.end_rot * 5, e0.end_rot);
  EXPECT_LT(e1.mean * 3, e0.mean);
  EXPECT_LT(e1.max_rot * 3, e0.max_rot);
  EXPECT_LT(r.final_cost, 0.01 * r.initial_cost);
  EXPECT_LE(r.iterations, 20);
  EXPECT_EQ(r.S_iw[0].matrix(), before[0].matrix());  // the fixed node
  return r;
}

TEST(PoseGraph, Sim3LoopRemovesScaleDrift) {
  const PoseGraphResult r = check_loop(true, false);
  for (const Sim3& S : r.S_iw) EXPECT_LT(std::abs(S.s - 1), 0.02);
}

TEST(PoseGraph, FixedScaleLoopKeepsScaleOne) {
  const PoseGraphResult r = check_loop(false, true);
  for (const Sim3& S : r.S_iw) EXPECT_EQ(S.s, 1.0);
}

TEST(PoseGraph, FixedNodesDoNotMove) {
  LoopScene sc = make_loop(true, 5);
  sc.problem.nodes[20].fixed = true;
  const PoseGraphResult free_run = optimize_pose_graph(make_loop(true, 5).problem);
  const PoseGraphResult r = optimize_pose_graph(sc.problem);
  EXPECT_GT((center(free_run.S_iw[20]) - center(sc.problem.nodes[20].S_iw)).norm(), 0.1);
  EXPECT_EQ(r.S_iw[20].matrix(), sc.problem.nodes[20].S_iw.matrix());
  EXPECT_EQ(r.S_iw[0].matrix(), sc.problem.nodes[0].S_iw.matrix());
  // Nodes 1..19 lie between two fixed nodes on a chain measured from these very poses: no
  // residual, they stay; nodes 21..39 take the loop error.
  EXPECT_LT((center(r.S_iw[10]) - center(sc.problem.nodes[10].S_iw)).norm(), 1e-9);
  EXPECT_GT((center(r.S_iw[30]) - center(sc.problem.nodes[30].S_iw)).norm(), 0.1);
}

TEST(PoseGraph, NoEdgesReturnsInput) {
  LoopScene sc = make_loop(true, 6);
  sc.problem.edges.clear();
  const PoseGraphResult r = optimize_pose_graph(sc.problem);
  ASSERT_EQ(r.S_iw.size(), sc.problem.nodes.size());
  for (size_t k = 0; k < r.S_iw.size(); ++k)
    EXPECT_EQ(r.S_iw[k].matrix(), sc.problem.nodes[k].S_iw.matrix());
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(r.final_cost, 0.0);
}

TEST(PoseGraph, SingleEdgeIsSolvedExactly) {  // large rotation / scale / translation gap
  PoseGraphProblem p;
  const Sim3 S0 = make_sim3(0.7, {1, 2, 3}, {1, -2, 0.5}, 1.3);
  p.nodes = {Sim3Node{S0, true}, Sim3Node{Sim3(), false}};
  Sim3Edge e;
  e.i = 0;
  e.j = 1;
  e.S_ij = make_sim3(2.0, {-1, 0.5, 0.2}, {3, 1, -2}, 2.5);
  p.edges = {e};
  const PoseGraphResult r = optimize_pose_graph(p);
  const Sim3 expected = e.S_ij.inverse() * S0;  // S_1w = S_01^{-1} * S_0w
  EXPECT_LT((r.S_iw[1].matrix() - expected.matrix()).norm(), 1e-8);
  EXPECT_LT(r.final_cost, 1e-16);
  EXPECT_TRUE(r.converged);
  e.j = 2;
  p.edges = {e};
  EXPECT_THROW(optimize_pose_graph(p), std::invalid_argument);
}

TEST(PoseGraph, PointCorrectionFollowsReferenceKeyframe) {
  const Sim3 old_pose = make_sim3(0.3, {0, 1, 0}, {0.5, 0, 1}, 1.0);
  const Sim3 corrected = make_sim3(0.35, {0.1, 1, 0}, {0.7, -0.1, 1.2}, 1.4);
  const Eigen::Vector3d x(1, 2, 5);
  const Eigen::Vector3d xc = dynaorb::optimize::correct_point(old_pose, corrected, x);
  const Eigen::Isometry3d T = dynaorb::optimize::sim3_to_se3(corrected);
  // The point keeps its place in the keyframe, up to the keyframe's new scale.
  EXPECT_LT((T * xc - (old_pose * x) / corrected.s).norm(), 1e-12);
  EXPECT_LT((corrected * xc - old_pose * x).norm(), 1e-12);
}

}  // namespace
