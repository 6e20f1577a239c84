#pragma once
// Local mapping (ORB-SLAM Sec. VI) in its own thread: keyframes arrive
// through a queue (condition variable, no polling); each is inserted into
// the covisibility graph, recent map points are culled, new points are
// triangulated with covisible keyframes, duplicates are fused, the local
// window is bundle adjusted (Ceres) and redundant keyframes are culled.
// With a vocabulary, each keyframe gets its bag of words on insertion and
// enters the keyframe database (ORB-SLAM2's ProcessNewKeyFrame).
#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "dynaorb/map/map.h"
#include "dynaorb/place/keyframe_database.h"
#include "dynaorb/vocab/vocabulary.h"

namespace dynaorb::mapping {

using StageTimes = std::map<std::string, double>;

struct LocalMapperOptions {
  int neighbors_stereo = 10;        // covisible keyframes to triangulate with
  int neighbors_mono = 20;
  // Triangulation pairs searched through the vocabulary's direct index
  // (ORB-SLAM's SearchForTriangulation; needs a vocabulary) rather than
  // exhaustively. Monocular: every keypoint of a keyframe is unmatched and 20
  // neighbours are searched; exhaustively that took 109 ms per keyframe on
  // EuRoC MH_05 (4x features after initialisation), and with asynchronous
  // mapping the run was lost at frame 35 in 3 of 3 runs; by the index 3-6 ms,
  // 2 of 3 runs tracked to the end. Stereo / RGB-D: the index cut KITTI 06's
  // tracking time 30-37 -> 23 ms/frame (asynchronous mapping, same ATE) but
  // moved the synthetic loop's end-point error after loop closing 0.032 ->
  // 0.060 m and shortened localisation beyond a loaded KITTI map; kept
  // exhaustive until that is understood. The exhaustive search only compares
  // descriptors within each keypoint's epipolar band (same pairs): KITTI 06
  // triangulation 48-49 -> 27-28 ms per keyframe (synchronous), local mapping
  // 70-80 -> 52-54 ms and the track call 23.5-34 -> 22-25 ms (asynchronous).
  bool triangulation_bow_mono = true;
  bool triangulation_bow_stereo = false;
  double min_found_ratio = 0.25;    // recent points found / visible below this go
  int min_observations_stereo = 3;  // after 2 keyframes, fewer observations: culled
  int min_observations_mono = 2;
  double redundant_ratio = 0.9;     // keyframe culled when this share of its points
  int redundant_observers = 3;      //   is seen by this many others at a similar scale
  bool local_ba = true;
  // Local BA's Levenberg-Marquardt iterations: a first pass under a Huber
  // loss, then (when ba_iterations_second > 0) a second over the first
  // pass's inliers without it: ORB-SLAM2's 5 then 10. ORB-SLAM3 runs one
  // pass of 10 and only drops the outliers after it (10 and 0 here):
  // measured in docs/slam-core.md ("Local BA's iterations"), not taken.
  int ba_iterations_first = 5;
  int ba_iterations_second = 10;
  int ba_threads = 1;
  // Ceres threads of a local BA under synchronous mapping, where tracking
  // waits for it and the other cores are idle (0: every core). The long
  // synthetic walk (1500 stereo frames, `dynaorb run kitti SEQ --mapping
  // ba_threads_synchronous=N`, this 2-core machine): 1 thread 215 s, local BA
  // 376 ms median; 2 threads 154-168 s, 243-264 ms; ATE 7.7 mm both, equal
  // to 1e-15 m (Ceres' multithreaded sums are not bit for bit repeatable,
  // so two runs may differ at that level). ba_threads applies beside tracking.
  int ba_threads_synchronous = 0;
  // A new keyframe (queued, or wanted by tracking) aborts the running local
  // BA (ORB-SLAM2's mbAbortBA); false lets it finish. Loop closing's pause
  // aborts it either way. On the long suite's stereo walk (1500 frames,
  // asynchronous, unpaced, 3 interleaved runs each; `dynaorb run kitti SEQ
  // --async-mapping --mapping abort_ba_for_keyframes=false`), where the
  // default aborts 119-127 of 180-183 local BAs: false runs 121-126 BAs, none
  // aborted (the queue skips the rest), ATE 17.1 / 13.7 / 17.4 mm against
  // 8.0 / 14.7 / 14.0. Kept.
  bool abort_ba_for_keyframes = true;
  // The mapping thread's nice value above the process's (core/thread_priority.h):
  // tracking gets the CPU first when the cores are busy. 0: the same priority.
  int thread_nice = 10;

  // InputError naming the option ("local mapping option 'min_found_ratio' is
  // nan; ...") for a value that would change mapping silently.
  void validate() const;
};

// Its fields by name (dynaorb/core/option_fields.h).
template <class F>
void option_fields(const LocalMapperOptions*, F&& f) {
  f("neighbors_stereo", &LocalMapperOptions::neighbors_stereo);
  f("neighbors_mono", &LocalMapperOptions::neighbors_mono);
  f("triangulation_bow_mono", &LocalMapperOptions::triangulation_bow_mono);
  f("triangulation_bow_stereo", &LocalMapperOptions::triangulation_bow_stereo);
  f("min_found_ratio", &LocalMapperOptions::min_found_ratio);
  f("min_observations_stereo", &LocalMapperOptions::min_observations_stereo);
  f("min_observations_mono", &LocalMapperOptions::min_observations_mono);
  f("redundant_ratio", &LocalMapperOptions::redundant_ratio);
  f("redundant_observers", &LocalMapperOptions::redundant_observers);
  f("local_ba", &LocalMapperOptions::local_ba);
  f("ba_iterations_first", &LocalMapperOptions::ba_iterations_first);
  f("ba_iterations_second", &LocalMapperOptions::ba_iterations_second);
  f("ba_threads", &LocalMapperOptions::ba_threads);
  f("ba_threads_synchronous", &LocalMapperOptions::ba_threads_synchronous);
  f("abort_ba_for_keyframes", &LocalMapperOptions::abort_ba_for_keyframes);
  f("thread_nice", &LocalMapperOptions::thread_nice);
}

struct LocalMapperCounters {
  long keyframes = 0, points_created = 0, points_culled = 0, points_fused = 0;
  long keyframes_culled = 0, local_ba_runs = 0, local_ba_aborted = 0;
  // The last local BA's window: keyframes optimised (the new one and its
  // covisibles) and keyframes held fixed (seeing its points from outside);
  // the most keyframes any window optimised.
  long local_ba_window_last = 0, local_ba_fixed_last = 0, local_ba_window_max = 0;
};

class LocalMapper {
 public:
  // vocabulary and database may be null (no bags of words, no database).
  LocalMapper(map::Map& map, Sensor sensor, const LocalMapperOptions& options = {},
              std::shared_ptr<const vocab::Vocabulary> vocabulary = nullptr,
              place::KeyFrameDatabase* database = nullptr);
  ~LocalMapper();
  LocalMapper(const LocalMapper&) = delete;
  LocalMapper& operator=(const LocalMapper&) = delete;

  // The keyframe must already be in the map (tracking adds it with its new points).
  void insert_keyframe(std::shared_ptr<map::KeyFrame> kf);
  bool idle() const;              // nothing queued or being processed
  size_t queued() const;
  void interrupt_ba() {
    if (o_.abort_ba_for_keyframes) abort_ba_ = true;
  }
  void wait_idle();               // blocks until the queue is drained
  void clear_queue();             // drops queued keyframes (reset)

  // Loop closing (ORB-SLAM's RequestStop / Release): pause() aborts a running
  // local BA and blocks until the keyframe being processed is finished; no
  // keyframe is processed until the matching resume(). Keyframes inserted
  // meanwhile wait in the queue. Nestable (a count); call without the map's mutex.
  void pause();
  void resume();
  bool paused() const;
  // Called (from the mapper's thread, without the map's mutex) with each
  // keyframe once it is processed and still in the map: the loop closer's queue.
  // Set before the first keyframe is inserted.
  void set_keyframe_sink(std::function<void(std::shared_ptr<map::KeyFrame>)> sink) {
    sink_ = std::move(sink);
  }

  LocalMapperCounters counters() const;
  // Stage times of the keyframes processed since the last call.
  std::vector<StageTimes> take_stage_times();

 private:
  void run();
  void process(const std::shared_ptr<map::KeyFrame>& kf, StageTimes& t);
  void insert_into_graph(map::KeyFrame& kf);
  void cull_recent_points(const map::KeyFrame& kf);
  void create_new_points(const std::shared_ptr<map::KeyFrame>& kf);
  void fuse_with_neighbors(map::KeyFrame& kf);
  void local_bundle_adjustment(map::KeyFrame& kf);
  void cull_keyframes(map::KeyFrame& kf);
  bool has_new_keyframes() const;
  // ORB-SLAM2's LocalMapping::Run: the local BA's abort flag is cleared just
  // before the BA, not when the keyframe is taken, so an interrupt that came
  // while the keyframe's points were being made (a monocular tracker wanting a
  // keyframe) does not cost it its BA. False, with the flag left alone, when a
  // keyframe is queued, a stop or pause is pending, or the queue was cleared
  // (a reset) since this keyframe was taken: then neither the BA nor the
  // keyframe culling runs.
  bool begin_local_ba();

  map::Map& map_;
  const Sensor sensor_;
  const LocalMapperOptions o_;
  const std::shared_ptr<const vocab::Vocabulary> vocabulary_;
  place::KeyFrameDatabase* const database_;
  std::vector<std::shared_ptr<map::MapPoint>> recent_points_;

  mutable std::mutex queue_mutex_;
  std::condition_variable queue_cv_, idle_cv_;
  std::deque<std::shared_ptr<map::KeyFrame>> queue_;
  bool busy_ = false;
  bool stop_ = false;
  int pause_requests_ = 0;
  unsigned long clears_ = 0;      // clear_queue calls
  unsigned long generation_ = 0;  // clears_ when the keyframe in process was taken
  std::function<void(std::shared_ptr<map::KeyFrame>)> sink_;
  std::atomic<bool> abort_ba_{false};
  LocalMapperCounters counters_;
  std::vector<StageTimes> stage_times_;
  std::thread thread_;
};

}  // namespace dynaorb::mapping
