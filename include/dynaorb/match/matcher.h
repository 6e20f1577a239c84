#pragma once
// ORB matching between frames, keyframes and map points (ORB-SLAM's
// searches): guided by projection where a pose is known, by descriptor and
// epipolar geometry where it is not. Descriptor thresholds are ORB-SLAM's
// TH_HIGH / TH_LOW; an orientation histogram keeps the matches whose rotation
// agrees with the three dominant ones.
#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

#include "dynaorb/map/frame.h"
#include "dynaorb/map/map.h"

namespace dynaorb::match {

struct MatcherOptions {
  int th_high = 100;
  int th_low = 50;
  bool check_orientation = true;
  int histogram_bins = 30;
};

class Matcher {
 public:
  explicit Matcher(const MatcherOptions& options = {}) : o_(options) {}

  // Motion model: projects the points of `last` into `cur` (whose pose is
  // set) and matches within th * scale of the last keypoint's level; stereo
  // frames restrict the levels by the direction of motion (ORB-SLAM2).
  int search_by_projection(map::Frame& cur, const map::Frame& last, double th) const;

  // Local map: the points whose track scratch says they are in cur's frustum
  // and not yet matched; best / second best ratio on the same level.
  int search_local_points(map::Frame& cur, const std::vector<std::shared_ptr<map::MapPoint>>& points,
                          double th, double nn_ratio = 0.8) const;

  // Reference keyframe without a vocabulary: each map point of kf against
  // all keypoints of cur by descriptor (best below th_low and below
  // nn_ratio * second best), then the orientation check.
  int search_keyframe(const map::KeyFrame& kf, map::Frame& cur, double nn_ratio = 0.7) const;

  // Reference keyframe / relocalisation with a vocabulary (ORB-SLAM's
  // SearchByBoW): each map point of kf against the keypoints of cur under the
  // same direct-index node only; best below th_low and below nn_ratio *
  // second best, then the orientation check. Both bags of words must be set
  // (std::invalid_argument otherwise); slots of cur already holding a point
  // are skipped.
  int search_by_bow(const map::KeyFrame& kf, map::Frame& cur, double nn_ratio = 0.7) const;

  // Relocalisation (ORB-SLAM's SearchByProjection from a keyframe): projects
  // the map points of kf that cur has not matched yet with cur's pose, within
  // th * scale of the predicted level (levels predicted -1 .. +1), best
  // descriptor distance at most max_distance, then the orientation check.
  int search_by_projection(map::Frame& cur, const map::KeyFrame& kf, double th, int max_distance) const;

  // F12 such that x1^T F12 x2 = 0 for pixels x1 of kf1 and x2 of kf2, from
  // the two keyframes' poses and calibration.
  static Eigen::Matrix3d fundamental(const map::KeyFrame& kf1, const map::KeyFrame& kf2);

  // Pairs of unmatched keypoints of kf1 / kf2 whose descriptors agree and
  // whose kf2 keypoint lies on the epipolar line of the kf1 one (F12 maps kf1
  // pixels to kf2 lines), for triangulation. by_bow and both bags of words:
  // only keypoints under the same vocabulary node are compared (ORB-SLAM's
  // direct index); else every unmatched pair.
  std::vector<std::pair<int, int>> search_for_triangulation(const map::KeyFrame& kf1,
                                                            const map::KeyFrame& kf2,
                                                            const Eigen::Matrix3d& F12,
                                                            bool by_bow = true) const;

  // Monocular initialisation (ORB-SLAM2's SearchForInitialization): each
  // level-0 keypoint i of f1 against the level-0 keypoints of f2 in a square
  // window of half-size `window` around prev_matched[i] (where it was last
  // matched; initially its own position): best <= th_low and < nn_ratio *
  // second best, a keypoint of f2 claimed twice goes to the later claim (as
  // ORB-SLAM2), then the orientation check. matches12[i]: index in f2 or -1;
  // prev_matched is moved to the new matches. Returns the number of matches.
  int search_for_initialization(const map::Features& f1, const map::Features& f2,
                                std::vector<Eigen::Vector2d>& prev_matched,
                                std::vector<int>& matches12, double window = 100.0,
                                double nn_ratio = 0.9) const;

  // Projects points into kf: where the keypoint already has a point, the one
  // with fewer observations is replaced by the other; otherwise the point
  // gains the observation. Returns the number of fused points.
  int fuse(map::Map& map, map::KeyFrame& kf, const std::vector<std::shared_ptr<map::MapPoint>>& points,
           double th = 3.0) const;

 private:
  MatcherOptions o_;
};

}  // namespace dynaorb::match
