// Tracking: when to insert a keyframe and how (ORB-SLAM2 Sec. III-D/E).
#include <algorithm>

#include "dynaorb/tracking/tracker.h"

namespace dynaorb::tracking {

using map::Frame;
using map::KeyFrame;
using map::MapPoint;

bool Tracker::need_new_keyframe(const Frame& f) const {
  const bool mono = sensor_ == Sensor::kMono;
  const int n_kfs = static_cast<int>(map_.keyframe_count());
  // ORB-SLAM2: not while the pose after a relocalisation settles, unless the map is small.
  if (o_.reloc.pause_keyframes && last_reloc_frame_ >= 0 && f.id < last_reloc_frame_ + o_.max_frames &&
      n_kfs > o_.max_frames)
    return false;
  const int min_obs = n_kfs <= 2 ? 2 : 3;
  const int ref_matches = reference_ ? reference_->tracked_points(min_obs) : 0;
  const bool mapper_idle = mapper_.idle();
  // Close points tracked vs. close points that could become new map points.
  int tracked_close = 0, untracked_close = 0;
  if (!mono) {
    for (int i = 0; i < f.size(); ++i) {
      if (!f.f().is_close(i)) continue;
      if (f.points[i] && !f.outlier[i]) ++tracked_close;
      else ++untracked_close;
    }
  }
  const bool need_close = tracked_close < o_.close_tracked_max && untracked_close > o_.close_untracked_min;
  double ratio = mono ? o_.ref_ratio_mono : o_.ref_ratio_stereo;
  if (n_kfs < 2) ratio = 0.4;
  const bool c1a = f.id >= last_keyframe_frame_ + o_.max_frames;
  const bool c1b = f.id >= last_keyframe_frame_ + o_.min_frames && mapper_idle;
  const bool c1c = !mono && (inliers_ < ref_matches * 0.25 || need_close);
  const bool c2 = (inliers_ < ref_matches * ratio || need_close) && inliers_ > 15;
  if (!((c1a || c1b || c1c) && c2)) return false;
  if (mapper_idle) return true;
  mapper_.interrupt_ba();
  return !mono && mapper_.queued() < 3;
}

std::shared_ptr<KeyFrame> Tracker::create_keyframe(Frame& f) {
  auto kf = std::make_shared<KeyFrame>(map_.new_keyframe_id(), f.id, f.stamp, f.features, f.T_cw);
  if (f.bow) kf->set_bow(f.bow);  // else local mapping computes it
  // Tracked map points: the mapper adds these observations when it inserts the keyframe.
  for (int i = 0; i < f.size(); ++i)
    if (f.points[i] && !f.outlier[i] && !f.points[i]->erased()) kf->set_point(i, f.points[i]);
  if (sensor_ != Sensor::kMono) {
    // New points from the closest depths: every close one, and at least
    // new_keyframe_close_points in all (ORB-SLAM2's CreateNewKeyFrame).
    int n = 0;
    for (const auto& [z, i] : by_depth(f.f())) {
      if (!kf->point(i)) new_point(*kf, f, i);
      ++n;
      if (z > f.calib().th_depth && n > o_.new_keyframe_close_points) break;
    }
  }
  map_.add_keyframe(kf);
  reference_ = kf;
  f.reference = kf;
  last_keyframe_frame_ = f.id;
  return kf;
}

}  // namespace dynaorb::tracking
