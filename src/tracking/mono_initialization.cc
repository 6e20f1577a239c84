// Tracking: monocular map initialisation (ORB-SLAM, T-RO 2015, Sec. IV, as
// ORB-SLAM2's MonocularInitialization / CreateInitialMapMonocular). The first
// frame with enough keypoints is the reference; later frames are matched to
// it by SearchForInitialization until two views give a clear H / F
// reconstruction with parallax (TwoViewInitializer). The two keyframes and
// the triangulated points then go through a global BA, the map is scaled to
// a median scene depth of 1 in the first keyframe, and both keyframes go to
// the local mapper.
#include <algorithm>
#include <string>

#include "dynaorb/optimize/bundle_adjuster.h"
#include "dynaorb/tracking/tracker.h"

namespace dynaorb::tracking {

using map::Frame;
using map::KeyFrame;
using map::MapPoint;

bool Tracker::initialize_mono(Frame& f) {
  if (!init_reference_.features) {
    // A new reference (ORB-SLAM2: more than 100 keypoints).
    if (f.size() > o_.mono_init_min_keypoints) {
      init_reference_ = f;
      init_prev_matched_.clear();
      init_status_ = "new reference frame";
    } else {
      init_status_ = "too few keypoints for a reference (" + std::to_string(f.size()) + ")";
    }
    return false;
  }
  if (f.size() <= o_.mono_init_min_keypoints) {
    init_reference_ = Frame();  // ORB-SLAM2 drops the reference too
    init_status_ = "too few keypoints (" + std::to_string(f.size()) + "), reference dropped";
    return false;
  }
  const Frame& ref = init_reference_;
  std::vector<int> matches12;
  const int n = matcher_.search_for_initialization(ref.f(), f.f(), init_prev_matched_, matches12,
                                                   o_.mono_init_window, o_.mono_init_nn_ratio);
  if (n < o_.mono_init_min_matches) {
    // Too few matches: start again. ORB-SLAM2 takes the next frame as the
    // reference; we take this one, which is as good and one frame earlier.
    init_reference_ = f;
    init_prev_matched_.clear();
    init_status_ = "new reference frame: " + std::to_string(n) + " matches to the last one < " +
                   std::to_string(o_.mono_init_min_matches);
    return false;
  }
  const map::Calibration& c = f.calib();
  const Eigen::Matrix3d K = c.K_eigen();
  auto pixels = [&c](const map::Features& fs, std::vector<Eigen::Vector2d>& uv, std::vector<double>& s2) {
    uv.resize(fs.size());
    s2.resize(fs.size());
    for (int i = 0; i < fs.size(); ++i) {
      uv[i] = {fs.keys_un[i].pt.x, fs.keys_un[i].pt.y};
      s2[i] = c.scale.sigma2[fs.keys_un[i].octave];
    }
  };
  std::vector<Eigen::Vector2d> uv_ref, uv_cur;
  std::vector<double> s2_ref, s2_cur;
  pixels(ref.f(), uv_ref, s2_ref);
  pixels(f.f(), uv_cur, s2_cur);
  std::vector<TwoViewMatch> matches;
  matches.reserve(n);
  for (int i = 0; i < static_cast<int>(matches12.size()); ++i)
    if (matches12[i] >= 0) matches.emplace_back(i, matches12[i]);
  const TwoViewInitializer initializer(o_.two_view);
  const TwoViewResult r = initializer.initialize(K, uv_ref, uv_cur, matches, s2_ref, s2_cur);
  if (!r.ok) {  // not yet: keep the reference, try the next frame
    init_status_ = std::to_string(n) + " matches: " + r.reason;
    return false;
  }
  return create_initial_map_mono(f, matches, r);
}

bool Tracker::create_initial_map_mono(Frame& f, const std::vector<TwoViewMatch>& matches,
                                      const TwoViewResult& two_view) {
  Frame& ref = init_reference_;
  ref.set_pose(Eigen::Isometry3d::Identity());
  Eigen::Isometry3d T_cr = Eigen::Isometry3d::Identity();
  T_cr.linear() = two_view.R_cr;
  T_cr.translation() = two_view.t_cr;
  f.set_pose(T_cr);
  auto kf_ini = std::make_shared<KeyFrame>(map_.new_keyframe_id(), ref.id, ref.stamp, ref.features, ref.T_cw);
  auto kf_cur = std::make_shared<KeyFrame>(map_.new_keyframe_id(), f.id, f.stamp, f.features, f.T_cw);
  map_.add_keyframe(kf_ini);
  map_.add_keyframe(kf_cur);
  std::fill(f.points.begin(), f.points.end(), nullptr);
  std::fill(f.outlier.begin(), f.outlier.end(), false);
  std::vector<std::shared_ptr<MapPoint>> points;
  std::vector<std::pair<int, int>> point_matches;
  for (size_t k = 0; k < matches.size(); ++k) {
    if (!two_view.triangulated[k]) continue;
    const auto [i_ref, i_cur] = matches[k];
    auto p = std::make_shared<MapPoint>(map_.new_point_id(), two_view.points[k], kf_ini.get(), kf_ini->id);
    map_.add_observation(*kf_ini, i_ref, p);
    map_.add_observation(*kf_cur, i_cur, p);
    p->compute_distinctive_descriptor();
    p->update_normal_and_depth();
    map_.add_point(p);
    points.push_back(p);
    point_matches.emplace_back(i_ref, i_cur);
  }
  kf_ini->update_connections();
  kf_cur->update_connections();

  // Global BA of both keyframes (the first one fixed) and all points.
  const map::Calibration& c = f.calib();
  optimize::BaProblem problem;
  problem.K = {c.fx, c.fy, c.cx, c.cy, 0.0};
  problem.keyframes = {{kf_ini->T_cw(), true}, {kf_cur->T_cw(), false}};
  problem.points.reserve(points.size());
  for (size_t k = 0; k < points.size(); ++k) {
    problem.points.push_back(points[k]->position());
    const int idx[2] = {point_matches[k].first, point_matches[k].second};
    const KeyFrame* kfs[2] = {kf_ini.get(), kf_cur.get()};
    for (int v = 0; v < 2; ++v) {
      const cv::KeyPoint& kp = kfs[v]->f().keys_un[idx[v]];
      optimize::BaObservation ob;
      ob.keyframe = v;
      ob.point = static_cast<int>(k);
      ob.obs.uv = {kp.pt.x, kp.pt.y};
      ob.obs.inv_sigma2 = c.scale.inv_sigma2[kp.octave];
      problem.observations.push_back(ob);
    }
  }
  optimize::BaOptions ba;
  ba.iterations_first = o_.mono_init_ba_iterations;  // ORB-SLAM2: one robust pass of 20
  ba.iterations_second = 0;
  const optimize::BaResult solved = optimize::bundle_adjust(problem, ba);
  kf_cur->set_pose(solved.T_cw[1]);
  // As ORB-SLAM2, every point stays (tracking's outlier rejection and the
  // mapper's culling deal with the bad ones): BA outliers are not removed.
  for (size_t k = 0; k < points.size(); ++k) points[k]->set_position(solved.points[k]);

  // Scale: median depth of the first keyframe's points = 1.
  const double median = kf_ini->median_depth(0.5);
  if (median <= 0 || kf_cur->tracked_points(1) < o_.mono_init_min_tracked) {
    // A bad initialisation: drop the map and start again from this frame
    // (ORB-SLAM2 resets and takes the next one).
    init_status_ = "map refused after BA (median depth " + std::to_string(median) + ", " +
                   std::to_string(kf_cur->tracked_points(1)) + " points, at least " +
                   std::to_string(o_.mono_init_min_tracked) + " needed); new reference frame";
    map_.clear();
    init_reference_ = f;
    init_prev_matched_.clear();
    std::fill(f.points.begin(), f.points.end(), nullptr);
    return false;
  }
  const double inv_median = 1.0 / median;
  Eigen::Isometry3d T = kf_cur->T_cw();
  T.translation() *= inv_median;
  kf_cur->set_pose(T);
  for (const auto& p : points) {
    if (p->erased()) continue;
    p->set_position(p->position() * inv_median);
    p->update_normal_and_depth();
  }
  kf_ini->update_connections();
  kf_cur->update_connections();

  // The current frame tracks the surviving points from the second keyframe.
  f.set_pose(T);
  for (int i = 0; i < f.size(); ++i) {
    const auto& p = kf_cur->point(i);
    if (p && !p->erased()) f.points[i] = p;
  }
  f.reference = kf_cur;
  // The first keyframe goes to the local mapper now, the second through the
  // outcome (track() returns it as the new keyframe).
  mapper_.insert_keyframe(kf_ini);
  start_tracking(f, {kf_cur, kf_ini});
  init_frame_id_ = f.id;
  init_features_released_ = false;
  init_reference_ = Frame();
  init_prev_matched_.clear();
  return true;
}

}  // namespace dynaorb::tracking

