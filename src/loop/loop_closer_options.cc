// LoopCloserOptions::validate (with ransac's). The options come from Python
// (`dynaorb run --loop KEY=VALUE`), ROS parameters and C++ callers.
#include "../core/option_checks.h"
#include "dynaorb/core/thread_priority.h"
#include "dynaorb/loop/loop_closer.h"

namespace dynaorb::loop {

void LoopCloserOptions::validate() const {
  const dynaorb::detail::OptionChecks c("loop closing");
  c.at_least("consistency", consistency, 0);
  c.at_least("min_map_keyframes", min_map_keyframes, 0);
  c.at_least("min_keyframes_after_loop", min_keyframes_after_loop, 0);
  c.at_least("min_bow_matches", min_bow_matches, 0);
  c.between("bow_nn_ratio", bow_nn_ratio, 0, 1, true);
  c.between("ransac.probability", ransac.probability, 0, 1, false);
  c.at_least("ransac.min_inliers", ransac.min_inliers, 3);  // a similarity needs 3 points
  c.at_least("ransac.max_iterations", ransac.max_iterations, 1);
  c.positive("ransac.chi2", ransac.chi2);
  c.positive("projection_radius", projection_radius);
  c.at_least("projection_max_distance", projection_max_distance, 0);
  c.at_least("min_projection_matches", min_projection_matches, 0);
  c.positive("fuse_radius", fuse_radius);
  c.at_least("essential_min_weight", essential_min_weight, 0);
  c.at_least("pose_graph_iterations", pose_graph_iterations, 1);
  c.at_least("global_ba_iterations", global_ba_iterations, 1);
  c.at_least("threads", threads, 1);
  c.at_least("threads_synchronous", threads_synchronous, 0);
  check_background_nice(thread_nice, "loop closing option 'thread_nice'");
}

}  // namespace dynaorb::loop
