// Tracking: bags of words and relocalisation (ORB-SLAM Sec. V-C; ORB-SLAM2's
// Tracking::Relocalization). Runs under the map lock, like the rest of track().
#include <algorithm>

#include "dynaorb/tracking/tracker.h"

namespace dynaorb::tracking {

using map::Frame;
using map::KeyFrame;

void Tracker::compute_bow(Frame& f) const {
  if (vocabulary_ && !f.bow) f.bow = map::BagOfWords::compute(*vocabulary_, f.f());
}

void Tracker::compute_bow(KeyFrame& kf) const {
  // Local mapping computes it on insertion; a keyframe still in its queue gets it here.
  if (vocabulary_ && !kf.bow()) kf.set_bow(map::BagOfWords::compute(*vocabulary_, kf.f()));
}

void Tracker::clear_matches(Frame& f) const {
  std::fill(f.points.begin(), f.points.end(), nullptr);
  std::fill(f.outlier.begin(), f.outlier.end(), false);
}

bool Tracker::relocalize(Frame& f) {
  if (!database_ || f.size() == 0) return false;
  compute_bow(f);
  if (f.bow->words.empty()) return false;
  std::vector<KeyFrame*> candidates;
  for (const place::PlaceCandidate& c : database_->relocalization_candidates(f.bow->words))
    candidates.push_back(c.keyframe);
  if (o_.reloc.try_last_reference && last_.reference) {
    // A reference culled meanwhile stands for its parent (as the trajectory does).
    KeyFrame* ref = last_.reference.get();
    while (ref && ref->erased()) ref = ref->parent();
    if (ref && std::find(candidates.begin(), candidates.end(), ref) == candidates.end())
      candidates.push_back(ref);
  }
  for (KeyFrame* kf : candidates) {
    if (kf->erased()) continue;
    compute_bow(*kf);
    if (relocalize_from(f, *kf)) {
      last_reloc_frame_ = f.id;
      return true;
    }
  }
  clear_matches(f);
  return false;
}

bool Tracker::relocalize_from(Frame& f, const KeyFrame& kf) {
  const RelocalizationOptions& o = o_.reloc;
  const map::Calibration& c = f.calib();
  clear_matches(f);
  if (!kf.bow() || matcher_.search_by_bow(kf, f, o.bow_ratio) < o.min_bow_matches) return false;

  // PnP RANSAC on the 2-D / 3-D matches; only its inliers stay matched.
  std::vector<place::PnpMatch> matches;
  std::vector<int> slot;
  for (int i = 0; i < f.size(); ++i) {
    if (!f.points[i]) continue;
    const cv::KeyPoint& k = f.f().keys_un[i];
    matches.push_back({f.points[i]->position(), Eigen::Vector2d(k.pt.x, k.pt.y), c.scale.sigma2[k.octave]});
    slot.push_back(i);
  }
  const place::PnpRansacResult pnp = place::pnp_ransac(matches, {c.fx, c.fy, c.cx, c.cy}, o.pnp);
  if (!pnp.ok) return false;
  f.set_pose(pnp.T_cw);
  for (size_t k = 0; k < slot.size(); ++k)
    if (!pnp.inlier[k]) f.points[slot[k]].reset();

  // Motion-only BA; too few inliers: more points of the candidate by
  // projection, first in a wide window, then (from the better pose) a narrow one.
  int good = optimize_pose(f);
  if (good < o.min_pose_inliers) return false;
  if (good < o.min_inliers) {
    // BA outliers keep their slots meanwhile, so the searches do not match them again.
    const int extra = matcher_.search_by_projection(f, kf, o.wide_window, o.wide_max_distance);
    if (good + extra >= o.min_inliers) {
      good = optimize_pose(f);
      if (good > o.narrow_after && good < o.min_inliers) {
        const int more = matcher_.search_by_projection(f, kf, o.narrow_window, o.narrow_max_distance);
        if (good + more >= o.min_inliers) good = optimize_pose(f);
      }
    }
  }
  discard_outliers(f);
  return good >= o.min_inliers;
}

}  // namespace dynaorb::tracking
