#pragma once
// Time going back in the messages a node receives: a bag played again or
// looped (`rosbag play -l`), a simulator reset. dynaorb_node starts a new map
// and dynaorb_octomap resets its own when it happens (~time_jump_reset).
#include <cmath>

namespace dynaorb::node {

// Whether `stamp` lies more than `limit` seconds before `newest` (limit 0: never;
// newest not finite: nothing came before).
inline bool time_went_back(double stamp, double newest, double limit) {
  return limit > 0 && std::isfinite(newest) && stamp < newest - limit;
}

}  // namespace dynaorb::node
