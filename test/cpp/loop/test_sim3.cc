// Sim(3) algebra, Horn's alignment and the Sim3 RANSAC of loop closing on synthetic data
// (deterministic seeds).
#include <gtest/gtest.h>

#include <unsupported/Eigen/MatrixFunctions>
#include <cmath>
#include <random>
#include <vector>

#include "dynaorb/loop/sim3.h"
#include "dynaorb/loop/sim3_ransac.h"

namespace {

using dynaorb::loop::align_horn;
using dynaorb::loop::Sim3;
using dynaorb::loop::Sim3Match;
using dynaorb::loop::Sim3RansacOptions;
using dynaorb::loop::Vector7d;

constexpr double kDeg = M_PI / 180.0;

Sim3 make_sim3(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t, double s) {
  return Sim3(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized())), t, s);
}

double rotation_error_deg(const Sim3& a, const Sim3& b) {
  return Eigen::AngleAxisd(a.rotation() * b.rotation().transpose()).angle() / kDeg;
}

Eigen::Matrix4d hat(const Vector7d& xi) {  // sim(3) element as a 4x4 matrix
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m.topLeftCorner<3, 3>() << xi[6], -xi[5], xi[4], xi[5], xi[6], -xi[3], -xi[4], xi[3], xi[6];
  m.topRightCorner<3, 1>() = xi.head<3>();
  return m;
}

TEST(Sim3, ExpMatchesMatrixExponentialAndLogInverts) {
  std::mt19937 rng(1);
  std::normal_distribution<double> g(0, 1);
  // Generic, small-rotation, small-scale and exactly-zero parts (the series branches).
  std::vector<Vector7d> cases;
  for (int k = 0; k < 20; ++k) {
    Vector7d xi;
    for (int i = 0; i < 7; ++i) xi[i] = g(rng);
    xi.segment<3>(3) *= 0.8;
    xi[6] *= 0.5;
    cases.push_back(xi);
  }
  Vector7d z = Vector7d::Zero();
  cases.push_back(z);
  z << 1, -2, 0.5, 0, 0, 0, 0.3;
  cases.push_back(z);
  z << 1, -2, 0.5, 0.4, -0.2, 0.9, 0;
  cases.push_back(z);
  z << 1, -2, 0.5, 1e-6, 2e-6, -1e-6, 1e-4;
  cases.push_back(z);
  z << 1, -2, 0.5, 0.3, 0.1, -0.2, 0.005;
  cases.push_back(z);
  z << 0.5, 0.2, -1, 0, 3.0, 0, -0.4;  // rotation close to pi
  cases.push_back(z);
  for (const Vector7d& xi : cases) {
    const Sim3 S = dynaorb::loop::sim3_exp(xi);
    const Eigen::Matrix4d M = hat(xi).exp();
    EXPECT_LT((S.matrix() - M).norm(), 1e-9) << xi.transpose();
    EXPECT_LT((dynaorb::loop::sim3_log(S) - xi).norm(), 1e-9) << xi.transpose();
  }
}

TEST(Sim3, ComposeInverseAndTransformAgreeWithMatrices) {
  const Sim3 A = make_sim3(30 * kDeg, {1, 2, 3}, {0.5, -1, 2}, 2.5);
  const Sim3 B = make_sim3(-70 * kDeg, {-1, 0, 1}, {3, 0.2, -1}, 0.4);
  const Eigen::Vector3d x(0.3, -0.7, 1.9);
  const Eigen::Vector4d xh(x.x(), x.y(), x.z(), 1);
  EXPECT_LT((A * x - (A.matrix() * xh).head<3>()).norm(), 1e-12);
  EXPECT_LT(((A * B).matrix() - A.matrix() * B.matrix()).norm(), 1e-12);
  EXPECT_LT((A.inverse().matrix() - A.matrix().inverse()).norm(), 1e-12);
  EXPECT_LT(((A * A.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  EXPECT_LT((A.inverse() * (A * x) - x).norm(), 1e-12);
  EXPECT_LT((((A * B).inverse()).matrix() - (B.inverse() * A.inverse()).matrix()).norm(), 1e-12);
  Sim3 A_neg = A;  // q and -q are the same rotation
  A_neg.q.coeffs() = -A.q.coeffs();
  EXPECT_LT((dynaorb::loop::sim3_log(A_neg) - dynaorb::loop::sim3_log(A)).norm(), 1e-12);
  // Isometry round trip (s = 1).
  const Sim3 C = make_sim3(40 * kDeg, {0, 1, 0}, {1, 2, 3}, 1.0);
  const Sim3 D = Sim3::from_isometry(C.to_isometry());
  EXPECT_LT((C.matrix() - D.matrix()).norm(), 1e-12);
  EXPECT_EQ(D.s, 1.0);
}

// p1 = S * p2 + noise for 20 random points.
void make_pairs(const Sim3& S, double noise, unsigned seed, std::vector<Eigen::Vector3d>* p1,
                std::vector<Eigen::Vector3d>* p2) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-2, 2);
  std::normal_distribution<double> g(0, noise);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d x(U(rng), U(rng), 4 + U(rng));
    p2->push_back(x);
    p1->push_back(S * x + Eigen::Vector3d(g(rng), g(rng), g(rng)));
  }
}

TEST(Sim3, HornRecoversSimilarity) {
  const Sim3 truth = make_sim3(30 * kDeg, {0.2, 1, -0.3}, {1.0, -0.5, 2.0}, 2.5);
  std::vector<Eigen::Vector3d> p1, p2;
  make_pairs(truth, 1e-5, 7, &p1, &p2);
  const Sim3 S = align_horn(p1, p2, false);
  EXPECT_LT(rotation_error_deg(S, truth), 1e-3);
  EXPECT_LT(std::abs(S.s / truth.s - 1), 1e-3);
  EXPECT_LT((S.t - truth.t).norm() / truth.t.norm(), 1e-3);
  EXPECT_THROW(align_horn(p1, {}, false), std::invalid_argument);
}

TEST(Sim3, HornFixScaleRecoversRigidMotion) {
  const Sim3 truth = make_sim3(-50 * kDeg, {1, -1, 0.5}, {-0.3, 0.8, 1.5}, 1.0);
  std::vector<Eigen::Vector3d> p1, p2;
  make_pairs(truth, 1e-5, 8, &p1, &p2);
  const Sim3 S = align_horn(p1, p2, true);
  EXPECT_EQ(S.s, 1.0);
  EXPECT_LT(rotation_error_deg(S, truth), 1e-3);
  EXPECT_LT((S.t - truth.t).norm(), 1e-3);
}

// ------------------------------------------------------------------------------ RANSAC
struct RansacScene {
  Eigen::Matrix3d K;
  Sim3 S12;
  std::vector<Sim3Match> matches;
  std::vector<bool> is_inlier;
};

// Keyframe 1 sees points at depth 2..8 m; keyframe 2 is another camera, in a map whose scale is
// 1 / 1.8 of keyframe 1's (monocular scale drift): X1 = S12 * X2. Keypoint levels 0..7, pixel
// noise 0.5 px * 1.2^level, triangulation noise (0.1 % of depth) on X1, X2; outliers pair a
// point in keyframe 1 with an unrelated point of keyframe 2.
RansacScene make_ransac_scene(unsigned seed, int n, double outlier_ratio, bool fix_scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> g(0, 1);
  RansacScene sc;
  sc.K << 500, 0, 320, 0, 500, 240, 0, 0, 1;
  const double scale = fix_scale ? 1.0 : 1.8;
  sc.S12 = make_sim3(12 * kDeg, {0.1, 1, 0.2}, {-0.8, 0.1, 0.3}, scale);
  const Sim3 S21 = sc.S12.inverse();
  auto project = [&](const Eigen::Vector3d& X) -> Eigen::Vector2d {
    return Eigen::Vector2d(500 * X.x() / X.z() + 320, 500 * X.y() / X.z() + 240);
  };
  auto random_point = [&]() -> Eigen::Vector3d {  // in keyframe 1, seen by both cameras
    for (;;) {
      const double z = 2 + 6 * U(rng);
      const Eigen::Vector3d X1((U(rng) * 600 + 20 - 320) / 500 * z,
                               (U(rng) * 440 + 20 - 240) / 500 * z, z);
      const Eigen::Vector2d uv2 = project(S21 * X1);
      if ((S21 * X1).z() > 0 && uv2.x() > 0 && uv2.x() < 640 && uv2.y() > 0 && uv2.y() < 480)
        return X1;
    }
  };
  auto noisy = [&](const Eigen::Vector3d& X) -> Eigen::Vector3d {  // 0.1 % of depth
    return X + 0.001 * X.z() * Eigen::Vector3d(g(rng), g(rng), g(rng));
  };
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d X1 = random_point();
    const bool outlier = U(rng) < outlier_ratio;
    const Eigen::Vector3d X2 = S21 * (outlier ? random_point() : X1);
    Sim3Match m;
    const int l1 = static_cast<int>(8 * U(rng)), l2 = static_cast<int>(8 * U(rng));
    m.sigma2_1 = std::pow(1.2, 2 * l1);
    m.sigma2_2 = std::pow(1.2, 2 * l2);
    m.uv1 = project(X1) + 0.5 * std::sqrt(m.sigma2_1) * Eigen::Vector2d(g(rng), g(rng));
    m.uv2 = project(X2) + 0.5 * std::sqrt(m.sigma2_2) * Eigen::Vector2d(g(rng), g(rng));
    m.X1 = noisy(X1);
    m.X2 = noisy(X2);
    sc.matches.push_back(m);
    sc.is_inlier.push_back(!outlier);
  }
  return sc;
}

void check_ransac(bool fix_scale) {
  const RansacScene sc = make_ransac_scene(fix_scale ? 11 : 12, 100, 0.4, fix_scale);
  Sim3RansacOptions opt;
  opt.fix_scale = fix_scale;
  opt.seed = 3;
  const auto r = dynaorb::loop::sim3_ransac(sc.matches, sc.K, sc.K, opt);
  ASSERT_TRUE(r.ok);
  const double rot = rotation_error_deg(r.S12, sc.S12);
  const double trans = (r.S12.t - sc.S12.t).norm() / sc.S12.t.norm();
  const double scale = std::abs(r.S12.s / sc.S12.s - 1);
  int tp = 0, fp = 0, fn = 0;
  for (size_t i = 0; i < sc.matches.size(); ++i) {
    tp += r.inlier[i] && sc.is_inlier[i];
    fp += r.inlier[i] && !sc.is_inlier[i];
    fn += !r.inlier[i] && sc.is_inlier[i];
  }
  const double precision = tp / double(tp + fp), recall = tp / double(tp + fn);
  std::printf("[ sim3 ransac %s ] iterations %d inliers %d rot %.4f deg trans %.4f %% scale "
              "%.4f %% precision %.3f recall %.3f\n",
              fix_scale ? "SE3" : "Sim3", r.iterations, r.inliers, rot, 100 * trans,
              100 * scale, precision, recall);
  EXPECT_LT(rot, 0.5);
  EXPECT_LT(trans, 0.01);
  EXPECT_LT(scale, 0.01);
  EXPECT_GT(precision, 0.95);
  EXPECT_GT(recall, 0.95);
  if (fix_scale) {
    EXPECT_EQ(r.S12.s, 1.0);
  }
}

TEST(Sim3Ransac, RecoversSimilarityWithOutliers) { check_ransac(false); }

TEST(Sim3Ransac, RecoversRigidMotionWithFixedScale) { check_ransac(true); }

TEST(Sim3Ransac, TooFewMatchesFails) {
  const RansacScene sc = make_ransac_scene(5, 15, 0.0, false);  // 15 < min_inliers = 20
  const auto r = dynaorb::loop::sim3_ransac(sc.matches, sc.K, sc.K);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.iterations, 0);
  const RansacScene all_wrong = make_ransac_scene(6, 60, 1.0, false);
  EXPECT_FALSE(dynaorb::loop::sim3_ransac(all_wrong.matches, sc.K, sc.K).ok);
}

TEST(Sim3Ransac, DeterministicPerSeed) {
  const RansacScene sc = make_ransac_scene(9, 100, 0.4, false);
  Sim3RansacOptions opt;
  opt.seed = 42;
  const auto a = dynaorb::loop::sim3_ransac(sc.matches, sc.K, sc.K, opt);
  const auto b = dynaorb::loop::sim3_ransac(sc.matches, sc.K, sc.K, opt);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.inlier, b.inlier);
  EXPECT_EQ(a.S12.matrix(), b.S12.matrix());
  opt.seed = 43;
  const auto c = dynaorb::loop::sim3_ransac(sc.matches, sc.K, sc.K, opt);
  EXPECT_TRUE(c.ok);  // another seed: another sample sequence, same answer up to noise
  EXPECT_LT(rotation_error_deg(a.S12, c.S12), 0.5);
}

}  // namespace
