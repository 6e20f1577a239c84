#pragma once
// Milliseconds since a steady-clock time point: the per-stage timings of the
// tracking, mapping and loop-closing threads.
#include <chrono>

namespace dynaorb {

using Clock = std::chrono::steady_clock;

inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace dynaorb
