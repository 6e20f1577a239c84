#pragma once
// Time going back in the messages a node receives: a bag played again or
// looped (`rosbag play -l`), a simulator reset. dynaorb_node starts a new map
// and dynaorb_octomap resets its own when it happens (~time_jump_reset).
#include <algorithm>
#include <cmath>

namespace dynaorb::node {

// The newest stamp of a stream of messages, and whether one went back.
class NewestStamp {
 public:
  // Records `stamp`. Returns how far it lies before the newest so far when
  // that is more than `limit` seconds (time went back; `stamp` is the newest
  // from then on), else 0. limit 0: never; nothing before: never.
  double jump_back(double stamp, double limit) {
    const bool back = limit > 0 && std::isfinite(newest_) && stamp < newest_ - limit;
    const double by = back ? newest_ - stamp : 0.0;
    newest_ = back ? stamp : std::max(newest_, stamp);
    return by;
  }

 private:
  double newest_ = -INFINITY;
};

}  // namespace dynaorb::node
