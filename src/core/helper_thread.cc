#include "dynaorb/core/helper_thread.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <memory>
#include <utility>

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#endif

namespace dynaorb {

HelperThread::HelperThread() : thread_([this] { run(); }) {}

HelperThread::~HelperThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

HelperThread::Job HelperThread::submit(std::function<void()> job) { return Job(enqueue(std::move(job))); }

// A packaged_task's future does not wait when destroyed (unlike std::async's).
void HelperThread::post(std::function<void()> job) { enqueue(std::move(job)); }

// Queues `job` and wakes the worker, off the caller's CPU; the job's future.
std::future<void> HelperThread::enqueue(std::function<void()> job) {
#if defined(__linux__)
  // Start on a core other than the caller's (see the header); the job then
  // widens the worker's affinity back to the caller's.
  cpu_set_t caller;
  CPU_ZERO(&caller);
  if (::sched_getaffinity(0, sizeof(caller), &caller) == 0 && CPU_COUNT(&caller) > 1) {
    const int cpu = ::sched_getcpu();
    if (cpu >= 0 && cpu < CPU_SETSIZE && CPU_ISSET(cpu, &caller)) {
      cpu_set_t others = caller;
      CPU_CLR(cpu, &others);
      if (::pthread_setaffinity_np(thread_.native_handle(), sizeof(others), &others) == 0) {
        job = [job = std::move(job), caller] {
          ::pthread_setaffinity_np(::pthread_self(), sizeof(caller), &caller);
          job();
        };
      }
    }
  }
#endif
  std::packaged_task<void()> task(std::move(job));
  std::future<void> done = task.get_future();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs_.push_back(std::move(task));
  }
  wake_.notify_one();
  return done;
}

// What share_async()'s caller and the worker hold together; the worker's
// job may outlive the call (woken after everything ran), so it holds this by
// shared_ptr and calls `task` only for an index it claimed, which the caller
// waits for.
struct HelperThread::Shared::State {
  State(int n_, std::function<void(int)> t) : n(n_), task(std::move(t)) {}
  const int n;
  const std::function<void(int)> task;  // may refer to the caller's locals: called only for a claimed index
  std::atomic<int> next{0}, done{0};
  std::mutex mutex;
  std::condition_variable all_done;
  std::exception_ptr error;  // under mutex

  void work() {
    for (int i = next.fetch_add(1); i < n; i = next.fetch_add(1)) {
      try {
        task(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
      }
      if (done.fetch_add(1) + 1 == n) {
        std::lock_guard<std::mutex> lock(mutex);  // the caller is waiting or will see done == n
        all_done.notify_all();
      }
    }
  }

  // All claimed and all done. What is left after the caller's own claims is
  // the worker's last task (a fraction of the whole): sleeping on it would
  // hand this core to whatever runs beside (local mapping), and the wake-up
  // could then wait for that thread's time slice, so spin a while first.
  void finish() {
    work();
    const auto spin_until = std::chrono::steady_clock::now() + std::chrono::microseconds(kShareSpinUs);
    while (done.load() < n && std::chrono::steady_clock::now() < spin_until) {
    }
    std::unique_lock<std::mutex> lock(mutex);
    all_done.wait(lock, [&] { return done.load() == n; });
  }
};

HelperThread::Shared HelperThread::share_async(int n, std::function<void(int)> task) {
  auto state = std::make_shared<Shared::State>(std::max(n, 0), std::move(task));
  if (n > 1) post([state] { state->work(); });
  return Shared(std::move(state));
}

void HelperThread::Shared::join() {
  const std::shared_ptr<State> s = std::move(state_);
  if (!s) return;
  s->finish();
  std::exception_ptr error;
  {
    std::lock_guard<std::mutex> lock(s->mutex);
    error = s->error;
  }
  if (error) std::rethrow_exception(error);
}

HelperThread::Shared::~Shared() {
  if (state_) state_->finish();
}

void HelperThread::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
    if (jobs_.empty()) return;  // stop_, and nothing left to run
    std::packaged_task<void()> task = std::move(jobs_.front());
    jobs_.pop_front();
    lock.unlock();
    task();  // an exception goes to the job's future
    lock.lock();
  }
}

}  // namespace dynaorb
