#include "dynaorb/core/thread_priority.h"

#include <algorithm>
#include <cerrno>

#include "dynaorb/io/errors.h"

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace dynaorb {

bool set_background_priority(int increment) {
  if (increment <= 0) return true;
#if defined(__linux__)
  // PRIO_PROCESS with a thread id addresses that thread alone on Linux; the
  // process id is the main thread's.
  errno = 0;
  const int base = ::getpriority(PRIO_PROCESS, static_cast<id_t>(::getpid()));
  if (base == -1 && errno != 0) return false;
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  return ::setpriority(PRIO_PROCESS, tid, std::min(base + increment, 19)) == 0;
#else
  return false;
#endif
}

void check_background_nice(int nice, const std::string& name) {
  if (nice < 0 || nice > 19) throw InputError(name + " must be in [0, 19], got " + std::to_string(nice));
}

}  // namespace dynaorb
