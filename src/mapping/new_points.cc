// Local mapping: new map points from covisible keyframe pairs, and fusion
// of duplicates with the neighbours (ORB-SLAM Sec. VI-D and VI-C).
#include <Eigen/SVD>
#include <cmath>
#include <set>

#include "dynaorb/mapping/local_mapper.h"
#include "dynaorb/match/matcher.h"
#include "dynaorb/core/triangulation.h"

namespace dynaorb::mapping {

using map::KeyFrame;
using map::MapPoint;

namespace {

// Reprojection check of a new point in one keyframe (chi2 at 95 %).
bool reprojects(const KeyFrame& kf, int i, const Eigen::Vector3d& X) {
  const Eigen::Vector3d pc = kf.T_cw() * X;
  if (pc.z() <= 0) return false;
  const map::Calibration& c = kf.calib();
  const cv::KeyPoint& k = kf.f().keys_un[i];
  const Eigen::Vector2d uv = c.project(pc);
  const double ex = uv.x() - k.pt.x, ey = uv.y() - k.pt.y;
  const double s2 = c.scale.sigma2[k.octave];
  const float ur = kf.f().u_right[i];
  if (ur < 0) return ex * ex + ey * ey <= 5.991 * s2;
  const double er = uv.x() - c.bf / pc.z() - ur;
  return ex * ex + ey * ey + er * er <= 7.8 * s2;
}

}  // namespace

// The pairs are searched without the map lock, so that tracking is not held
// up by the descriptor comparisons (most of local mapping's time: 30-55 ms a
// keyframe on KITTI 06 at 2000 features, while tracking waited up to 45 ms
// for the map). The search reads the two keyframes' features and bag of
// words, which never change, and their poses and point slots, which change
// only on this thread while it works on a keyframe: tracking fills the slots
// of the keyframe it is making only, and loop correction, global BA and a
// map reset wait for local mapping to be idle (pause, clear_queue). The
// neighbours are held, and they and the slots are checked again under the
// lock all the same.
void LocalMapper::create_new_points(const std::shared_ptr<KeyFrame>& kf_ptr) {
  const bool mono = sensor_ == Sensor::kMono;
  const match::Matcher matcher;
  std::unique_lock<std::mutex> lk(map_.mutex());
  if (kf_ptr->erased()) return;
  KeyFrame& kf1 = *kf_ptr;
  std::vector<std::shared_ptr<KeyFrame>> neighbors;
  for (KeyFrame* k : kf1.covisibles(mono ? o_.neighbors_mono : o_.neighbors_stereo))
    if (auto held = map_.keyframe(k->id)) neighbors.push_back(std::move(held));
  const map::Calibration& c = kf1.calib();
  const map::ScalePyramid& s = c.scale;
  const double ratio_factor = 1.5 * s.scale_factor;
  const Eigen::Vector3d C1 = kf1.center();
  Eigen::Matrix<double, 3, 4> P1 = kf1.T_cw().matrix().topRows<3>();
  const Eigen::Matrix3d Rwc1 = kf1.T_wc().rotation();
  int created = 0;
  for (size_t n = 0; n < neighbors.size(); ++n) {
    if (n > 0 && has_new_keyframes()) break;  // give way to tracking (ORB-SLAM)
    KeyFrame& kf2 = *neighbors[n];
    const Eigen::Vector3d C2 = kf2.center();
    const double baseline = (C2 - C1).norm();
    if (!mono) {
      if (baseline < c.baseline) continue;
    } else {
      const double median = kf2.median_depth(0.5);
      if (median <= 0 || baseline / median < 0.01) continue;
    }
    const bool by_bow = mono ? o_.triangulation_bow_mono : o_.triangulation_bow_stereo;
    const Eigen::Matrix3d F12 = match::Matcher::fundamental(kf1, kf2);
    lk.unlock();
    const std::vector<std::pair<int, int>> pairs = matcher.search_for_triangulation(kf1, kf2, F12, by_bow);
    lk.lock();
    if (kf1.erased()) break;
    if (kf2.erased()) continue;
    Eigen::Matrix<double, 3, 4> P2 = kf2.T_cw().matrix().topRows<3>();
    const Eigen::Matrix3d Rwc2 = kf2.T_wc().rotation();
    for (const auto& [i1, i2] : pairs) {
      if (kf1.point(i1) || kf2.point(i2)) continue;
      const cv::KeyPoint& k1 = kf1.f().keys_un[i1];
      const cv::KeyPoint& k2 = kf2.f().keys_un[i2];
      const bool stereo1 = kf1.f().u_right[i1] >= 0, stereo2 = kf2.f().u_right[i2] >= 0;
      const Eigen::Vector3d x1((k1.pt.x - c.cx) * c.inv_fx, (k1.pt.y - c.cy) * c.inv_fy, 1.0);
      const Eigen::Vector3d x2((k2.pt.x - c.cx) * c.inv_fx, (k2.pt.y - c.cy) * c.inv_fy, 1.0);
      const Eigen::Vector3d ray1 = Rwc1 * x1, ray2 = Rwc2 * x2;
      const double cos_rays = ray1.dot(ray2) / (ray1.norm() * ray2.norm());
      // Parallax a stereo pair gives at the measured depth: triangulate from
      // the two views only when they see the point under a wider angle.
      const double cos_st1 = stereo1 ? std::cos(2 * std::atan2(c.baseline / 2, kf1.f().depth[i1])) : 2.0;
      const double cos_st2 = stereo2 ? std::cos(2 * std::atan2(c.baseline / 2, kf2.f().depth[i2])) : 2.0;
      const double cos_st = std::min(cos_st1, cos_st2);
      Eigen::Vector3d X;
      if (cos_rays < cos_st && cos_rays > 0 && (stereo1 || stereo2 || cos_rays < 0.9998)) {
        if (!triangulate_dlt(x1.head<2>(), P1, x2.head<2>(), P2, X)) continue;
      } else if (stereo1 && cos_st1 < cos_st2) {
        X = kf1.unproject(i1);
      } else if (stereo2 && cos_st2 < cos_st1) {
        X = kf2.unproject(i2);
      } else {
        continue;  // no parallax
      }
      if (!reprojects(kf1, i1, X) || !reprojects(kf2, i2, X)) continue;
      // Scale consistency: distance ratio agrees with the octave ratio.
      const double d1 = (X - C1).norm(), d2 = (X - C2).norm();
      if (d1 == 0 || d2 == 0) continue;
      const double ratio_dist = d2 / d1;
      const double ratio_octave = s.scale[k1.octave] / s.scale[k2.octave];
      if (ratio_dist * ratio_factor < ratio_octave || ratio_dist > ratio_octave * ratio_factor) continue;
      auto p = std::make_shared<MapPoint>(map_.new_point_id(), X, &kf1, kf1.id);
      map_.add_observation(kf1, i1, p);
      map_.add_observation(kf2, i2, p);
      p->compute_distinctive_descriptor();
      p->update_normal_and_depth();
      map_.add_point(p);
      recent_points_.push_back(p);
      ++created;
    }
  }
  std::lock_guard<std::mutex> c_lk(queue_mutex_);
  counters_.points_created += created;
}

void LocalMapper::fuse_with_neighbors(KeyFrame& kf) {
  const bool mono = sensor_ == Sensor::kMono;
  const match::Matcher matcher;
  // First and second neighbours in the covisibility graph.
  std::vector<KeyFrame*> targets;
  std::set<const KeyFrame*> seen{&kf};
  auto visit = [&](KeyFrame* n) {
    if (!n->erased() && seen.insert(n).second) targets.push_back(n);
  };
  for (KeyFrame* n : kf.covisibles(mono ? o_.neighbors_mono : o_.neighbors_stereo)) {
    visit(n);
    for (KeyFrame* n2 : n->covisibles(5)) visit(n2);
  }
  int fused = 0;
  std::vector<std::shared_ptr<MapPoint>> own;
  for (const auto& p : kf.points())
    if (p && !p->erased()) own.push_back(p);
  for (KeyFrame* t : targets) fused += matcher.fuse(map_, *t, own);

  std::vector<std::shared_ptr<MapPoint>> candidates;
  for (KeyFrame* t : targets) {
    for (const auto& p : t->points()) {
      if (!p || p->erased() || p->fuse_keyframe == kf.id) continue;
      p->fuse_keyframe = kf.id;
      candidates.push_back(p);
    }
  }
  fused += matcher.fuse(map_, kf, candidates);

  for (const auto& p : kf.points()) {
    if (!p || p->erased()) continue;
    p->compute_distinctive_descriptor();
    p->update_normal_and_depth();
  }
  kf.update_connections();
  std::lock_guard<std::mutex> lk(queue_mutex_);
  counters_.points_fused += fused;
}

}  // namespace dynaorb::mapping
