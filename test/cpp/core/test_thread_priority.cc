// Background threads run at the process's nice value plus an increment;
// the calling thread alone changes, and a second call does not add again.
#include <gtest/gtest.h>

#include <thread>

#include "dynaorb/core/thread_priority.h"
#include "dynaorb/io/errors.h"

// The adapters' check of the option (the node's ~background_nice, Python's
// background_nice): [0, 19] passes, anything else names the option and value.
TEST(ThreadPriority, BackgroundNiceOutsideZeroToNineteenIsRefused) {
  EXPECT_NO_THROW(dynaorb::check_background_nice(0, "~background_nice"));
  EXPECT_NO_THROW(dynaorb::check_background_nice(19, "~background_nice"));
  for (const int bad : {-1, 20}) {
    try {
      dynaorb::check_background_nice(bad, "~background_nice");
      ADD_FAILURE() << bad << " passed";
    } catch (const dynaorb::InputError& e) {
      EXPECT_EQ(std::string(e.what()), "~background_nice must be in [0, 19], got " + std::to_string(bad));
    }
  }
}

#if defined(__linux__)
#include <dirent.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "dynaorb/map/map.h"
#include "dynaorb/mapping/local_mapper.h"

namespace {

int own_nice() { return ::getpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid))); }
int process_nice() { return ::getpriority(PRIO_PROCESS, static_cast<id_t>(::getpid())); }

// Nice values of this process's threads, from /proc (field 19 of stat).
std::multiset<int> thread_nices() {
  std::multiset<int> out;
  DIR* dir = ::opendir("/proc/self/task");
  if (!dir) return out;
  while (dirent* e = ::readdir(dir)) {
    if (e->d_name[0] == '.') continue;
    std::ifstream f(std::string("/proc/self/task/") + e->d_name + "/stat");
    std::string line;
    std::getline(f, line);
    const auto close = line.rfind(')');  // the name may hold spaces
    if (close == std::string::npos) continue;
    std::istringstream rest(line.substr(close + 2));
    std::string field;
    for (int i = 3; i <= 19 && rest >> field; ++i)
      if (i == 19) out.insert(std::stoi(field));
  }
  ::closedir(dir);
  return out;
}

}  // namespace

TEST(ThreadPriority, RaisesOnlyTheCallingThreadAndIsIdempotent) {
  const int base = process_nice();
  if (base > 14) GTEST_SKIP() << "the process already runs at nice " << base;
  int first = -100, second = -100, child = -100;
  bool ok = false;
  std::thread t([&] {
    ok = dynaorb::set_background_priority(4);
    first = own_nice();
    ok = ok && dynaorb::set_background_priority(4);
    second = own_nice();
    // A thread started from a background thread inherits its value; calling
    // again keeps it rather than adding the increment twice.
    std::thread([&] {
      dynaorb::set_background_priority(4);
      child = own_nice();
    }).join();
  });
  t.join();
  EXPECT_TRUE(ok);
  EXPECT_EQ(first, base + 4);
  EXPECT_EQ(second, base + 4);
  EXPECT_EQ(child, base + 4);
  EXPECT_EQ(process_nice(), base);  // the main thread keeps its priority
  EXPECT_EQ(own_nice(), base);
}

TEST(ThreadPriority, ZeroChangesNothingAndLargeValuesStopAtNineteen) {
  int zero = -100, large = -100;
  std::thread([&] {
    EXPECT_TRUE(dynaorb::set_background_priority(0));
    zero = own_nice();
    EXPECT_TRUE(dynaorb::set_background_priority(100));
    large = own_nice();
  }).join();
  EXPECT_EQ(zero, process_nice());
  EXPECT_EQ(large, 19);
}

TEST(ThreadPriority, LocalMappingThreadRunsAtItsOption) {
  const int base = process_nice();
  if (base > 16) GTEST_SKIP() << "the process already runs at nice " << base;
  const int before = static_cast<int>(thread_nices().count(base + 3));
  dynaorb::map::Map map;
  dynaorb::mapping::LocalMapperOptions o;
  o.thread_nice = 3;
  dynaorb::mapping::LocalMapper mapper(map, dynaorb::Sensor::kStereo, o);
  // The thread sets its priority as it starts.
  int now = before;
  for (int i = 0; i < 200 && now == before; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    now = static_cast<int>(thread_nices().count(base + 3));
  }
  EXPECT_EQ(now, before + 1);
}
#endif
