#include "dynaorb/match/matcher.h"

#include <climits>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_set>

#include "dynaorb/map/point_view.h"
#include "dynaorb/match/hamming.h"
#include "epipolar_band.h"
#include "rotation_histogram.h"

namespace dynaorb::match {

using map::Frame;
using map::KeyFrame;
using map::MapPoint;

namespace {

// A slot already holds a point that some keyframe observes: leave it alone.
bool slot_taken(const Frame& f, int i) {
  const auto& p = f.points[i];
  return p && !p->erased() && p->observation_count() > 0;
}


void drop_rejected(Frame& cur, const RotationHistogram& h, int& n) {
  for (int i : h.rejected()) {
    cur.points[i].reset();
    --n;
  }
}

}  // namespace

int Matcher::search_by_projection(Frame& cur, const Frame& last, double th) const {
  const map::Calibration& c = cur.calib();
  const map::Features& fc = cur.f();
  const map::Features& fl = last.f();
  RotationHistogram hist(o_.histogram_bins);
  // Direction of motion along the optical axis, for stereo only (ORB-SLAM2).
  const Eigen::Vector3d t_lc = last.T_cw * cur.center();
  const bool forward = c.sensor != Sensor::kMono && t_lc.z() > c.baseline;
  const bool backward = c.sensor != Sensor::kMono && -t_lc.z() > c.baseline;
  int n = 0;
  std::vector<int> cand;
  for (int i = 0; i < last.size(); ++i) {
    const auto& p = last.points[i];
    if (!p || last.outlier[i] || p->erased()) continue;
    const Eigen::Vector3d pc = cur.T_cw * p->position();
    if (pc.z() <= 0) continue;
    const Eigen::Vector2d uv = c.project(pc);
    if (!c.in_image(uv)) continue;
    const int level = fl.keys_un[i].octave;
    const double radius = th * c.scale.scale[level];
    if (forward) fc.in_area(uv.x(), uv.y(), radius, level, -1, cand);
    else if (backward) fc.in_area(uv.x(), uv.y(), radius, 0, level, cand);
    else fc.in_area(uv.x(), uv.y(), radius, std::max(0, level - 1), level + 1, cand);
    int best = INT_MAX, best_i = -1;
    const double ur = uv.x() - c.bf / pc.z();
    for (int j : cand) {
      if (slot_taken(cur, j)) continue;
      if (fc.u_right[j] > 0 && std::abs(ur - fc.u_right[j]) > radius) continue;
      const int d = hamming(p->descriptor_data(), fc.descriptor(j));
      if (d < best) {
        best = d;
        best_i = j;
      }
    }
    if (best > o_.th_high) continue;
    cur.points[best_i] = p;
    ++n;
    if (o_.check_orientation) hist.add(best_i, fl.keys_un[i].angle, fc.keys_un[best_i].angle);
  }
  if (o_.check_orientation) drop_rejected(cur, hist, n);
  return n;
}

int Matcher::search_local_points(Frame& cur, const std::vector<std::shared_ptr<MapPoint>>& points,
                                 double th, double nn_ratio) const {
  const map::Calibration& c = cur.calib();
  const map::Features& fc = cur.f();
  int n = 0;
  std::vector<int> cand;
  for (const auto& p : points) {
    if (p->erased() || p->track.in_view_frame != cur.id || p->track.matched_frame == cur.id) continue;
    const int level = p->track.predicted_level;
    // A wider window when the point is seen obliquely (ORB-SLAM's RadiusByViewingCos).
    const double r = (p->track.view_cos > 0.998 ? 2.5 : 4.0) * th * c.scale.scale[level];
    fc.in_area(p->track.proj_x, p->track.proj_y, r, level - 1, level, cand);
    int best = INT_MAX, second = INT_MAX, best_level = -1, second_level = -1, best_i = -1;
    for (int j : cand) {
      if (slot_taken(cur, j)) continue;
      if (fc.u_right[j] > 0 && std::abs(p->track.proj_xr - fc.u_right[j]) > r * c.scale.scale[level])
        continue;
      const int d = hamming(p->descriptor_data(), fc.descriptor(j));
      if (d < best) {
        second = best;
        second_level = best_level;
        best = d;
        best_level = fc.keys_un[j].octave;
        best_i = j;
      } else if (d < second) {
        second = d;
        second_level = fc.keys_un[j].octave;
      }
    }
    if (best > o_.th_high) continue;
    if (best_level == second_level && best > nn_ratio * second) continue;
    cur.points[best_i] = p;
    ++n;
  }
  return n;
}

int Matcher::search_keyframe(const KeyFrame& kf, Frame& cur, double nn_ratio) const {
  const map::Features& fk = kf.f();
  const map::Features& fc = cur.f();
  RotationHistogram hist(o_.histogram_bins);
  std::vector<int> best_for(cur.size(), INT_MAX);
  int n = 0;
  for (int i = 0; i < fk.size(); ++i) {
    const auto& p = kf.point(i);
    if (!p || p->erased()) continue;
    int best = INT_MAX, second = INT_MAX, best_j = -1;
    for (int j = 0; j < fc.size(); ++j) {
      const int d = hamming(fk.descriptor(i), fc.descriptor(j));
      if (d < best) {
        second = best;
        best = d;
        best_j = j;
      } else if (d < second) {
        second = d;
      }
    }
    if (best > o_.th_low || best > nn_ratio * second) continue;
    if (cur.points[best_j]) {
      if (best >= best_for[best_j]) continue;  // keep the closer of two claims
      --n;
    }
    best_for[best_j] = best;
    cur.points[best_j] = p;
    ++n;
    if (o_.check_orientation) hist.add(best_j, fk.keys_un[i].angle, fc.keys_un[best_j].angle);
  }
  if (o_.check_orientation) {
    for (int j : hist.rejected()) {
      if (cur.points[j] && best_for[j] != INT_MAX) {
        cur.points[j].reset();
        best_for[j] = INT_MAX;
        --n;
      }
    }
  }
  return n;
}

int Matcher::search_by_bow(const KeyFrame& kf, Frame& cur, double nn_ratio) const {
  if (!kf.bow() || !cur.bow)
    throw std::invalid_argument("Matcher::search_by_bow: keyframe " + std::to_string(kf.id) + " and frame " +
                                std::to_string(cur.id) + " both need a bag of words");
  const map::Features& fk = kf.f();
  const map::Features& fc = cur.f();
  RotationHistogram hist(o_.histogram_bins);
  int n = 0;
  vocab::for_each_shared_key(kf.bow()->nodes, cur.bow->nodes, [&](const auto& node_k, const auto& node_c) {
    for (const unsigned i : node_k) {
      const auto& p = kf.point(static_cast<int>(i));
      if (!p || p->erased()) continue;
      int best = INT_MAX, second = INT_MAX, best_j = -1;
      for (const unsigned j : node_c) {
        if (cur.points[j]) continue;
        const int d = hamming(fk.descriptor(static_cast<int>(i)), fc.descriptor(static_cast<int>(j)));
        if (d < best) {
          second = best;
          best = d;
          best_j = static_cast<int>(j);
        } else if (d < second) {
          second = d;
        }
      }
      if (best_j < 0 || best > o_.th_low || best >= nn_ratio * second) continue;
      cur.points[best_j] = p;
      cur.outlier[best_j] = false;
      ++n;
      if (o_.check_orientation) hist.add(best_j, fk.keys_un[i].angle, fc.keys_un[best_j].angle);
    }
  });
  if (o_.check_orientation) drop_rejected(cur, hist, n);
  return n;
}

int Matcher::search_by_projection(Frame& cur, const KeyFrame& kf, double th, int max_distance) const {
  const map::Calibration& c = cur.calib();
  const map::Features& fc = cur.f();
  const map::Features& fk = kf.f();
  const Eigen::Vector3d center = cur.center();
  std::unordered_set<const MapPoint*> found;
  for (const auto& p : cur.points)
    if (p) found.insert(p.get());
  RotationHistogram hist(o_.histogram_bins);
  int n = 0;
  std::vector<int> cand;
  for (int i = 0; i < fk.size(); ++i) {
    const auto& p = kf.point(i);
    if (!p || p->erased() || found.count(p.get())) continue;
    // Any viewing angle (ORB-SLAM checks none here).
    const std::optional<map::PointView> v = map::view_point(c, cur.T_cw, center, *p, -2.0);
    if (!v) continue;
    const int level = v->predicted_level;
    const double radius = th * c.scale.scale[level];
    int best = INT_MAX, best_j = -1;
    fc.in_area(v->uv.x(), v->uv.y(), radius, std::max(0, level - 1), level + 1, cand);
    for (int j : cand) {
      if (cur.points[j]) continue;
      const int d = hamming(p->descriptor_data(), fc.descriptor(j));
      if (d < best) {
        best = d;
        best_j = j;
      }
    }
    if (best_j < 0 || best > max_distance) continue;
    cur.points[best_j] = p;
    cur.outlier[best_j] = false;
    ++n;
    if (o_.check_orientation) hist.add(best_j, fk.keys_un[i].angle, fc.keys_un[best_j].angle);
  }
  if (o_.check_orientation) drop_rejected(cur, hist, n);
  return n;
}

Eigen::Matrix3d Matcher::fundamental(const KeyFrame& kf1, const KeyFrame& kf2) {
  const Eigen::Isometry3d T12 = kf1.T_cw() * kf2.T_wc();
  const Eigen::Vector3d& t = T12.translation();
  Eigen::Matrix3d t_x;
  t_x << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return kf1.calib().K_eigen().inverse().transpose() * t_x * T12.rotation() * kf2.calib().K_eigen().inverse();
}

std::vector<std::pair<int, int>> Matcher::search_for_triangulation(const KeyFrame& kf1,
                                                                   const KeyFrame& kf2,
                                                                   const Eigen::Matrix3d& F12,
                                                                   bool by_bow) const {
  const map::Features& f1 = kf1.f();
  const map::Features& f2 = kf2.f();
  const map::ScalePyramid& s = kf1.calib().scale;
  // Epipole of kf1's centre in kf2: matches too close to it are ill-conditioned.
  const Eigen::Vector3d c1_in_2 = kf2.T_cw() * kf1.center();
  const Eigen::Vector2d ep = kf2.calib().project(c1_in_2);
  std::vector<int> match12(f1.size(), -1), best_for2(f2.size(), INT_MAX), owner2(f2.size(), -1);
  RotationHistogram hist(o_.histogram_bins);
  // The best kf2 keypoint for kf1's keypoint i among the candidates.
  auto match_one = [&](int i, const auto& candidates) {
    if (kf1.point(i)) return;
    const cv::KeyPoint& k1 = f1.keys_un[i];
    const bool stereo1 = f1.u_right[i] >= 0;
    const Eigen::Vector3d line = Eigen::Vector3d(k1.pt.x, k1.pt.y, 1.0).transpose() * F12;
    const double norm2 = line.x() * line.x() + line.y() * line.y();
    if (norm2 == 0) return;
    int best = o_.th_low + 1, best_j = -1;
    for (const auto jj : candidates) {
      const int j = static_cast<int>(jj);
      if (kf2.point(j)) continue;
      const int d = hamming(f1.descriptor(i), f2.descriptor(j));
      if (d >= best) continue;
      const cv::KeyPoint& k2 = f2.keys_un[j];
      const double num = line.x() * k2.pt.x + line.y() * k2.pt.y + line.z();
      if (num * num / norm2 >= 3.84 * s.sigma2[k2.octave]) continue;
      if (!stereo1 && f2.u_right[j] < 0) {
        const double dx = ep.x() - k2.pt.x, dy = ep.y() - k2.pt.y;
        if (c1_in_2.z() > 0 && dx * dx + dy * dy < 100 * s.scale[k2.octave]) continue;
      }
      best = d;
      best_j = j;
    }
    if (best_j < 0) return;
    if (owner2[best_j] >= 0) {  // kf2 keypoint claimed twice: the closer descriptor wins
      if (best >= best_for2[best_j]) return;
      match12[owner2[best_j]] = -1;
    }
    owner2[best_j] = i;
    best_for2[best_j] = best;
    match12[i] = best_j;
    if (o_.check_orientation) hist.add(i, k1.angle, f2.keys_un[best_j].angle);
  };
  if (by_bow && kf1.bow() && kf2.bow()) {
    // ORB-SLAM's SearchForTriangulation: compare only keypoints under the
    // same vocabulary node (the direct index).
    vocab::for_each_shared_key(kf1.bow()->nodes, kf2.bow()->nodes, [&](const auto& node1, const auto& node2) {
      for (const unsigned i : node1) match_one(static_cast<int>(i), node2);
    });
  } else {
    // Every pair, but first narrowed to the kf2 keypoints within match_one's epipolar distance
    // by EpipolarBand (the same test, so the same pairs pass, found without testing them all):
    // the band holds a few percent of the keypoints, and its test is a few flops against a
    // descriptor distance. Keypoints with a map point are never candidates.
    std::vector<EpipolarBand::Point> free2;
    for (int j = 0; j < f2.size(); ++j) {
      if (kf2.point(j)) continue;
      const cv::KeyPoint& k2 = f2.keys_un[j];
      free2.push_back({k2.pt.x, k2.pt.y, 3.84 * s.sigma2[k2.octave], j});
    }
    const EpipolarBand band(std::move(free2));
    std::vector<int> near_line;
    for (int i = 0; i < f1.size(); ++i) {
      if (kf1.point(i)) continue;
      const cv::KeyPoint& k1 = f1.keys_un[i];
      band.near(Eigen::Vector3d(k1.pt.x, k1.pt.y, 1.0).transpose() * F12, &near_line);
      match_one(i, near_line);
    }
  }
  if (o_.check_orientation)
    for (int i : hist.rejected()) match12[i] = -1;
  std::vector<std::pair<int, int>> out;
  for (int i = 0; i < f1.size(); ++i)
    if (match12[i] >= 0 && owner2[match12[i]] == i) out.emplace_back(i, match12[i]);
  return out;
}

int Matcher::fuse(map::Map& map, KeyFrame& kf, const std::vector<std::shared_ptr<MapPoint>>& points,
                  double th) const {
  const map::Calibration& c = kf.calib();
  const map::Features& f = kf.f();
  const Eigen::Vector3d center = kf.center();
  int fused = 0;
  std::vector<int> cand;
  for (const auto& p : points) {
    if (!p || p->erased() || p->index_in(&kf) >= 0) continue;
    const std::optional<map::PointView> v = map::view_point(c, kf.T_cw(), center, *p, 0.5);
    if (!v) continue;
    const Eigen::Vector2d& uv = v->uv;
    const double ur = v->u_right;
    const int level = v->predicted_level;
    const double radius = th * c.scale.scale[level];
    int best = INT_MAX, best_j = -1;
    f.in_area(uv.x(), uv.y(), radius, -1, -1, cand);
    for (int j : cand) {
      const cv::KeyPoint& k = f.keys_un[j];
      if (k.octave < level - 1 || k.octave > level) continue;
      const double ex = uv.x() - k.pt.x, ey = uv.y() - k.pt.y;
      double chi2 = ex * ex + ey * ey;
      double limit = 5.99;
      if (f.u_right[j] >= 0) {
        const double er = ur - f.u_right[j];
        chi2 += er * er;
        limit = 7.8;
      }
      if (chi2 * c.scale.inv_sigma2[k.octave] > limit) continue;
      const int d = hamming(p->descriptor_data(), f.descriptor(j));
      if (d < best) {
        best = d;
        best_j = j;
      }
    }
    if (best > o_.th_low) continue;
    const std::shared_ptr<MapPoint> existing = kf.point(best_j);
    if (existing && !existing->erased()) {
      if (existing->observation_count() > p->observation_count()) map.replace_point(p, existing);
      else map.replace_point(existing, p);
    } else {
      map.add_observation(kf, best_j, p);
    }
    ++fused;
  }
  return fused;
}

}  // namespace dynaorb::match
