#pragma once
// Monocular map initialisation from two views (ORB-SLAM, T-RO 2015, Sec. IV),
// written from the paper: a homography (normalised DLT) and a fundamental
// matrix (normalised 8-point, rank 2) are estimated in parallel by RANSAC on
// the same prefixed sample sets and scored with the symmetric transfer error
// and rho(d^2) = Gamma - d^2 (d^2 < T_M, else 0); R_H = S_H / (S_H + S_F)
// selects the model; the motion hypotheses (8 from the homography by Faugeras
// & Lustman's SVD method, 4 from E = K^T F K) are triangulated and one is
// accepted only when it clearly wins with enough points and enough parallax.
// The map is up to scale (|t_cr| = 1): the caller normalises it after BA,
// e.g. to median_depth() == 1. Plain data in and out, no map classes.
#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace dynaorb::tracking {

struct TwoViewOptions {
  double sigma = 1.0;              // keypoint noise at level 0, pixels (ORB-SLAM: 1 px)
  int ransac_iterations = 200;     // prefixed, same sample sets for H and F
  int homography_sample = 4;       // points of each 8-point set used for H: 4 as in the
                                   // paper; ORB-SLAM2's code fits H on all 8
  double chi2_h = 5.991;           // T_H: chi2 95 %, 2 dof (transfer error)
  double chi2_f = 3.841;           // T_F: chi2 95 %, 1 dof (point-to-epipolar-line)
  double score_gamma = 5.991;      // Gamma = T_H for both models, so scores compare
  double ratio_h = 0.40;           // homography when R_H > ratio_h. The paper says 0.45;
                                   // ORB-SLAM2's code uses 0.40, which we follow.
  bool refine_with_inliers = true; // ours, not in the paper: after the selection, refit the
                                   // selected model on its inliers (kept only if the score
                                   // does not drop); the selection uses the RANSAC scores
  double reproj_chi2 = 4.0;        // triangulated point: squared reprojection error < 4 sigma^2
  double min_parallax_deg = 1.0;   // see parallax_rank
  int parallax_rank = 50;          // parallax check: the (rank+1)-th largest parallax among the
                                   // good points (ORB-SLAM2: index min(50, n-1) of the sorted
                                   // parallaxes) must reach min_parallax_deg, i.e. at least 51
                                   // points (or all, when fewer) have that parallax
  int min_triangulated = 50;       // good points of the winning hypothesis; also the least
                                   // number of matches accepted as input
  double min_good_fraction = 0.9;  // good points >= this * model inliers (ORB-SLAM2)
  double clear_winner_ratio = 0.75;  // every other hypothesis below ratio * best good count
  // Ours: when the model R_H picked (H or F) cannot reconstruct (no clear winner, too
  // few good points, too little parallax), the other one is tried on the same matches
  // and taken when it passes the same tests (ORB-SLAM2 tries only the picked one and
  // waits for the next frame). With movers masked, what is left of a room is mostly
  // its walls: H wins R_H, its two physical solutions tie, and the reference frame
  // loses its matches before the baseline grows. `dynaorb bench --suite seeds
  // --sensors mono --conditions static,full,masks,off` (12 seeds, synchronous):
  // `full` first map at frames 5 / 4 instead of 24 / 27 on seeds 6 / 10 (55 / 56 of
  // 60 frames tracked instead of 36 / 33; every seed 51-56), full / static median
  // 1.03 -> 1.04 (seeds 0-2 0.90 both; seed 6 1.83 over its 55 frames against 0.90
  // over 36); static, masks and off unchanged on every seed, and EuRoC MH_05
  // monocular the same (first map at frame 8, 242/250 frames, 0.0153 m).
  bool try_other_model = true;
  std::uint32_t seed = 0;          // RANSAC sample sets (std::mt19937): deterministic
  bool parallel = true;            // H and F in two threads (std::async)
};

// Its fields by name (dynaorb/core/option_fields.h).
template <class F>
void option_fields(const TwoViewOptions*, F&& f) {
  f("sigma", &TwoViewOptions::sigma);
  f("ransac_iterations", &TwoViewOptions::ransac_iterations);
  f("homography_sample", &TwoViewOptions::homography_sample);
  f("chi2_h", &TwoViewOptions::chi2_h);
  f("chi2_f", &TwoViewOptions::chi2_f);
  f("score_gamma", &TwoViewOptions::score_gamma);
  f("ratio_h", &TwoViewOptions::ratio_h);
  f("refine_with_inliers", &TwoViewOptions::refine_with_inliers);
  f("reproj_chi2", &TwoViewOptions::reproj_chi2);
  f("min_parallax_deg", &TwoViewOptions::min_parallax_deg);
  f("parallax_rank", &TwoViewOptions::parallax_rank);
  f("min_triangulated", &TwoViewOptions::min_triangulated);
  f("min_good_fraction", &TwoViewOptions::min_good_fraction);
  f("clear_winner_ratio", &TwoViewOptions::clear_winner_ratio);
  f("try_other_model", &TwoViewOptions::try_other_model);
  f("seed", &TwoViewOptions::seed);
  f("parallel", &TwoViewOptions::parallel);
}

// (index in the reference keypoints, index in the current keypoints)
using TwoViewMatch = std::pair<int, int>;

struct TwoViewResult {
  bool ok = false;
  std::string reason;              // why not ok (empty when ok)
  Eigen::Matrix3d R_cr = Eigen::Matrix3d::Identity();  // X_cur = R_cr * X_ref + t_cr
  Eigen::Vector3d t_cr = Eigen::Vector3d::Zero();      // |t_cr| = 1 when ok
  std::vector<Eigen::Vector3d> points;  // per match, in the reference camera frame (the
                                        // world of the new map); zero where not triangulated
  std::vector<bool> triangulated;       // per match: good point with parallax (a map point)
  bool used_homography = false;
  double score_h = 0, score_f = 0;
  double ratio_h = 0;                   // S_H / (S_H + S_F)
  bool other_model_used = false;        // used_homography is the model R_H did not pick
                                        // (try_other_model)
  int n_inliers = 0;                    // inliers of the selected model
  int n_good = 0;                       // good points of the accepted (or best) hypothesis
  double median_parallax_deg = 0;       // over the good points of that hypothesis
};

class TwoViewInitializer {
 public:
  explicit TwoViewInitializer(const TwoViewOptions& options = {}) : options_(options) {}

  // K: pinhole matrix of the undistorted keypoints. level_sigma2_*: empty (all 1) or the
  // squared pyramid scale of each keypoint, multiplying sigma^2 in every test. Never throws
  // on bad input: ok = false with the reason.
  TwoViewResult initialize(const Eigen::Matrix3d& K, const std::vector<Eigen::Vector2d>& kps_ref,
                           const std::vector<Eigen::Vector2d>& kps_cur,
                           const std::vector<TwoViewMatch>& matches,
                           const std::vector<double>& level_sigma2_ref = {},
                           const std::vector<double>& level_sigma2_cur = {}) const;

  const TwoViewOptions& options() const { return options_; }

 private:
  TwoViewOptions options_;
};

// Depth quantile (0.5: median) of the triangulated points in the reference camera; 0 when
// none. ORB-SLAM scales the initial map so that this is 1 (after the global BA).
double median_depth(const TwoViewResult& result, double quantile = 0.5);

// Building blocks, exposed for reuse and tests.
namespace two_view {

// Matched keypoints of the two views with the inverse variance of each one
// (w = 1 / (sigma^2 * level_sigma2)).
struct Correspondences {
  std::vector<Eigen::Vector2d> x1, x2;  // reference, current (pixels)
  std::vector<double> w1, w2;
  int size() const { return static_cast<int>(x1.size()); }
};

// x2 ~ H x1 from >= 4 correspondences (normalised DLT, least squares beyond 4).
Eigen::Matrix3d homography_dlt(const std::vector<Eigen::Vector2d>& x1,
                               const std::vector<Eigen::Vector2d>& x2);
// x2^T F x1 = 0 from >= 8 correspondences (normalised 8-point, rank 2 enforced).
Eigen::Matrix3d fundamental_8point(const std::vector<Eigen::Vector2d>& x1,
                                   const std::vector<Eigen::Vector2d>& x2);

struct ModelScore {
  double score = 0;
  int n_inliers = 0;
  std::vector<bool> inliers;  // within the threshold in both images
};

// Symmetric transfer errors (H: point to point; F: point to epipolar line) in both images.
// must_beat: scoring stops once the score can no longer exceed it (each correspondence adds
// at most 2 gamma, its weights being inverse variances, >= 0); the score returned is then
// below must_beat and its inliers incomplete.
// A model that can still exceed it is scored to the end, to the same result as without it.
// RANSAC passes its best score so far: the same winner as scoring every sample set's model
// to the end.
ModelScore score_homography(const Eigen::Matrix3d& H21, const Correspondences& c, double chi2,
                            double gamma, double must_beat = -std::numeric_limits<double>::infinity());
ModelScore score_fundamental(const Eigen::Matrix3d& F21, const Correspondences& c, double chi2,
                             double gamma, double must_beat = -std::numeric_limits<double>::infinity());

// RANSAC over the given sample sets (indices into c, 8 each; H takes the first
// o.homography_sample of them); model = the best minimal-set model. Score 0 when none fits.
ModelScore ransac_homography(const Correspondences& c, const std::vector<std::vector<int>>& samples,
                             const TwoViewOptions& o, Eigen::Matrix3d& model);
ModelScore ransac_fundamental(const Correspondences& c,
                              const std::vector<std::vector<int>>& samples,
                              const TwoViewOptions& o, Eigen::Matrix3d& model);

// Ours (TwoViewOptions::refine_with_inliers): refits model on the inliers of start (least
// squares DLT for H; 8-point weighted by the previous model's Sampson weights for F), up to
// 5 times, while the score does not drop; returns the final score.
ModelScore refine_homography(const Correspondences& c, const ModelScore& start,
                             const TwoViewOptions& o, Eigen::Matrix3d& model);
ModelScore refine_fundamental(const Correspondences& c, const ModelScore& start,
                              const TwoViewOptions& o, Eigen::Matrix3d& model);

// One motion hypothesis: X2 = R X1 + t (|t| = 1); n: plane normal (homography only).
struct Motion {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
};

// Faugeras & Lustman: the 8 hypotheses of H21 (pixels) given K; empty when two singular
// values of K^-1 H K coincide (no translation, or a degenerate case).
std::vector<Motion> decompose_homography(const Eigen::Matrix3d& H21, const Eigen::Matrix3d& K);
// The 4 hypotheses (R1|R2) x (+t|-t) of an essential matrix.
std::vector<Motion> decompose_essential(const Eigen::Matrix3d& E21);

// Linear (DLT) triangulation from normalised image coordinates (K^-1 x) of the reference
// camera [I|0] and the current one [R|t], |t| = 1 as the hypotheses have it (solved on
// the normal equations: core/triangulation.h); false when the point is at infinity.
bool triangulate(const Eigen::Vector2d& xn1, const Eigen::Vector2d& xn2,
                 const Eigen::Matrix3d& R, const Eigen::Vector3d& t, Eigen::Vector3d& X);

// Triangulation of the inliers under one hypothesis.
struct MotionCheck {
  int n_good = 0;                       // finite, in front (unless nearly no parallax),
                                        // reprojection within threshold in both views
  std::vector<Eigen::Vector3d> points;  // per correspondence; zero where not triangulated
  std::vector<bool> triangulated;       // good and parallax above ~0.36 deg
  std::vector<double> parallax_deg;     // of the good points
  bool abandoned = false;               // stopped at give_up_at: n_good and the rest partial
};
// give_up_at >= 0: stop as soon as n_good plus the inliers still to check is at
// most give_up_at (the hypothesis can no longer have more good points than that).
MotionCheck check_motion(const Motion& m, const Eigen::Matrix3d& K, const Correspondences& c,
                         const std::vector<bool>& inliers, double reproj_chi2, int give_up_at = -1);

// Checks every hypothesis and accepts the clear winner (ok, R_cr, t_cr, points,
// triangulated, n_good, median_parallax_deg and reason of out are set).
void select_motion(const std::vector<Motion>& hypotheses, const Eigen::Matrix3d& K,
                   const Correspondences& c, const ModelScore& model, const TwoViewOptions& o,
                   TwoViewResult& out);

}  // namespace two_view
}  // namespace dynaorb::tracking
