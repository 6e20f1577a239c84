#pragma once
// Loop closing (ORB-SLAM, Mur-Artal et al., T-RO 2015, Sec. VI; ORB-SLAM2 Sec. V) in its own
// thread, fed by local mapping with each keyframe it has processed (queue + condition variable).
//
// 1. Detection: the lowest bag-of-words score of the keyframe against its covisible keyframes is
//    the bar; the keyframe database gives the keyframes not connected to it that score above it
//    (KeyFrameDatabase::loop_candidates); a candidate is kept once its covisibility group has been
//    consistent with candidate groups of `consistency` consecutive keyframes (ConsistentGroups).
// 2. Geometry: per consistent candidate, matches by bag of words (>= min_bow_matches), Sim(3)
//    RANSAC (SE(3) for stereo / RGB-D), then guided matching by projection of the points of the
//    candidate and its covisibles with the estimate; accepted with >= min_projection_matches.
// 3. Correction: local mapping paused (its local BA aborted), the keyframe and its covisibles
//    moved with the loop transform (through their relative poses) with their points, the matched
//    points fused (current-side points replaced by loop-side points) and the loop points fused
//    into the corrected neighbours, loop edges added, the essential graph optimised (spanning
//    tree, covisibility edges of weight >= essential_min_weight, loop edges; the loop keyframe
//    and keyframe 0 fixed), every keyframe and point corrected (points through their reference
//    keyframe), local mapping resumed. The map's mutex is held for the correction (tracking
//    waits for it, not for global BA).
// 4. Global BA in a separate thread over all keyframes and points, solved without the map's
//    mutex, aborted by a new loop; merged with local mapping paused and the map's mutex held;
//    keyframes created meanwhile follow their spanning-tree parents, their points their
//    reference keyframes (ORB-SLAM2's RunGlobalBundleAdjustment).
#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "dynaorb/core/sensor.h"
#include "dynaorb/loop/sim3.h"
#include "dynaorb/loop/sim3_ransac.h"
#include "dynaorb/map/map.h"
#include "dynaorb/mapping/local_mapper.h"
#include "dynaorb/place/keyframe_database.h"

namespace dynaorb::loop {

// Covisibility consistency of loop candidates over consecutive keyframes (ORB-SLAM's
// DetectLoop): each candidate's group (the candidate and its covisible keyframes, as ids) is
// consistent with a group of the previous keyframe when they share a keyframe; its consistency
// is then that group's + 1, else 0. A candidate whose consistency reaches `threshold` is
// returned (each previous group extends at most one new group). The groups of this call
// replace the previous ones.
class ConsistentGroups {
 public:
  using Group = std::set<long>;
  // candidates: (candidate id, its group); returns the ids of the consistent candidates.
  std::vector<long> update(const std::vector<std::pair<long, Group>>& candidates, int threshold);
  void clear() { groups_.clear(); }
  const std::vector<std::pair<Group, int>>& groups() const { return groups_; }

 private:
  std::vector<std::pair<Group, int>> groups_;
};

struct LoopCloserOptions {
  int consistency = 3;              // ORB-SLAM: mnCovisibilityConsistencyTh = 3
  int min_map_keyframes = 10;       // no detection in a map this small (ORB-SLAM: 10)
  int min_keyframes_after_loop = 10;  // keyframes between two loops (ORB-SLAM: 10)
  int min_bow_matches = 20;         // ORB-SLAM2 ComputeSim3: 20
  double bow_nn_ratio = 0.75;       // ORB-SLAM2: SearchByBoW(..., 0.75)
  Sim3RansacOptions ransac;         // 0.99, 20 inliers, 300 iterations; fix_scale set by the sensor
  double projection_radius = 10.0;  // ORB-SLAM2: SearchByProjection(..., 10)
  int projection_max_distance = 50; // TH_LOW
  int min_projection_matches = 40;  // ORB-SLAM2: nTotalMatches >= 40
  double fuse_radius = 4.0;         // ORB-SLAM2 SearchAndFuse: 4
  int essential_min_weight = 100;   // covisibility edges in the essential graph
  int pose_graph_iterations = 20;
  bool global_ba = true;
  int global_ba_iterations = 10;    // ORB-SLAM2: 10
  int threads = 1;                  // Ceres threads (pose graph, global BA)
  int threads_synchronous = 0;      // the same under synchronous mapping, which waits for them (0: every core)
  // The loop closing and global BA threads' nice value above the process's
  // (core/thread_priority.h). 0: the same priority as tracking.
  int thread_nice = 10;

  // InputError naming the option ("loop closing option 'ransac.chi2' is
  // -1; ...") for a value that would change loop closing silently.
  void validate() const;
};

// Its fields by name (dynaorb/core/option_fields.h).
template <class F>
void option_fields(const LoopCloserOptions*, F&& f) {
  f("consistency", &LoopCloserOptions::consistency);
  f("min_map_keyframes", &LoopCloserOptions::min_map_keyframes);
  f("min_keyframes_after_loop", &LoopCloserOptions::min_keyframes_after_loop);
  f("min_bow_matches", &LoopCloserOptions::min_bow_matches);
  f("bow_nn_ratio", &LoopCloserOptions::bow_nn_ratio);
  f("ransac", &LoopCloserOptions::ransac);
  f("projection_radius", &LoopCloserOptions::projection_radius);
  f("projection_max_distance", &LoopCloserOptions::projection_max_distance);
  f("min_projection_matches", &LoopCloserOptions::min_projection_matches);
  f("fuse_radius", &LoopCloserOptions::fuse_radius);
  f("essential_min_weight", &LoopCloserOptions::essential_min_weight);
  f("pose_graph_iterations", &LoopCloserOptions::pose_graph_iterations);
  f("global_ba", &LoopCloserOptions::global_ba);
  f("global_ba_iterations", &LoopCloserOptions::global_ba_iterations);
  f("threads", &LoopCloserOptions::threads);
  f("threads_synchronous", &LoopCloserOptions::threads_synchronous);
  f("thread_nice", &LoopCloserOptions::thread_nice);
}

struct LoopCloserCounters {
  long keyframes = 0;        // keyframes checked
  long candidates = 0;       // consistent candidates found
  long loops_closed = 0;
  long global_ba_runs = 0;   // finished and merged
  long global_ba_aborted = 0;
  long loop_edges = 0;           // loop edges of the current map (pairs), not a running total
  long last_loop_keyframe = -1;  // ids of the keyframes of the last loop
  long last_loop_match = -1;
  long last_loop_frame = -1;     // frame id of the keyframe that closed the last loop
  int last_loop_matches = 0;     // points matched by projection
  double last_correction_ms = 0;  // pause + correction + essential graph
  double last_global_ba_ms = 0;   // solve + merge
};

class LoopCloser {
 public:
  // The database and the mapper must outlive the loop closer.
  LoopCloser(map::Map& map, Sensor sensor, place::KeyFrameDatabase& database,
             mapping::LocalMapper& mapper, const LoopCloserOptions& options = {});
  ~LoopCloser();
  LoopCloser(const LoopCloser&) = delete;
  LoopCloser& operator=(const LoopCloser&) = delete;

  void insert_keyframe(std::shared_ptr<map::KeyFrame> kf);
  // Blocks until the queue is drained, nothing is processed and no global BA runs.
  void wait_idle();
  bool idle() const;
  // Drops the queue, aborts global BA, forgets groups and loop edges (map reset).
  void reset();
  // The loop edges (keyframe id -> loop partners), for a map file; the caller
  // holds the map mutex.
  std::map<long, std::set<long>> loop_edges() const;
  // After reset() and a map loaded from a file: that map's loop edges (the
  // essential graph of a later loop keeps them). The caller holds the map mutex.
  void restore_loop_edges(std::map<long, std::set<long>> edges);
  LoopCloserCounters counters() const;

 private:
  struct Loop;
  void run();
  void process(const std::shared_ptr<map::KeyFrame>& kf);
  std::vector<std::shared_ptr<map::KeyFrame>> detect(map::KeyFrame& kf);  // map mutex held
  bool compute_sim3(const std::shared_ptr<map::KeyFrame>& kf,
                    const std::vector<std::shared_ptr<map::KeyFrame>>& candidates, Loop& loop);  // map mutex held
  bool correct(Loop& loop);
  void stop_global_ba();
  void global_ba(long loop_keyframe);

  map::Map& map_;
  const Sensor sensor_;
  place::KeyFrameDatabase& database_;
  mapping::LocalMapper& mapper_;
  LoopCloserOptions o_;

  // Loop-thread state.
  ConsistentGroups groups_;
  long last_loop_kf_ = -1;
  std::map<long, std::set<long>> loop_edges_;  // keyframe id -> loop partners (map mutex)

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_, idle_cv_;
  std::deque<std::shared_ptr<map::KeyFrame>> queue_;
  bool busy_ = false;
  bool stop_ = false;
  bool gba_running_ = false;
  LoopCloserCounters counters_;

  std::atomic<bool> abort_gba_{false};
  std::thread gba_thread_;
  std::thread thread_;
};

}  // namespace dynaorb::loop
