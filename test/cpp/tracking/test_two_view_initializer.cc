// Monocular two-view initialisation on synthetic scenes: a 640x480 camera
// (fx = fy = 500), a reference camera at the origin and a current one moved by
// (R_cr, t_cr); points on a tilted plane or spread in depth 2-8 m, Gaussian
// pixel noise, optional gross outliers. Deterministic seeds.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

#include "../stats_util.h"
#include "dynaorb/tracking/two_view_initializer.h"

namespace {

using dynaorb::tracking::TwoViewInitializer;
using dynaorb::tracking::TwoViewMatch;
using dynaorb::tracking::TwoViewOptions;
using dynaorb::tracking::TwoViewResult;
namespace two_view = dynaorb::tracking::two_view;

constexpr double kDeg = 3.14159265358979323846 / 180;

Eigen::Matrix3d camera() {
  Eigen::Matrix3d K;
  K << 500, 0, 320, 0, 500, 240, 0, 0, 1;
  return K;
}

struct Scene {
  Eigen::Matrix3d K = camera();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // X_cur = R X_ref + t
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> X;                   // per match, reference frame
  std::vector<Eigen::Vector2d> ref, cur;
  std::vector<TwoViewMatch> matches;
  std::vector<bool> outlier;
};

bool in_image(const Eigen::Vector2d& p) {
  return p.x() >= 0 && p.x() < 640 && p.y() >= 0 && p.y() < 480;
}

// n points seen by both cameras: planar (on n^T X = 4 with a tilted normal) or at depth 2-8 m.
// A plane needs a wide baseline (kPlanarR, kPlanarT: 1.2 m at 4 m): with less, the second
// physically valid homography solution keeps more than 0.75 of the true one's points and
// the initialiser rightly refuses (no clear winner, as in the paper).
// Keypoints of the current frame are stored in reverse order so that matches are not i <-> i.
// A fraction of the matches are gross outliers: the current keypoint is a random pixel at
// least 30 px away from the true one.
Scene make_scene(unsigned seed, int n, bool planar, const Eigen::Matrix3d& R,
                 const Eigen::Vector3d& t, double noise_px, double outlier_ratio = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> g(0, noise_px);
  Scene s;
  s.R = R;
  s.t = t;
  const Eigen::Vector3d normal = Eigen::Vector3d(-0.3, 0.2, 1).normalized();
  const Eigen::Matrix3d Kinv = s.K.inverse();
  std::vector<Eigen::Vector2d> cur;
  while (static_cast<int>(s.X.size()) < n) {
    const Eigen::Vector3d ray = Kinv * Eigen::Vector3d(640 * U(rng), 480 * U(rng), 1);
    const double depth = planar ? 4.0 / normal.dot(ray) : 2 + 6 * U(rng);
    const Eigen::Vector3d X = depth * ray;
    const Eigen::Vector3d Xc = R * X + t;
    if (Xc.z() < 0.5) continue;
    const Eigen::Vector2d p1 = (s.K * X).hnormalized(), p2 = (s.K * Xc).hnormalized();
    if (!in_image(p2)) continue;
    Eigen::Vector2d q2 = p2 + Eigen::Vector2d(g(rng), g(rng));
    const bool out = U(rng) < outlier_ratio;
    if (out) {
      do q2 = Eigen::Vector2d(640 * U(rng), 480 * U(rng));
      while ((q2 - p2).norm() < 30);
    }
    s.X.push_back(X);
    s.ref.push_back(p1 + Eigen::Vector2d(g(rng), g(rng)));
    cur.push_back(q2);
    s.outlier.push_back(out);
  }
  s.cur.assign(cur.rbegin(), cur.rend());
  for (int i = 0; i < n; ++i) s.matches.emplace_back(i, n - 1 - i);
  return s;
}

Eigen::Matrix3d rot(double deg, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(deg * kDeg, axis.normalized()).toRotationMatrix();
}

const Eigen::Matrix3d kPlanarR = rot(8, {0.2, 1, 0.1});
const Eigen::Vector3d kPlanarT(-1.2, 0.1, 0.15);
const Eigen::Matrix3d kGeneralR = rot(5, {0.1, 1, -0.2});
const Eigen::Vector3d kGeneralT(0.8, -0.1, 0.2);

double rotation_error_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return Eigen::AngleAxisd(A * B.transpose()).angle() / kDeg;
}

double direction_error_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) / kDeg;
}

int count(const std::vector<bool>& v) { return static_cast<int>(std::count(v.begin(), v.end(), true)); }

// The scene's matches as the initialiser's correspondences, unit weights.
two_view::Correspondences correspondences(const Scene& s) {
  two_view::Correspondences c;
  for (const auto& [i1, i2] : s.matches) {
    c.x1.push_back(s.ref[i1]);
    c.x2.push_back(s.cur[i2]);
    c.w1.push_back(1);
    c.w2.push_back(1);
  }
  return c;
}

TwoViewResult run(const Scene& s, const TwoViewOptions& o = {}) {
  return TwoViewInitializer(o).initialize(s.K, s.ref, s.cur, s.matches);
}

// Median relative 3-D error after the one global scale |t_true| / |t_est| (|t_est| = 1).
double median_point_error(const Scene& s, const TwoViewResult& r) {
  const double scale = s.t.norm() / r.t_cr.norm();
  std::vector<double> err;
  for (size_t i = 0; i < s.X.size(); ++i)
    if (r.triangulated[i] && !s.outlier[i])
      err.push_back((scale * r.points[i] - s.X[i]).norm() / s.X[i].norm());
  if (err.empty()) return 1e9;
  return dynaorb::test::median(err);
}

TEST(TwoViewInitializer, PlanarSceneSelectsHomography) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const Scene s = make_scene(seed, 300, true, kPlanarR, kPlanarT, 0.5);
    const TwoViewResult r = run(s);
    ASSERT_TRUE(r.ok) << "seed " << seed << ": " << r.reason;
    EXPECT_TRUE(r.used_homography) << "R_H = " << r.ratio_h;
    EXPECT_GT(r.ratio_h, 0.40);
    EXPECT_LT(rotation_error_deg(r.R_cr, s.R), 1.0);
    EXPECT_LT(direction_error_deg(r.t_cr, s.t), 2.0);
    EXPECT_NEAR(r.t_cr.norm(), 1.0, 1e-9);
    EXPECT_GT(count(r.triangulated), 0.9 * 300);
    EXPECT_GT(r.median_parallax_deg, 1.0);
    EXPECT_TRUE(r.reason.empty());
  }
}

TEST(TwoViewInitializer, GeneralSceneSelectsFundamental) {
  for (unsigned seed : {4u, 5u, 6u}) {
    const Scene s = make_scene(seed, 300, false, kGeneralR, kGeneralT, 0.7);
    const TwoViewResult r = run(s);
    ASSERT_TRUE(r.ok) << "seed " << seed << ": " << r.reason;
    EXPECT_FALSE(r.used_homography) << "R_H = " << r.ratio_h;
    EXPECT_LT(r.ratio_h, 0.40);
    EXPECT_LT(rotation_error_deg(r.R_cr, s.R), 1.0);
    EXPECT_LT(direction_error_deg(r.t_cr, s.t), 2.0);
    EXPECT_GT(count(r.triangulated), 0.8 * 300);
  }
}

TEST(TwoViewInitializer, OutliersAreRejected) {
  for (bool planar : {false, true}) {
    const Scene s = planar ? make_scene(7, 400, true, kPlanarR, kPlanarT, 0.5, 0.2)
                           : make_scene(7, 400, false, kGeneralR, kGeneralT, 0.5, 0.2);
    const int n_out = count(s.outlier);
    ASSERT_GT(n_out, 50);
    const TwoViewResult r = run(s);
    ASSERT_TRUE(r.ok) << r.reason;
    EXPECT_EQ(r.used_homography, planar);
    EXPECT_LT(rotation_error_deg(r.R_cr, s.R), 1.0);
    EXPECT_LT(direction_error_deg(r.t_cr, s.t), 2.0);
    int out_tri = 0, in_tri = 0;
    for (size_t i = 0; i < s.outlier.size(); ++i) (s.outlier[i] ? out_tri : in_tri) += r.triangulated[i];
    EXPECT_LT(out_tri, 0.1 * n_out) << out_tri << " of " << n_out << " outliers triangulated";
    EXPECT_GT(in_tri, 0.9 * (400 - n_out));
  }
}

TEST(TwoViewInitializer, NoParallaxIsRejected) {
  // Pure rotation, then a 5 mm translation at depths of 2-8 m (parallax < 0.15 deg).
  for (double baseline : {0.0, 0.005}) {
    for (bool planar : {false, true}) {
      const Scene s =
          make_scene(8, 300, planar, rot(4, {0.3, 1, 0}), baseline * Eigen::Vector3d(1, 0, 0), 0.5);
      const TwoViewResult r = run(s);
      EXPECT_FALSE(r.ok) << "baseline " << baseline << " planar " << planar;
      EXPECT_NE(r.reason.find("parallax"), std::string::npos) << r.reason;
      EXPECT_EQ(count(r.triangulated), 0);
    }
  }
}

TEST(TwoViewInitializer, PlanarAmbiguityIsRejected) {
  // A plane with a short baseline: the second physically valid homography solution keeps
  // most points in front of both cameras, so there is no clear winner (paper: do not
  // initialise, try the next frame).
  for (unsigned seed : {17u, 18u}) {
    const Scene s = make_scene(seed, 300, true, kPlanarR, {-0.3, 0.1, 0.15}, 0.5);
    const TwoViewResult r = run(s);
    EXPECT_FALSE(r.ok);
    EXPECT_TRUE(r.used_homography);
    EXPECT_NE(r.reason.find("no clear winner"), std::string::npos) << r.reason;
    EXPECT_EQ(count(r.triangulated), 0);
  }
}

// A room whose movers were masked: mostly its back wall (a plane), a few points off it,
// a short baseline. R_H picks H, whose two physical solutions tie (no clear winner); F,
// tried next (try_other_model, ours), reconstructs. ORB-SLAM2's rule alone waits.
TEST(TwoViewInitializer, TheOtherModelIsTriedWhenThePickedOneCannotReconstruct) {
  int fell_back = 0;
  for (unsigned seed : {41u, 42u, 43u}) {
    const Eigen::Vector3d t(-0.3, 0.1, 0.15);
    Scene s = make_scene(seed, 300, true, kPlanarR, t, 0.5);
    const Scene off = make_scene(seed + 100, 60, false, kPlanarR, t, 0.5);
    const int n = static_cast<int>(s.X.size());
    std::vector<Eigen::Vector2d> cur(s.cur.rbegin(), s.cur.rend());  // back to match order
    const std::vector<Eigen::Vector2d> off_cur(off.cur.rbegin(), off.cur.rend());
    for (size_t i = 0; i < off.X.size(); ++i) {
      s.X.push_back(off.X[i]);
      s.ref.push_back(off.ref[i]);
      cur.push_back(off_cur[i]);
      s.outlier.push_back(false);
    }
    s.cur.assign(cur.rbegin(), cur.rend());
    s.matches.clear();
    const int all = static_cast<int>(s.X.size());
    for (int i = 0; i < all; ++i) s.matches.emplace_back(i, all - 1 - i);
    ASSERT_GT(all, n);
    TwoViewOptions paper;
    paper.try_other_model = false;
    const TwoViewResult alone = run(s, paper);
    const TwoViewResult r = run(s);
    std::printf("seed %u: R_H %.2f, picked alone: %s (%s); with the other model: %s, %s%s\n", seed,
                alone.ratio_h, alone.used_homography ? "H" : "F", alone.ok ? "ok" : alone.reason.c_str(),
                r.ok ? "ok" : r.reason.c_str(), r.used_homography ? "H" : "F", r.other_model_used ? " (other)" : "");
    // 300 points on the wall, 60 off it: R_H 0.43.
    EXPECT_FALSE(alone.ok);
    EXPECT_TRUE(alone.used_homography);
    EXPECT_GT(alone.ratio_h, paper.ratio_h);
    EXPECT_NE(alone.reason.find("no clear winner"), std::string::npos) << alone.reason;
    ASSERT_TRUE(r.ok) << r.reason;
    ++fell_back;
    EXPECT_TRUE(r.other_model_used);
    EXPECT_FALSE(r.used_homography);
    EXPECT_LT(rotation_error_deg(r.R_cr, kPlanarR), 0.5);
    EXPECT_LT(direction_error_deg(r.t_cr, t), 3.0);
    EXPECT_GE(count(r.triangulated), 50);
  }
  EXPECT_EQ(fell_back, 3);
  // A general scene never needs it: F is picked and reconstructs.
  const TwoViewResult general = run(make_scene(44, 300, false, kGeneralR, kGeneralT, 0.5));
  EXPECT_TRUE(general.ok);
  EXPECT_FALSE(general.other_model_used);
}

TEST(TwoViewInitializer, CheckMotionRejectsInconsistentMatches) {
  // All matches offered as inliers under the true motion: the gross outliers must fail the
  // depth / reprojection tests, the others pass.
  const Scene s = make_scene(19, 300, false, kGeneralR, kGeneralT, 0.5, 0.3);
  const two_view::Correspondences c = correspondences(s);
  two_view::Motion m;
  m.R = s.R;
  m.t = s.t.normalized();
  const auto mc = two_view::check_motion(m, s.K, c, std::vector<bool>(300, true), 4.0);
  int out_tri = 0, in_tri = 0;
  for (size_t i = 0; i < s.outlier.size(); ++i) (s.outlier[i] ? out_tri : in_tri) += mc.triangulated[i];
  const int n_out = count(s.outlier);
  EXPECT_LT(out_tri, 0.05 * n_out);
  EXPECT_GT(in_tri, 0.95 * (300 - n_out));
  EXPECT_EQ(mc.n_good, static_cast<int>(mc.parallax_deg.size()));
}

// select_motion leaves a hypothesis unfinished once it can no longer win or
// count against the winner: the outcome must be what checking every
// hypothesis to the end gives (winner, points, the clear-winner refusal).
TEST(TwoViewInitializer, UnfinishedHypothesesDoNotChangeTheChoice) {
  struct Case {
    unsigned seed;
    bool planar;
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
  };
  const std::vector<Case> cases = {{31, true, kPlanarR, kPlanarT},
                                   {17, true, kPlanarR, {-0.3, 0.1, 0.15}},  // no clear winner
                                   {32, false, kGeneralR, kGeneralT},
                                   {33, false, rot(1, {0, 1, 0}), {0.05, 0, 0}}};
  int abandoned = 0, clear_winner_refused = 0;
  for (const Case& k : cases) {
    const Scene s = make_scene(k.seed, 300, k.planar, k.R, k.t, 0.5, 0.1);
    const two_view::Correspondences c = correspondences(s);
    two_view::ModelScore model;
    model.inliers.assign(c.size(), true);
    for (size_t i = 0; i < s.outlier.size(); ++i) model.inliers[i] = !s.outlier[i];
    model.n_inliers = count(model.inliers);
    Eigen::Matrix3d tx;  // [t]x: E = [t]x R in normalised coordinates
    tx << 0, -k.t.z(), k.t.y(), k.t.z(), 0, -k.t.x(), -k.t.y(), k.t.x(), 0;
    std::vector<two_view::Motion> hyps;
    if (k.planar) {
      const Eigen::Vector3d n = Eigen::Vector3d(-0.3, 0.2, 1).normalized();
      hyps = two_view::decompose_homography(s.K * (k.R + k.t * n.transpose() / 4.0) * s.K.inverse(), s.K);
    } else {
      hyps = two_view::decompose_essential(tx * k.R);
    }
    ASSERT_FALSE(hyps.empty());
    const TwoViewOptions o;
    // Each rotation of the hypotheses' order (every hypothesis comes first
    // once): which ones are left unfinished depends on the best one before them.
    for (size_t shift = 0; shift < hyps.size(); ++shift) {
      std::rotate(hyps.begin(), hyps.begin() + 1, hyps.end());
      // Every hypothesis to the end.
      std::vector<two_view::MotionCheck> full;
      int best = 0;
      for (const auto& m : hyps) {
        full.push_back(two_view::check_motion(m, s.K, c, model.inliers, o.reproj_chi2));
        EXPECT_FALSE(full.back().abandoned);
        if (full.back().n_good > full[best].n_good) best = static_cast<int>(full.size()) - 1;
      }
      int similar = 0;
      for (const auto& mc : full) similar += mc.n_good > o.clear_winner_ratio * full[best].n_good;
      for (size_t h = 0; h < hyps.size(); ++h) {
        const int give_up_at = static_cast<int>(std::floor(o.clear_winner_ratio * full[best].n_good));
        const auto part = two_view::check_motion(hyps[h], s.K, c, model.inliers, o.reproj_chi2, give_up_at);
        if (full[h].n_good > give_up_at) {
          EXPECT_FALSE(part.abandoned);
          EXPECT_EQ(part.n_good, full[h].n_good);
        } else if (part.abandoned) {
          EXPECT_LE(part.n_good, give_up_at);
          ++abandoned;
        }
      }
      TwoViewResult r;
      two_view::select_motion(hyps, s.K, c, model, o, r);
      EXPECT_EQ(r.n_good, full[best].n_good);
      EXPECT_EQ(r.reason.find("no clear winner") != std::string::npos, similar > 1) << r.reason;
      clear_winner_refused += similar > 1;
      if (r.ok) {
        EXPECT_TRUE(r.R_cr.isApprox(hyps[best].R));
        EXPECT_TRUE(r.t_cr.isApprox(hyps[best].t));
        EXPECT_EQ(r.triangulated, full[best].triangulated);
      }
    }
  }
  EXPECT_GT(clear_winner_refused, 0);  // the ambiguous plane, in every order
  EXPECT_GT(abandoned, 0);  // wrong hypotheses do stop early
}

// RANSAC stops scoring a sample set's model once it can no longer beat the
// best so far: the same winner, score and inliers as scoring every model to
// the end (a loop over the same sample sets here), for H and F, on planar and
// general scenes with outliers; and a model that can still win is scored to
// the end.
TEST(TwoViewInitializer, ScoringStopsOnlyForModelsThatCannotWin) {
  const TwoViewOptions o;
  int stopped = 0;
  for (const auto& [seed, planar] : std::vector<std::pair<unsigned, bool>>{{41, true}, {42, false}, {43, false}}) {
    const Scene s = make_scene(seed, 300, planar, planar ? kPlanarR : kGeneralR, planar ? kPlanarT : kGeneralT, 0.7,
                               planar ? 0.2 : 0.35);
    const two_view::Correspondences c = correspondences(s);
    std::mt19937 rng(seed);
    std::vector<std::vector<int>> samples(200);
    std::vector<int> all(c.size());
    std::iota(all.begin(), all.end(), 0);
    for (auto& smp : samples) {
      std::shuffle(all.begin(), all.end(), rng);
      smp.assign(all.begin(), all.begin() + 8);
    }
    for (const bool homography : {true, false}) {
      const double chi2 = homography ? o.chi2_h : o.chi2_f;
      const auto fit = [&](const std::vector<int>& smp) {
        std::vector<Eigen::Vector2d> x1, x2;
        const int k = homography ? std::min(std::max(o.homography_sample, 4), 8) : 8;
        for (int i = 0; i < k; ++i) {
          x1.push_back(c.x1[smp[i]]);
          x2.push_back(c.x2[smp[i]]);
        }
        return homography ? two_view::homography_dlt(x1, x2) : two_view::fundamental_8point(x1, x2);
      };
      const auto score = [&](const Eigen::Matrix3d& M, double must_beat) {
        return homography ? two_view::score_homography(M, c, chi2, o.score_gamma, must_beat)
                          : two_view::score_fundamental(M, c, chi2, o.score_gamma, must_beat);
      };
      // Every model to the end.
      two_view::ModelScore best;
      Eigen::Matrix3d best_model = Eigen::Matrix3d::Zero();
      for (const auto& smp : samples) {
        const Eigen::Matrix3d M = fit(smp);
        if (!M.allFinite() || M.norm() == 0) continue;
        const two_view::ModelScore full = score(M, -std::numeric_limits<double>::infinity());
        // With a bound: scored to the end while it can exceed it, below it when stopped.
        for (const double bound : {0.5 * full.score, full.score - 1e-6, full.score, 1.5 * full.score + 1}) {
          const two_view::ModelScore part = score(M, bound);
          if (full.score > bound) {
            EXPECT_EQ(part.score, full.score);
            EXPECT_EQ(part.inliers, full.inliers);
          } else {
            EXPECT_LE(part.score, bound);
            stopped += part.n_inliers < full.n_inliers;
          }
        }
        if (full.score > best.score) {
          best = full;
          best_model = M;
        }
      }
      Eigen::Matrix3d model;
      const two_view::ModelScore r = homography ? two_view::ransac_homography(c, samples, o, model)
                                                : two_view::ransac_fundamental(c, samples, o, model);
      EXPECT_GT(best.n_inliers, 0);
      EXPECT_EQ(r.score, best.score);
      EXPECT_EQ(r.inliers, best.inliers);
      EXPECT_EQ(model, best_model);
    }
  }
  EXPECT_GT(stopped, 0);  // models that cannot win do stop early
}

TEST(TwoViewInitializer, TooFewMatchesFailsCleanly) {
  const Scene s = make_scene(9, 300, false, rot(5, {0, 1, 0}), {0.5, 0, 0}, 0.5);
  for (int n : {0, 5, 8, 30, 49}) {
    Scene small = s;
    small.matches.resize(n);
    const TwoViewResult r = run(small);
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.reason.find("too few matches"), std::string::npos) << r.reason;
    EXPECT_EQ(r.triangulated.size(), static_cast<size_t>(n));
  }
  // Bad indices and mismatched sigma vectors: a reason, no crash.
  Scene bad = s;
  bad.matches[10].second = 1000;
  EXPECT_NE(run(bad).reason.find("out of range"), std::string::npos);
  const TwoViewResult r = TwoViewInitializer().initialize(s.K, s.ref, s.cur, s.matches, {1.0}, {});
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.reason.empty());
  // Enough matches but all random: no model and no map.
  Scene noise = make_scene(10, 200, false, rot(5, {0, 1, 0}), {0.5, 0, 0}, 0.5, 1.0);
  const TwoViewResult rn = run(noise);
  EXPECT_FALSE(rn.ok);
  EXPECT_FALSE(rn.reason.empty());
}

TEST(TwoViewInitializer, NonFiniteKeypointsGiveNoModelAndNoCrash) {
  const Scene s = make_scene(13, 300, false, kGeneralR, kGeneralT, 0.5);
  two_view::Correspondences c = correspondences(s);
  c.x1[0] = {std::nan(""), 100};
  // The minimal models through the bad point are not models: neither comes out usable
  // (finite and non-zero), and a RANSAC whose every sample holds it finds nothing.
  std::vector<Eigen::Vector2d> x1(c.x1.begin(), c.x1.begin() + 8), x2(c.x2.begin(), c.x2.begin() + 8);
  const Eigen::Matrix3d F = two_view::fundamental_8point(x1, x2);
  const Eigen::Matrix3d H = two_view::homography_dlt(x1, x2);
  EXPECT_FALSE(F.allFinite() && F.norm() > 0);
  EXPECT_FALSE(H.allFinite() && H.norm() > 0);
  std::vector<std::vector<int>> samples(20);
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 8; ++j) samples[k].push_back(j == 0 ? 0 : 1 + k * 7 + j);
  Eigen::Matrix3d model;
  EXPECT_EQ(two_view::ransac_fundamental(c, samples, TwoViewOptions(), model).n_inliers, 0);
  EXPECT_EQ(two_view::ransac_homography(c, samples, TwoViewOptions(), model).n_inliers, 0);
  // The initialiser refuses such input before any model, naming it.
  Scene bad = s;
  bad.ref[bad.matches[0].first] = {std::nan(""), 100};
  const TwoViewResult r = run(bad);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.reason.find("non-finite keypoint"), std::string::npos) << r.reason;
}

TEST(TwoViewInitializer, PointsMatchGroundTruthUpToScale) {
  for (bool planar : {false, true}) {
    const Scene s = planar ? make_scene(11, 300, true, kPlanarR, kPlanarT, 0.5)
                           : make_scene(11, 300, false, kGeneralR, kGeneralT, 0.5);
    const TwoViewResult r = run(s);
    ASSERT_TRUE(r.ok) << r.reason;
    EXPECT_LT(median_point_error(s, r), 0.03) << "planar " << planar;
    // Depths in the reference camera are positive; median_depth is the scale the caller uses.
    const double md = dynaorb::tracking::median_depth(r);
    EXPECT_GT(md, 0);
    std::vector<double> z;
    for (const auto& X : s.X) z.push_back(X.z());
    const double z_median = dynaorb::test::median(z);
    EXPECT_NEAR(md * s.t.norm(), z_median, 0.05 * z_median);
  }
}

TEST(TwoViewInitializer, LevelSigmaScalesTheThresholds) {
  // Keypoints from pyramid levels 0-7 (scale 1.2): noise 0.5 px * 1.2^level. With the level
  // sigma2 given, the coarse keypoints keep their wider thresholds and are triangulated.
  Scene s = make_scene(15, 300, false, kGeneralR, kGeneralT, 0.0);
  std::mt19937 rng(16);
  std::normal_distribution<double> g(0, 0.5);
  std::vector<double> s2_ref, s2_cur;
  for (auto* kps : {&s.ref, &s.cur}) {
    auto& s2 = kps == &s.ref ? s2_ref : s2_cur;
    for (auto& p : *kps) {
      const double scale = std::pow(1.2, static_cast<int>(rng() % 8));
      p += scale * Eigen::Vector2d(g(rng), g(rng));
      s2.push_back(scale * scale);
    }
  }
  const TwoViewResult with = TwoViewInitializer().initialize(s.K, s.ref, s.cur, s.matches, s2_ref, s2_cur);
  const TwoViewResult without = run(s);
  ASSERT_TRUE(with.ok) << with.reason;
  EXPECT_LT(rotation_error_deg(with.R_cr, s.R), 1.0);
  EXPECT_LT(direction_error_deg(with.t_cr, s.t), 2.0);
  EXPECT_GT(count(with.triangulated), 0.85 * 300);
  EXPECT_LT(count(without.triangulated), count(with.triangulated) - 30);
}

TEST(TwoViewInitializer, SameSeedSameResult) {
  const Scene s = make_scene(12, 300, false, rot(5, {0, 1, 0.2}), {0.5, 0, 0.1}, 1.0, 0.2);
  for (bool parallel : {true, false}) {
    TwoViewOptions o;
    o.seed = 42;
    o.parallel = parallel;
    const TwoViewResult a = run(s, o), b = run(s, o);
    ASSERT_TRUE(a.ok) << a.reason;
    EXPECT_EQ(a.ok, b.ok);
    EXPECT_EQ(a.used_homography, b.used_homography);
    EXPECT_EQ(a.score_h, b.score_h);
    EXPECT_EQ(a.score_f, b.score_f);
    EXPECT_EQ(a.n_good, b.n_good);
    EXPECT_TRUE(a.R_cr == b.R_cr);
    EXPECT_TRUE(a.t_cr == b.t_cr);
    EXPECT_EQ(a.triangulated, b.triangulated);
    for (size_t i = 0; i < a.points.size(); ++i) EXPECT_TRUE(a.points[i] == b.points[i]) << i;
  }
  // Serial and parallel runs agree too; another seed draws other samples.
  TwoViewOptions o;
  o.seed = 42;
  const TwoViewResult p = run(s, o);
  o.parallel = false;
  const TwoViewResult q = run(s, o);
  EXPECT_EQ(p.score_f, q.score_f);
  EXPECT_TRUE(p.R_cr == q.R_cr);
}

TEST(TwoViewInitializer, HomographyDecompositionContainsTrueMotion) {
  // Exact plane-induced homography: one of the 8 hypotheses is the true (R, t/|t|, n).
  const Eigen::Matrix3d K = camera(), R = rot(8, {0.3, 1, 0.2});
  const Eigen::Vector3d t(0.4, -0.1, 0.2), n = Eigen::Vector3d(0.2, -0.1, 1).normalized();
  const double d = 3;
  const Eigen::Matrix3d H = K * (R + t * n.transpose() / d) * K.inverse();
  const auto hyps = two_view::decompose_homography(H, K);
  ASSERT_EQ(hyps.size(), 8u);
  int found = 0;
  for (const auto& m : hyps) {
    EXPECT_NEAR(m.R.determinant(), 1.0, 1e-9);
    EXPECT_LT((m.R.transpose() * m.R - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    // Every hypothesis reproduces H: K^-1 H K = a R + b t n^T for some a, b.
    const Eigen::Matrix3d A = K.inverse() * H * K, B = m.t * m.n.transpose();
    Eigen::Matrix<double, 9, 2> M;
    M.col(0) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(m.R.data());
    M.col(1) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(B.data());
    const Eigen::Matrix<double, 9, 1> a = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(A.data());
    const Eigen::Vector2d ab = M.colPivHouseholderQr().solve(a);
    EXPECT_LT((M * ab - a).norm(), 1e-9 * a.norm());
    if (rotation_error_deg(m.R, R) < 1e-6 && direction_error_deg(m.t, t) < 1e-6 &&
        std::min(direction_error_deg(m.n, n), direction_error_deg(-m.n, n)) < 1e-6)
      ++found;
  }
  EXPECT_EQ(found, 1);
  // Pure rotation: no hypotheses.
  EXPECT_TRUE(two_view::decompose_homography(K * R * K.inverse(), K).empty());
}

TEST(TwoViewInitializer, EssentialDecompositionAndModels) {
  const Scene s = make_scene(13, 60, false, rot(5, {0, 1, 0.2}), {0.5, 0, 0.1}, 0.0);
  std::vector<Eigen::Vector2d> cur(s.matches.size());
  for (size_t i = 0; i < cur.size(); ++i) cur[i] = s.cur[s.matches[i].second];
  const Eigen::Matrix3d F = two_view::fundamental_8point(s.ref, cur);
  // Rank 2 also with noisy points (least squares over 60 of them).
  const Scene noisy = make_scene(13, 60, false, s.R, s.t, 1.0);
  std::vector<Eigen::Vector2d> ncur(noisy.cur.rbegin(), noisy.cur.rend());
  const Eigen::Vector3d sv = two_view::fundamental_8point(noisy.ref, ncur).jacobiSvd().singularValues();
  EXPECT_LT(sv(2), 1e-12 * sv(0));
  EXPECT_GT(sv(1), 1e-3 * sv(0));
  for (size_t i = 0; i < cur.size(); ++i)
    EXPECT_NEAR(cur[i].homogeneous().dot(F * s.ref[i].homogeneous()) /
                    (F * s.ref[i].homogeneous()).head<2>().norm(),
                0, 1e-6);
  const auto hyps = two_view::decompose_essential(s.K.transpose() * F * s.K);
  ASSERT_EQ(hyps.size(), 4u);
  int found = 0;
  for (const auto& m : hyps)
    if (rotation_error_deg(m.R, s.R) < 1e-6 && direction_error_deg(m.t, s.t) < 1e-6) ++found;
  EXPECT_EQ(found, 1);
  // A homography from 4 exact correspondences of a plane maps them exactly.
  const Scene p = make_scene(14, 4, true, rot(5, {0, 1, 0}), {0.5, 0, 0}, 0.0);
  std::vector<Eigen::Vector2d> pc(p.cur.rbegin(), p.cur.rend());
  const Eigen::Matrix3d H = two_view::homography_dlt(p.ref, pc);
  for (int i = 0; i < 4; ++i) EXPECT_LT(((H * p.ref[i].homogeneous()).hnormalized() - pc[i]).norm(), 1e-6);
}

}  // namespace
