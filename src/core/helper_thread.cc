#include "dynaorb/core/helper_thread.h"

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
