#pragma once
// Scheduling priority of background threads. Tracking is the latency-critical
// thread of a SLAM system; local mapping, loop closing and global BA are
// background work whose results may come a frame later. On a machine with
// fewer cores than busy threads, a lower priority (a higher nice value) for
// the background threads hands the tracking thread its CPU first, while an
// idle core still runs them at full speed.
//
// Not SCHED_IDLE, which would spare tracking the last preemptions by local
// mapping: tried on KITTI 06 stereo, `full` with the network beside it,
// asynchronous mapping, unpaced (3 + 3 runs), the track call went 19.5 ->
// 17.9 ms, but local mapping starved (0-6 keyframes against 28-29) and
// tracking was lost after 41-80 % of the frames.
//
// Nor a short EEVDF slice for the tracking side (Linux >= 6.12 takes
// sched_attr.sched_runtime of a SCHED_OTHER thread as its slice, and a waking
// thread with a shorter slice than the running one preempts it). Tried with
// sched_setattr on the tracking thread and its helper threads, unpaced
// asynchronous runs on Linux 6.18, track call medians' median, without ->
// with a 300 us slice: synthetic monocular with movers (`full` + labels)
// 9.34 -> 8.54 ms (8 + 8 runs; 100 us: 9.18), synthetic stereo with movers
// 14.46 -> 14.60 (5 + 5), KITTI 06 `off` 11.87 -> 12.85 (6 + 6; 11.45 ->
// 12.12 in another 4 + 4): the shorter slices preempt the tracking thread
// more often too.
//
// Nor a short slice for the background threads instead (the tracking side
// unchanged), to end the wait of a woken foreground helper behind local
// mapping: on Linux 6.18 with HZ 250 a woken FrameBuilder helper that does
// not preempt the nice-10 mapping thread at once waits for the next tick. On
// the synthetic monocular clip with movers (`full`, unpaced, asynchronous)
// the helper began its first pyramid level more than 1.4 ms after the
// extraction started on 16 of 60 frames (up to 4.8 ms; sched_switch traces
// show local mapping on the other core until the tick), and on 5 of 60 with
// a 100 us slice for the background threads (sched_setattr's
// sched_runtime). Track call medians in paired runs, 300 us slice against
// none: that clip -0.63 ms (10 of 12 pairs faster), then -0.06 (8 of 16),
// paced -0.10 (5 of 10); KITTI 06 `off` +1.06 (2 of 8), then -0.29 (8 of
// 14); synthetic stereo with movers +0.03 (4 of 8). Within the runs' spread.

#include <string>

namespace dynaorb {

// Sets the calling thread's nice value to the process's (its main thread's)
// plus `increment`, at most 19 (Linux keeps a nice value per thread; raising
// it needs no privilege). Idempotent: a thread started by a background thread
// (which inherits its nice value) calls it again and gets the same value.
// <= 0: nothing, true. false: the platform has no per-thread nice, or the
// call was refused; the thread then runs at the priority it had.
bool set_background_priority(int increment);

// The check of a background nice increment as the adapters take it (the ROS
// node's ~background_nice, the Python System's background_nice): InputError
// "<name> must be in [0, 19], got <nice>" unless it is in [0, 19].
void check_background_nice(int nice, const std::string& name);

}  // namespace dynaorb
