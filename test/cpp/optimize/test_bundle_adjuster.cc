// Local bundle adjustment on a synthetic local map: 10 keyframes along a 60 deg arc (radius 4 m)
// looking at 500 points in a 3 x 2 x 2 m box (fx = 500, 640x480, bf = 40), mixed mono / stereo
// observations (or monocular only, which bundle_adjust solves with another pose layout) with Gaussian noise 0.3 px * 1.2^level (levels 0..3), keyframes 0 and 1 fixed
// (gauge); free poses perturbed by 5 cm / 2 deg and points by 5 cm. Deterministic seeds.
// The noise is sub-pixel so that the maximum-likelihood estimate itself lies well within 1/10 of
// the perturbation: with this geometry the BA optimum sits ~1 mm / 0.01 deg * (noise / 0.1 px)
// from the truth (a rotation about the scene centre is the weakest direction).
#include <ceres/types.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <thread>
#include <vector>

#include "dynaorb/optimize/bundle_adjuster.h"
#include "pose_test_util.h"

namespace {

using dynaorb::optimize::BaObservation;
using dynaorb::optimize::BaProblem;
using dynaorb::optimize::BaResult;
using dynaorb::optimize::bundle_adjust;

using namespace dynaorb::test;  // NOLINT: kDeg, perturb, pose errors
constexpr int kKeyframes = 10;
constexpr int kFixed = 2;

// A 640x480 pinhole camera with focal length f and a stereo baseline bf = 40 px m.
dynaorb::optimize::Intrinsics camera(double f) {
  dynaorb::optimize::Intrinsics K;
  K.fx = K.fy = f;
  K.cx = 320;
  K.cy = 240;
  K.bf = 40;
  return K;
}

struct Scene {
  BaProblem truth;    // true poses and points, noisy observations
  BaProblem problem;  // the same with perturbed free poses and points
  std::vector<bool> injected;  // per observation: replaced by a random pixel
};

// stereo_share: the chance that an observation has a right coordinate (0: monocular only).
Scene make_scene(unsigned seed, int n_points, double outlier_ratio, double stereo_share = 0.5) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> g(0, 1);
  Scene s;
  BaProblem& P = s.truth;
  P.K = camera(500);
  // Keyframes on a 60 deg arc of radius 4 m around the centre of the point cloud, looking at it
  // (with a little jitter): the parallax of a local map, so depths are well triangulated.
  const Eigen::Vector3d target(0, 0, 4);
  for (int k = 0; k < kKeyframes; ++k) {
    const double a = (-30 + 60.0 * k / (kKeyframes - 1)) * kDeg;
    const Eigen::Vector3d center =
        target + 4 * Eigen::Vector3d(std::sin(a), 0.1 * std::sin(3 * a), -std::cos(a));
    const Eigen::Vector3d z = (target - center).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    Eigen::Matrix3d R_wc;
    R_wc << x, z.cross(x), z;
    R_wc = Eigen::AngleAxisd(1 * kDeg * std::cos(k), Eigen::Vector3d::UnitX()) * R_wc;
    dynaorb::optimize::BaKeyframe kf;
    kf.T_cw.linear() = R_wc.transpose();
    kf.T_cw.translation() = -R_wc.transpose() * center;
    kf.fixed = k < kFixed;
    P.keyframes.push_back(kf);
  }
  for (int i = 0; i < n_points; ++i)
    P.points.push_back(target + Eigen::Vector3d(3 * U(rng) - 1.5, 2 * U(rng) - 1, 2 * U(rng) - 1));
  for (int k = 0; k < kKeyframes; ++k) {
    for (int i = 0; i < n_points; ++i) {
      const Eigen::Vector3d Xc = P.keyframes[k].T_cw * P.points[i];
      const double u = P.K.fx * Xc.x() / Xc.z() + P.K.cx, v = P.K.fy * Xc.y() / Xc.z() + P.K.cy;
      if (Xc.z() < 0.5 || u < 5 || u > 635 || v < 5 || v > 475) continue;
      BaObservation o;
      o.keyframe = k;
      o.point = i;
      const int level = static_cast<int>(U(rng) * 4);
      const double scale = std::pow(1.2, level), sigma = 0.3 * scale;
      o.obs.inv_sigma2 = 1.0 / (scale * scale);
      // The right pixel must lie in the image.
      const bool stereo = U(rng) < stereo_share && u - P.K.bf / Xc.z() >= 0;
      const bool outlier = U(rng) < outlier_ratio;
      if (outlier) {
        o.obs.uv = Eigen::Vector2d(640 * U(rng), 480 * U(rng));
        if (stereo) o.obs.u_right = std::max(0.0, o.obs.uv.x() - 40 * U(rng));
      } else {
        o.obs.uv = Eigen::Vector2d(u + sigma * g(rng), v + sigma * g(rng));
        if (stereo) o.obs.u_right = std::max(0.0, u - P.K.bf / Xc.z() + sigma * g(rng));
      }
      P.observations.push_back(o);
      s.injected.push_back(outlier);
    }
  }
  s.problem = P;
  for (auto& kf : s.problem.keyframes)
    if (!kf.fixed) kf.T_cw = perturb(kf.T_cw, 0.05, 2 * kDeg, rng);
  for (auto& X : s.problem.points) X += 0.05 * random_unit(rng);
  return s;
}

double mean_point_error(const std::vector<Eigen::Vector3d>& a,
                        const std::vector<Eigen::Vector3d>& b) {
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]).norm();
  return sum / a.size();
}

struct Bounds {
  double pose_m, pose_deg;  // per free keyframe
  double mean_m, mean_deg;  // mean over the free keyframes
  double points_m;          // mean point error
};

// Solves s.problem with the default options and checks the result against the truth (bounds b,
// and at least 10x closer than the start), the gauge, the costs and the outlier flags; the
// default 5 + 10 iterations must reach the optimum that 60 + 60 reach.
void check_converges(const Scene& s, const Bounds& b) {
  const BaResult r = bundle_adjust(s.problem);
  EXPECT_FALSE(r.aborted);
  ASSERT_EQ(r.T_cw.size(), s.truth.keyframes.size());
  ASSERT_EQ(r.outlier.size(), s.problem.observations.size());
  dynaorb::optimize::BaOptions longer;
  longer.iterations_first = longer.iterations_second = 60;
  const BaResult optimum = bundle_adjust(s.problem, longer);

  double t0 = 0, r0 = 0, t1 = 0, r1 = 0;  // mean over the free keyframes
  for (int k = 0; k < kKeyframes; ++k) {
    SCOPED_TRACE(k);
    const auto& truth = s.truth.keyframes[k].T_cw;
    if (k < kFixed) {
      EXPECT_TRUE(r.T_cw[k].matrix() == s.problem.keyframes[k].T_cw.matrix());
      continue;
    }
    const double tk = center_error(r.T_cw[k], truth), rk = rotation_error_deg(r.T_cw[k], truth);
    EXPECT_LT(tk, b.pose_m);
    EXPECT_LT(rk, b.pose_deg);
    EXPECT_LT(center_error(r.T_cw[k], optimum.T_cw[k]), 1e-5);
    t0 += center_error(s.problem.keyframes[k].T_cw, truth) / (kKeyframes - kFixed);
    r0 += rotation_error_deg(s.problem.keyframes[k].T_cw, truth) / (kKeyframes - kFixed);
    t1 += tk / (kKeyframes - kFixed);
    r1 += rk / (kKeyframes - kFixed);
  }
  EXPECT_LT(t1, t0 / 5);
  EXPECT_LT(r1, r0 / 10);
  EXPECT_LT(t1, b.mean_m);
  EXPECT_LT(r1, b.mean_deg);
  const double p0 = mean_point_error(s.problem.points, s.truth.points);
  const double p1 = mean_point_error(r.points, s.truth.points);
  EXPECT_LT(p1, p0 / 10);
  EXPECT_LT(p1, b.points_m);
  EXPECT_LT(r.final_cost, 0.01 * r.initial_cost);
  EXPECT_GT(r.initial_cost, 0);

  int flagged = 0;
  for (bool o : r.outlier) flagged += o;
  EXPECT_LT(flagged, 0.005 * r.outlier.size());  // clean data, noise well inside the gate
}

TEST(BundleAdjuster, ConvergesFromPerturbedStart) {
  for (unsigned seed : {42u, 3u, 2u}) {
    SCOPED_TRACE(seed);
    const Scene s = make_scene(seed, 500, 0.0);
    ASSERT_GT(s.problem.observations.size(), 4000u);
    // Measured: per keyframe <= 4.3 mm / 0.053 deg (from 50 mm / 2 deg), means <= 3.0 mm /
    // 0.042 deg, points <= 2.8 mm (from 50 mm).
    check_converges(s, {0.008, 0.1, 0.0045, 0.065, 0.0045});
  }
}

// Without a stereo observation the poses are single 7-double blocks (bundle_adjuster.cc).
// Depth then comes from parallax alone and the optimum lies farther from the truth.
TEST(BundleAdjuster, MonocularOnlyConverges) {
  for (unsigned seed : {42u, 3u}) {
    SCOPED_TRACE(seed);
    const Scene s = make_scene(seed, 500, 0.0, 0.0);
    ASSERT_GT(s.problem.observations.size(), 4000u);
    for (const BaObservation& o : s.problem.observations) ASSERT_FALSE(o.obs.stereo());
    // Measured: per keyframe <= 8.3 mm / 0.075 deg, means <= 5.7 mm / 0.055 deg, points <= 4.3 mm.
    check_converges(s, {0.012, 0.12, 0.0085, 0.08, 0.0065});
  }
}

// The outlier flags of r against the scene's injected outliers (recall >= 0.95, false
// outliers < 1 % of the inliers) and each free keyframe within 8 mm / 0.1 deg of the truth.
void check_flags_and_poses(const Scene& s, const BaResult& r) {
  int tp = 0, fp = 0, fn = 0, n_inliers = 0;
  for (size_t i = 0; i < r.outlier.size(); ++i) {
    tp += r.outlier[i] && s.injected[i];
    fp += r.outlier[i] && !s.injected[i];
    fn += !r.outlier[i] && s.injected[i];
    n_inliers += !s.injected[i];
  }
  ASSERT_GT(tp + fn, 100);
  EXPECT_GE(double(tp) / (tp + fn), 0.95) << "missed " << fn;
  EXPECT_LT(fp, 0.01 * n_inliers) << "false outliers " << fp;
  for (int k = kFixed; k < kKeyframes; ++k) {
    EXPECT_LT(center_error(r.T_cw[k], s.truth.keyframes[k].T_cw), 0.008);
    EXPECT_LT(rotation_error_deg(r.T_cw[k], s.truth.keyframes[k].T_cw), 0.1);
  }
}

TEST(BundleAdjuster, FlagsInjectedOutliers) {
  const Scene s = make_scene(7, 500, 0.05);
  const BaResult r = bundle_adjust(s.problem);
  check_flags_and_poses(s, r);
  EXPECT_LT(mean_point_error(r.points, s.truth.points), 0.005);
  EXPECT_LT(r.final_cost, r.initial_cost);
}

// ORB-SLAM3's local BA schedule (LocalMapperOptions::ba_iterations_first 10,
// ba_iterations_second 0): one robust pass, the outliers only flagged after
// it. The same outliers are caught and the poses land as close to the truth;
// the points do not, which is what ORB-SLAM2's second pass is for.
TEST(BundleAdjuster, OneRobustPassFlagsInjectedOutliersToo) {
  const Scene s = make_scene(7, 500, 0.05);
  dynaorb::optimize::BaOptions one_pass;
  one_pass.iterations_first = 10;
  one_pass.iterations_second = 0;
  const BaResult r = bundle_adjust(s.problem, one_pass);
  EXPECT_FALSE(r.aborted);
  check_flags_and_poses(s, r);
  // The points keep what the Huber loss lets the outliers pull: measured
  // 9.8 mm mean error against 3.1 mm after ORB-SLAM2's second pass.
  const double one = mean_point_error(r.points, s.truth.points);
  const double two = mean_point_error(bundle_adjust(s.problem).points, s.truth.points);
  EXPECT_LT(one, 0.015);
  EXPECT_LT(two, one / 2);
  EXPECT_LT(r.final_cost, r.initial_cost);
}

TEST(BundleAdjuster, AbortBeforeCallReturnsInputQuickly) {
  const Scene s = make_scene(3, 500, 0.02);
  const std::atomic<bool> abort{true};
  const auto start = std::chrono::steady_clock::now();
  const BaResult r = bundle_adjust(s.problem, {}, &abort);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  EXPECT_TRUE(r.aborted);
  EXPECT_LT(ms, 50);  // a few microseconds per observation: no solve happened
  for (size_t k = 0; k < s.problem.keyframes.size(); ++k)
    EXPECT_TRUE(r.T_cw[k].isApprox(s.problem.keyframes[k].T_cw, 1e-12));
  EXPECT_TRUE(r.points == s.problem.points);
  EXPECT_EQ(r.outlier.size(), s.problem.observations.size());
  EXPECT_EQ(r.final_cost, r.initial_cost);

  // The same flag left false does not abort.
  const std::atomic<bool> go{false};
  EXPECT_FALSE(bundle_adjust(s.problem, {}, &go).aborted);
}

TEST(BundleAdjuster, AbortDuringSolveKeepsLatestIterate) {
  const Scene s = make_scene(5, 500, 0.02);
  std::atomic<bool> abort{false};
  // Raised from another thread while the first pass runs (a full solve takes tens of ms here).
  std::thread raiser([&abort] {
    std::this_thread::sleep_for(std::chrono::milliseconds(8));
    abort = true;
  });
  const BaResult r = bundle_adjust(s.problem, {}, &abort);
  raiser.join();
  if (!r.aborted) GTEST_SKIP() << "the solve finished before the flag was raised";
  for (const auto& T : r.T_cw) EXPECT_TRUE(T.matrix().allFinite());
  for (const auto& X : r.points) EXPECT_TRUE(X.allFinite());
  EXPECT_EQ(r.outlier.size(), s.problem.observations.size());
  EXPECT_LE(r.final_cost, r.initial_cost);  // an accepted LM iterate (or the input itself)
}

TEST(BundleAdjuster, UnobservedPointAndBadIndicesAreLeftAlone) {
  Scene s = make_scene(9, 100, 0.0);
  const Eigen::Vector3d lonely(1, 2, 30);
  s.problem.points.push_back(lonely);
  BaObservation bad;
  bad.keyframe = 3;
  bad.point = 100000;  // out of range
  s.problem.observations.push_back(bad);
  const BaResult r = bundle_adjust(s.problem);
  ASSERT_EQ(r.points.size(), s.problem.points.size());
  EXPECT_TRUE(r.points.back() == lonely);
  EXPECT_TRUE(r.outlier.back());
  EXPECT_LT(r.final_cost, r.initial_cost);
}

// One NaN residual anywhere makes Ceres refuse every step of the window: non-finite points and
// observations must stay out of the problem, which then converges as without them.
TEST(BundleAdjuster, NonFiniteDataIsLeftOutAndTheRestConverges) {
  Scene s = make_scene(11, 300, 0.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // A point whose every observation goes with it, and single observations of good points.
  const int bad_point = 17;
  s.problem.points[bad_point] = Eigen::Vector3d(nan, 0, 1);
  std::vector<size_t> bad_obs;
  for (size_t i = 0; i < s.problem.observations.size() && bad_obs.size() < 3; ++i)
    if (s.problem.observations[i].point != bad_point && i % 97 == 5) bad_obs.push_back(i);
  ASSERT_EQ(bad_obs.size(), 3u);
  s.problem.observations[bad_obs[0]].obs.uv.x() = nan;
  s.problem.observations[bad_obs[1]].obs.inv_sigma2 = std::numeric_limits<double>::infinity();
  s.problem.observations[bad_obs[2]].obs.u_right = nan;  // reads as monocular: still usable
  const BaResult r = bundle_adjust(s.problem);
  for (size_t i = 0; i < s.problem.observations.size(); ++i) {
    if (s.problem.observations[i].point == bad_point) {
      EXPECT_TRUE(r.outlier[i]) << i;
    }
  }
  EXPECT_TRUE(r.outlier[bad_obs[0]]);
  EXPECT_TRUE(r.outlier[bad_obs[1]]);
  EXPECT_TRUE(std::isnan(r.points[bad_point].x()));  // returned as given
  for (int k = kFixed; k < kKeyframes; ++k) {
    SCOPED_TRACE(k);
    EXPECT_TRUE(r.T_cw[k].matrix().allFinite());
    EXPECT_LT(center_error(r.T_cw[k], s.truth.keyframes[k].T_cw), 0.008);
    EXPECT_LT(rotation_error_deg(r.T_cw[k], s.truth.keyframes[k].T_cw), 0.1);
  }
  EXPECT_LT(r.final_cost, 0.01 * r.initial_cost);
}

// A map point behind a free keyframe that observes it (a wrong fusion can leave one there: on
// KITTI 06 a point 8 m behind the newest keyframe, seen by 6 keyframes in front of it). Its
// observation there is an outlier from the start and stays out of the first pass: projected
// at the minimum depth it outweighed the whole window and moved the keyframe 2 m.
// The scene drives forward as KITTI's camera does: keyframes 1 m apart along +z (the first two
// fixed) looking ahead at 300 points 12-40 m away, and one point 9 m ahead of the first, seen
// where it is by the first six and by the last one, 6 m past it.
TEST(BundleAdjuster, PointBehindAFreeKeyframeDoesNotMoveIt) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> g(0, 1);
  BaProblem truth;
  truth.K = camera(500);
  constexpr int kDriven = 16;
  for (int k = 0; k < kDriven; ++k) {
    dynaorb::optimize::BaKeyframe kf;
    kf.T_cw.translation() = Eigen::Vector3d(0, 0, -k);
    kf.fixed = k < kFixed;
    truth.keyframes.push_back(kf);
  }
  auto observe = [&](int k, int i, bool stereo, double noise_px) {
    const Eigen::Vector3d Xc = truth.keyframes[k].T_cw * truth.points[i];
    BaObservation o;
    o.keyframe = k;
    o.point = i;
    o.obs.uv = Eigen::Vector2d(500 * Xc.x() / Xc.z() + 320 + noise_px * g(rng),
                               500 * Xc.y() / Xc.z() + 240 + noise_px * g(rng));
    if (stereo) o.obs.u_right = o.obs.uv.x() - 40 / Xc.z();
    truth.observations.push_back(o);
  };
  for (int i = 0; i < 300; ++i) {
    truth.points.emplace_back(16 * U(rng) - 8, 6 * U(rng) - 3, 22 + 18 * U(rng));
    for (int k = 0; k < kDriven; ++k) observe(k, i, U(rng) < 0.5, 0.3);
  }
  truth.points.emplace_back(1, -0.5, 9);
  for (int k = 0; k < 6; ++k) observe(k, 300, true, 0);
  const int last = kDriven - 1;
  BaObservation behind;
  behind.keyframe = last;
  behind.point = 300;
  behind.obs.uv = Eigen::Vector2d(480, 100);
  truth.observations.push_back(behind);
  ASSERT_LT((truth.keyframes[last].T_cw * truth.points[300]).z(), -5);

  BaProblem problem = truth;
  for (auto& kf : problem.keyframes)
    if (!kf.fixed) kf.T_cw = perturb(kf.T_cw, 0.02, 0.5 * kDeg, rng);
  const BaResult r = bundle_adjust(problem);
  // The answer is that of the problem without the observation (it took the keyframes up to
  // 4 cm away from it).
  BaProblem without = problem;
  without.observations.pop_back();
  const BaResult clean = bundle_adjust(without);
  EXPECT_TRUE(r.outlier.back());
  int flagged = 0;
  for (size_t i = 0; i + 1 < r.outlier.size(); ++i) flagged += r.outlier[i];
  EXPECT_LT(flagged, 0.005 * r.outlier.size());
  for (int k = kFixed; k < kDriven; ++k) {
    SCOPED_TRACE(k);
    EXPECT_LT(center_error(r.T_cw[k], clean.T_cw[k]), 1e-9);
    EXPECT_LT(center_error(r.T_cw[k], truth.keyframes[k].T_cw), 0.015);
  }
  EXPECT_TRUE(std::isfinite(r.initial_cost) && std::isfinite(r.final_cost));
  EXPECT_LT(r.final_cost, 0.5 * r.initial_cost);
}

// A corridor: n keyframes 0.25 m apart looking down it (keyframes 0, 1 fixed), points_per_kf
// points ahead of each, seen by the keyframes up to `band` places on (where in view), stereo,
// 0.3 px noise; free poses perturbed by 1 cm. `band` sets how full the reduced camera matrix is.
BaProblem make_corridor(int n, int band, int points_per_kf, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> g(0, 1);
  BaProblem P;
  P.K = camera(400);
  for (int k = 0; k < n; ++k) {
    dynaorb::optimize::BaKeyframe kf;
    kf.T_cw.translation() = Eigen::Vector3d(0, 0, -0.25 * k);
    kf.fixed = k < 2;
    P.keyframes.push_back(kf);
  }
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < points_per_kf; ++i) {
      const Eigen::Vector3d X(4 * U(rng) - 2, 3 * U(rng) - 1.5, 0.25 * (k + band * U(rng)) + 2);
      const int pi = static_cast<int>(P.points.size());
      P.points.push_back(X + 0.03 * Eigen::Vector3d(g(rng), g(rng), g(rng)));
      for (int j = std::max(0, k - 1); j < std::min(n, k + band); ++j) {
        const Eigen::Vector3d Xc = P.keyframes[j].T_cw * X;
        const double u = P.K.fx * Xc.x() / Xc.z() + P.K.cx, v = P.K.fy * Xc.y() / Xc.z() + P.K.cy;
        if (Xc.z() < 0.5 || u < 0 || u > 640 || v < 0 || v > 480) continue;
        BaObservation o;
        o.keyframe = j;
        o.point = pi;
        o.obs.uv = Eigen::Vector2d(u + 0.3 * g(rng), v + 0.3 * g(rng));
        o.obs.u_right = std::max(0.0, o.obs.uv.x() - P.K.bf / Xc.z());
        P.observations.push_back(o);
      }
    }
  }
  for (int k = 2; k < n; ++k) P.keyframes[k].T_cw.translation() += 0.01 * random_unit(rng);
  return P;
}

// Above dense_schur_max_keyframes free keyframes the linear solver follows the fill of the
// reduced camera matrix: dense for a window whose keyframes all see each other (a local BA in a
// corridor), sparse for a long chain (a global BA); either gives the same answer.
TEST(BundleAdjuster, LinearSolverFollowsCameraMatrixFill) {
  dynaorb::optimize::BaOptions dense, sparse;
  dense.dense_schur_max_keyframes = 1000;
  sparse.dense_schur_max_keyframes = sparse.dense_schur_cap_keyframes = 0;
  const bool have_sparse = ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE) ||
                           ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE);
  struct Case {
    int n, band;
    bool expect_dense;
  };
  for (const Case& c : {Case{70, 70, true}, Case{160, 6, !have_sparse}}) {
    SCOPED_TRACE(c.band);
    const BaProblem p = make_corridor(c.n, c.band, 8, 7);
    const BaResult automatic = bundle_adjust(p);
    EXPECT_EQ(automatic.dense_schur, c.expect_dense);
    EXPECT_LT(automatic.final_cost, 0.05 * automatic.initial_cost);
    const BaResult other = bundle_adjust(p, c.expect_dense ? sparse : dense);
    EXPECT_EQ(other.dense_schur, !c.expect_dense || !have_sparse);
    for (int k = 0; k < c.n; ++k) EXPECT_LT(center_error(automatic.T_cw[k], other.T_cw[k]), 1e-6);
  }
  // At or below dense_schur_max_keyframes the solve is dense whatever the fill.
  EXPECT_TRUE(bundle_adjust(make_corridor(40, 4, 8, 7)).dense_schur);
}

}  // namespace
