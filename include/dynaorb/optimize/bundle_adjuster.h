#pragma once
// Local bundle adjustment (ORB-SLAM2's LocalBundleAdjustment) on plain data:
// keyframe poses (some fixed) and points, reprojection residuals (2-D mono,
// 3-D stereo) under a Huber loss; a first pass, then the observations whose
// chi2 exceeds the threshold (or whose point lies behind the camera) are
// excluded and the problem is solved again. Can be aborted from another
// thread (tracking asks for a new keyframe). Observations with an index out
// of range, not usable(), or of a non-finite point or pose are outliers and
// never enter the problem.
#include <atomic>
#include <vector>

#include "dynaorb/optimize/types.h"

namespace dynaorb::optimize {

struct BaKeyframe {
  Eigen::Isometry3d T_cw = Eigen::Isometry3d::Identity();
  bool fixed = false;
};

struct BaObservation {
  int keyframe = 0;  // index into BaProblem::keyframes
  int point = 0;     // index into BaProblem::points
  Observation obs;
};

struct BaProblem {
  Intrinsics K;
  std::vector<BaKeyframe> keyframes;
  std::vector<Eigen::Vector3d> points;  // world coordinates
  std::vector<BaObservation> observations;
};

struct BaOptions {
  int iterations_first = 5;    // ORB-SLAM2: 5 then 10
  int iterations_second = 10;
  double chi2_mono = kChi2Mono;
  double chi2_stereo = kChi2Stereo;
  int num_threads = 1;
  // Linear solver (speed only: both give the same step). The reduced camera system is solved
  // dense (DENSE_SCHUR) for up to dense_schur_max_keyframes free keyframes, and up to
  // dense_schur_cap_keyframes while at least this share of its keyframe-pair blocks is non-zero
  // (split layout: any stereo / RGB-D observation; mono: one block per pose); else sparse
  // (SPARSE_SCHUR, SuiteSparse). Measured in bundle_adjuster.cc.
  int dense_schur_max_keyframes = 60;
  int dense_schur_cap_keyframes = 500;
  double dense_schur_min_fill = 0.2;
  double dense_schur_min_fill_mono = 0.4;
};

struct BaResult {
  std::vector<Eigen::Isometry3d> T_cw;  // per keyframe (fixed ones unchanged)
  std::vector<Eigen::Vector3d> points;
  std::vector<bool> outlier;            // per observation, after the final solve
  bool aborted = false;                 // stopped early by the abort flag
  bool dense_schur = false;             // the last solve's reduced camera system was dense
  double initial_cost = 0, final_cost = 0;
};

BaResult bundle_adjust(const BaProblem& problem, const BaOptions& options = {},
                       const std::atomic<bool>* abort = nullptr);

}  // namespace dynaorb::optimize
