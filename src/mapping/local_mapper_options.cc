// LocalMapperOptions::validate. The options come from Python (`dynaorb run
// --mapping KEY=VALUE`), ROS parameters and C++ callers.
#include "../core/option_checks.h"
#include "dynaorb/core/thread_priority.h"
#include "dynaorb/mapping/local_mapper.h"

namespace dynaorb::mapping {

void LocalMapperOptions::validate() const {
  const dynaorb::detail::OptionChecks c("local mapping");
  c.at_least("neighbors_stereo", neighbors_stereo, 1);
  c.at_least("neighbors_mono", neighbors_mono, 1);
  if (!(min_found_ratio >= 0 && min_found_ratio <= 1))
    c.fail("min_found_ratio", min_found_ratio, "a ratio in [0, 1] (0: no point culled for it)");
  c.at_least("min_observations_stereo", min_observations_stereo, 0);
  c.at_least("min_observations_mono", min_observations_mono, 0);
  c.between("redundant_ratio", redundant_ratio, 0, 1, true);
  c.at_least("redundant_observers", redundant_observers, 1);
  c.at_least("ba_iterations_first", ba_iterations_first, 1);
  c.at_least("ba_iterations_second", ba_iterations_second, 0);
  c.at_least("ba_threads", ba_threads, 1);
  c.at_least("ba_threads_synchronous", ba_threads_synchronous, 0);
  check_background_nice(thread_nice, "local mapping option 'thread_nice'");
}

}  // namespace dynaorb::mapping
