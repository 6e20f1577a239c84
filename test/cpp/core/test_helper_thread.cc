// HelperThread: jobs run on one other thread, in order; a job's exception
// reaches its get() (post() drops it, the worker goes on); destroying a Job
// waits for it; the job runs with the caller's affinity (the worker is only
// started off the caller's CPU), and a caller confined to one CPU still gets
// its jobs run.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <stdexcept>
#include <thread>
#include <vector>

#include "dynaorb/core/helper_thread.h"

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#endif

using dynaorb::HelperThread;

TEST(HelperThread, RunsJobsInSubmissionOrderOnOneOtherThread) {
  HelperThread helper;
  std::vector<int> order;
  std::vector<std::thread::id> ids(3);
  {
    std::vector<HelperThread::Job> jobs;
    for (int i = 0; i < 3; ++i)
      jobs.push_back(helper.submit([&, i] {
        order.push_back(i);
        ids[i] = std::this_thread::get_id();
      }));
    for (auto& j : jobs) j.get();
  }
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2}));
  EXPECT_NE(ids[0], std::this_thread::get_id());
  EXPECT_EQ(ids[0], ids[1]);
  EXPECT_EQ(ids[1], ids[2]);
}

TEST(HelperThread, AJobsExceptionReachesItsGetAndTheWorkerGoesOn) {
  HelperThread helper;
  HelperThread::Job bad = helper.submit([] { throw std::runtime_error("job failed"); });
  EXPECT_THROW(bad.get(), std::runtime_error);
  bool ran = false;
  helper.submit([&] { ran = true; }).get();
  EXPECT_TRUE(ran);
}

TEST(HelperThread, DestroyingAJobWaitsForIt) {
  HelperThread helper;
  std::atomic<bool> done{false};
  {
    HelperThread::Job job = helper.submit([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      done = true;
    });
  }  // e.g. the caller left by an exception before get()
  EXPECT_TRUE(done);
}

TEST(HelperThread, DestructionRunsTheJobsAlreadyPostedThenJoins) {
  std::atomic<int> ran{0};
  {
    HelperThread helper;
    for (int i = 0; i < 3; ++i)
      helper.post([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        ++ran;
      });
  }  // nothing waited for them
  EXPECT_EQ(ran, 3);
}

// share(): every index runs once, on the caller and the worker.
TEST(HelperThread, ShareRunsEveryTaskOnceOnBothThreads) {
  HelperThread helper;
  for (int n : {0, 1, 2, 8, 200}) {
    std::vector<std::atomic<int>> runs(static_cast<size_t>(n));
    helper.share(n, [&](int i) {
      ++runs[static_cast<size_t>(i)];
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    });
    for (int i = 0; i < n; ++i) EXPECT_EQ(runs[static_cast<size_t>(i)].load(), 1) << "n " << n << " task " << i;
  }
  // The caller's first task holds until the worker has run one of the others.
  const auto caller = std::this_thread::get_id();
  std::atomic<int> on_worker{0};
  helper.share(4, [&](int) {
    if (std::this_thread::get_id() != caller) {
      ++on_worker;
      return;
    }
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (on_worker == 0 && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  });
  EXPECT_GT(on_worker.load(), 0);
}

// A worker still busy with an earlier job: the caller runs every task
// itself and returns without waiting for the worker.
TEST(HelperThread, ShareDoesNotWaitForABusyWorker) {
  HelperThread helper;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  helper.post([released] { released.wait(); });
  const auto caller = std::this_thread::get_id();
  std::atomic<int> elsewhere{0};
  helper.share(8, [&](int) {
    if (std::this_thread::get_id() != caller) ++elsewhere;
  });
  EXPECT_EQ(elsewhere.load(), 0);
  release.set_value();
  // The stale share job runs later and finds nothing to do.
  helper.submit([] {}).get();
}

TEST(HelperThread, ShareRethrowsATasksExceptionAfterTheRest) {
  HelperThread helper;
  std::atomic<int> ran{0};
  EXPECT_THROW(helper.share(6,
                            [&](int i) {
                              ++ran;
                              if (i == 2) throw std::runtime_error("task 2 failed");
                            }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 6);
  helper.share(2, [&](int) { ++ran; });  // still usable
  EXPECT_EQ(ran.load(), 8);
}

// share_async(): the worker starts at once; the caller joins later. A
// Shared dropped without join (the caller left by an exception) still runs
// every task, so one that waits for an earlier index is never stranded.
TEST(HelperThread, ShareAsyncRunsBesideTheCallerAndWithoutJoin) {
  HelperThread helper;
  std::vector<std::atomic<int>> runs(20);
  {
    HelperThread::Shared shared = helper.share_async(20, [&](int i) { ++runs[static_cast<size_t>(i)]; });
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the caller's own work
    shared.join();
  }
  for (auto& r : runs) EXPECT_EQ(r.load(), 1);
  std::atomic<bool> first_done{false};
  std::atomic<int> ran{0};
  try {
    HelperThread::Shared shared = helper.share_async(6, [&](int i) {
      if (i == 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        first_done = true;
      } else {
        while (!first_done) {
        }  // waits for index 0, as a pyramid level waits for its pyramid
      }
      ++ran;
    });
    throw std::runtime_error("the caller's own work failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(ran.load(), 6);
}

#if defined(__linux__)
// The worker is woken with the caller's CPU out of its affinity; the job
// itself runs with the caller's whole affinity again.
TEST(HelperThread, TheJobRunsWithTheCallersAffinity) {
  cpu_set_t caller;
  CPU_ZERO(&caller);
  ASSERT_EQ(::sched_getaffinity(0, sizeof(caller), &caller), 0);
  HelperThread helper;
  for (int i = 0; i < 3; ++i) {
    cpu_set_t seen;
    CPU_ZERO(&seen);
    helper.submit([&] { ::pthread_getaffinity_np(::pthread_self(), sizeof(seen), &seen); }).get();
    EXPECT_TRUE(CPU_EQUAL(&seen, &caller));
  }
}

// A caller that may run on one CPU only (taskset, a cpuset of one core):
// the affinity is left alone and the job still runs, there.
TEST(HelperThread, ACallerOnOneCpuStillGetsItsJobsRun) {
  cpu_set_t before, one;
  ASSERT_EQ(::sched_getaffinity(0, sizeof(before), &before), 0);
  const int cpu = ::sched_getcpu();
  ASSERT_GE(cpu, 0);
  CPU_ZERO(&one);
  CPU_SET(cpu, &one);
  ASSERT_EQ(::pthread_setaffinity_np(::pthread_self(), sizeof(one), &one), 0);
  {
    HelperThread helper;  // started from the one-CPU thread: it inherits that mask
    cpu_set_t seen;
    CPU_ZERO(&seen);
    helper.submit([&] { ::pthread_getaffinity_np(::pthread_self(), sizeof(seen), &seen); }).get();
    EXPECT_TRUE(CPU_EQUAL(&seen, &one));
  }
  ASSERT_EQ(::pthread_setaffinity_np(::pthread_self(), sizeof(before), &before), 0);
}
#endif

// post(): the job runs in order with the others; what it throws is dropped
// (the caller learns of the end by its own future, here a packaged_task's).
TEST(HelperThread, PostRunsTheJobAndTheWorkerOutlivesItsException) {
  HelperThread helper;
  auto task = std::make_shared<std::packaged_task<int()>>([] { return 7; });
  std::future<int> result = task->get_future();
  helper.post([] { throw std::runtime_error("dropped"); });
  helper.post([task] { (*task)(); });
  EXPECT_EQ(result.get(), 7);
  bool ran = false;
  helper.submit([&] { ran = true; }).get();
  EXPECT_TRUE(ran);
}
