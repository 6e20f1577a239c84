// Loop detection: candidates, covisibility consistency, Sim3 / SE3 estimation (ORB-SLAM Sec. VI-A, VI-B).
#include "dynaorb/loop/loop_closer.h"

#include <algorithm>
#include <chrono>
#include <unordered_map>
#include <unordered_set>

#include "dynaorb/map/frame.h"
#include "dynaorb/match/matcher.h"
#include "dynaorb/optimize/bundle_adjuster.h"
#include "dynaorb/optimize/pose_graph.h"
#include "dynaorb/core/stopwatch.h"

#include "loop.h"

namespace dynaorb::loop {

using map::KeyFrame;
using map::MapPoint;

std::vector<std::shared_ptr<KeyFrame>> LoopCloser::detect(KeyFrame& kf) {
  if ((last_loop_kf_ >= 0 && kf.id < last_loop_kf_ + o_.min_keyframes_after_loop) ||
      static_cast<int>(map_.keyframe_count()) <= o_.min_map_keyframes || !kf.bow())
    return {};
  // The bar: the lowest score against the covisible keyframes (ORB-SLAM: starts at 1).
  double min_score = 1.0;
  for (const KeyFrame* n : kf.covisibles()) {
    if (n->erased() || !n->bow()) continue;
    min_score = std::min(min_score, vocab::score_l1(kf.bow()->words, kf.bow()->words_l1, n->bow()->words,
                                                    n->bow()->words_l1));
  }
  const std::vector<place::PlaceCandidate> found = database_.loop_candidates(kf, min_score);
  if (found.empty()) {
    groups_.clear();
    return {};
  }
  std::vector<std::pair<long, ConsistentGroups::Group>> groups;
  for (const place::PlaceCandidate& c : found) {
    ConsistentGroups::Group g{c.keyframe->id};
    for (const KeyFrame* n : c.keyframe->covisibles()) g.insert(n->id);
    groups.emplace_back(c.keyframe->id, std::move(g));
  }
  std::vector<std::shared_ptr<KeyFrame>> out;
  for (long id : groups_.update(groups, o_.consistency))
    if (auto k = map_.keyframe(id)) out.push_back(std::move(k));
  return out;
}

bool LoopCloser::compute_sim3(const std::shared_ptr<KeyFrame>& kf,
                              const std::vector<std::shared_ptr<KeyFrame>>& candidates, Loop& loop) {
  const match::Matcher matcher;
  const map::Calibration& c1 = kf->calib();
  const map::Features& f1 = kf->f();
  const Eigen::Matrix3d K1 = c1.K_eigen();
  for (const auto& cand : candidates) {
    if (cand->erased() || !cand->bow()) continue;
    map::Frame bow_frame(kf->frame_id, kf->stamp, kf->features);
    bow_frame.bow = kf->bow();
    if (matcher.search_by_bow(*cand, bow_frame, o_.bow_nn_ratio) < o_.min_bow_matches) continue;
    const map::Calibration& c2 = cand->calib();
    std::vector<Sim3Match> matches;
    std::vector<int> keypoint;  // match -> keypoint of kf
    for (int i = 0; i < f1.size(); ++i) {
      const auto& p2 = bow_frame.points[i];
      const auto& p1 = kf->point(i);
      if (!p1 || !p2 || p1->erased() || p2->erased()) continue;
      const int j = p2->index_in(cand.get());
      if (j < 0) continue;
      Sim3Match m;
      m.X1 = kf->T_cw() * p1->position();
      m.X2 = cand->T_cw() * p2->position();
      const cv::KeyPoint& k1 = f1.keys_un[i];
      const cv::KeyPoint& k2 = cand->f().keys_un[j];
      m.uv1 = {k1.pt.x, k1.pt.y};
      m.uv2 = {k2.pt.x, k2.pt.y};
      m.sigma2_1 = c1.scale.sigma2[k1.octave];
      m.sigma2_2 = c2.scale.sigma2[k2.octave];
      matches.push_back(m);
      keypoint.push_back(i);
    }
    if (static_cast<int>(matches.size()) < o_.min_bow_matches) continue;
    Sim3RansacOptions ro = o_.ransac;
    ro.seed = static_cast<unsigned>(kf->id * 7919 + cand->id);
    const Sim3RansacResult r = sim3_ransac(matches, K1, c2.K_eigen(), ro);
    if (!r.ok) continue;

    // Guided matching with the estimate: the points of the candidate and its covisibles
    // projected into the current keyframe (ORB-SLAM2's SearchByProjection with Scw).
    const Sim3 S_cw = r.S12 * pose_of(*cand);
    map::Frame guided(kf->frame_id, kf->stamp, kf->features);
    guided.set_pose(optimize::sim3_to_se3(S_cw));
    for (size_t m = 0; m < matches.size(); ++m)
      if (r.inlier[m]) guided.points[keypoint[m]] = bow_frame.points[keypoint[m]];
    std::vector<KeyFrame*> group{cand.get()};
    for (KeyFrame* n : cand->covisibles())
      if (!n->erased()) group.push_back(n);
    for (KeyFrame* k : group)
      matcher.search_by_projection(guided, *k, o_.projection_radius, o_.projection_max_distance);
    int total = 0;
    for (const auto& p : guided.points)
      if (p) ++total;
    if (total < o_.min_projection_matches) continue;

    loop.current = kf;
    loop.match = cand;
    loop.S_cw = S_cw;
    loop.matched = guided.points;
    loop.matches = total;
    std::unordered_set<const MapPoint*> seen;
    for (KeyFrame* k : group)
      for (const auto& p : k->points())
        if (p && !p->erased() && seen.insert(p.get()).second) loop.loop_points.push_back(p);
    return true;
  }
  return false;
}

}  // namespace dynaorb::loop
