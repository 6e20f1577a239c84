#pragma once
// A persistent worker for one calling thread's fork-join work: the tracking
// thread shares the ORB extraction's pyramid levels with it (share;
// tracking/frame_builder.h). The measurements below are of its first use,
// the right image's extraction submitted whole.
//
// Why not std::async. It starts a thread per job, and on a machine whose
// other cores are busy, even with lower-priority work (the segmentation
// network at nice 10, local mapping, a nice-19 or SCHED_IDLE busy loop), the
// scheduler places that thread on its waker's core: it runs once the caller
// blocks on it, and the two halves run one after the other. On the 2-vCPU
// development VM (Linux 6.18), `dynaorb run euroc .../V1_01_easy_micro
// --sensor stereo --async-mapping` extracted both images in 6.5 ms per frame
// alone, 12.4 ms beside a nice-19 busy loop, 13.6 ms pinned to one CPU.
//
// submit(), post() and share() therefore wake the worker with the caller's
// current CPU taken out of the worker's affinity, so it starts on another
// core (and preempts lower-priority work there, though under EEVDF not
// always at once: share()); the job first gives the worker the caller's
// whole affinity back, so the scheduler may move it as usual while it runs.
// Where the caller may run on one CPU only, or off Linux, the affinity is
// left alone. Interleaved runs, old / new (medians of the runs' median
// track call; FrameBuilder::stereo):
//   EuRoC V1 stereo, `full` with the network async   21.9 -> 17.9 ms (4 + 4)
//   EuRoC V1 stereo, off                             13.0 -> 12.4 ms (4 + 4)
//   KITTI 06 stereo, off                             24.3 -> 22.4 ms (8 + 8)
//   synthetic stereo, no movers, off                 13.4 -> 10.4 ms (5 + 5)
//   synthetic stereo, 3 movers, `full`               29.6 -> 29.7 ms (6 + 6;
//     both cores already busy: the motion cues' worker)
// The motion cues' corners for the next frame are detected on one too
// (MotionCueCache::ahead). The overlapped detection beside the dynamic
// filter (mono, RGB-D) stays on std::async: there the helper measured
// 1.1-1.8 ms per frame slower.
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>

namespace dynaorb {

class HelperThread {
 public:
  // A submitted job's completion. Like std::async's future, destroying it
  // waits for the job (so that a caller leaving by an exception never leaves
  // a job running on its locals).
  class Job {
   public:
    explicit Job(std::future<void> done) : done_(std::move(done)) {}
    Job(Job&&) = default;
    Job& operator=(Job&&) = delete;
    ~Job() {
      if (done_.valid()) done_.wait();
    }
    // Waits for the job; rethrows what it threw.
    void get() { done_.get(); }

   private:
    std::future<void> done_;
  };

  HelperThread();
  ~HelperThread();  // runs the jobs already submitted, then joins
  HelperThread(const HelperThread&) = delete;
  HelperThread& operator=(const HelperThread&) = delete;

  // Runs `job` on the worker; jobs run one at a time, in submission order.
  Job submit(std::function<void()> job);
  // Tasks shared between a caller and the worker (share_async): each index
  // runs once, on whichever thread claims it first.
  class Shared {
   public:
    struct State;
    explicit Shared(std::shared_ptr<State> state) : state_(std::move(state)) {}
    Shared(Shared&&) = default;
    Shared& operator=(Shared&&) = delete;
    // The caller claims what is left, then waits for the tasks the worker
    // claimed (spinning a while first: kShareSpinUs); rethrows the first
    // exception a task threw, once all have run. Once only.
    void join();
    // Without join (e.g. the caller left by an exception): the caller runs
    // the tasks not yet claimed as join() does (none is skipped, so a task
    // that waits for an earlier one never waits for one left out) and drops
    // what they threw.
    ~Shared();

   private:
    std::shared_ptr<State> state_;
  };

  // Runs task(0), ..., task(n - 1), each once, on the calling thread and the
  // worker together, and returns when all have run: each thread claims the
  // next index until none is left, so the tasks go in index order (put the
  // longest first) and the worker takes what the caller has not begun. The
  // caller never waits for the worker to start: on a core held by other
  // work the worker may wake milliseconds late (EEVDF lets a nice-10 local
  // mapping finish its slice), and then the caller runs everything itself.
  // It waits only for tasks the worker has claimed. The first exception a
  // task throws is rethrown here, once all tasks are done (the others still run).
  void share(int n, std::function<void(int)> task) { share_async(n, std::move(task)).join(); }
  // The same, started on the worker now; the caller joins when it is free
  // (its own work meanwhile). Tasks may wait for earlier indices (e.g. a
  // level for its image's pyramid): a claimed index is running or done.
  Shared share_async(int n, std::function<void(int)> task);
  // How long share()'s caller spins on the worker's last task before it sleeps.
  static constexpr int kShareSpinUs = 3000;

  // The same without a Job: the caller learns of the job's end by its own
  // means (e.g. a std::packaged_task's future), and the job must own what it
  // reads (captures by value). What it throws is dropped.
  void post(std::function<void()> job);

 private:
  void run();
  std::future<void> enqueue(std::function<void()> job);

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::packaged_task<void()>> jobs_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace dynaorb
