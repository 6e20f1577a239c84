"""Running the network below tracking's priority.

Linux niceness is per thread: a thread, or every thread of a process, can
lower itself without privileges. The network is background work: when the
cores are busy, tracking gets them first (as the core's background_nice does
for local mapping and loop closing), and the frames the network skips get
older labels propagated by optical flow.
"""
from __future__ import annotations

import os
import threading

# The network's nice above tracking's unless told otherwise (the core's
# background_nice default for local mapping and loop closing is 10 too).
DEFAULT_NICE = 10

# Passes of lower_process_priority before it gives up (each one after the
# first only finds threads started during the pass before).
_MAX_PASSES = 20


def check_nice(nice: int, name: str = "nice") -> int:
    """`nice` if it is an int in [0, 19] (how far a thread may lower itself); ValueError otherwise."""
    if isinstance(nice, bool) or not isinstance(nice, int) or not 0 <= nice <= 19:
        raise ValueError(f"{name} {nice!r} is not an integer in [0, 19] (0: the network at tracking's priority)")
    return nice


def _lower(tid: int, nice: int) -> None:
    os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + nice))


def lower_thread_priority(nice: int) -> str | None:
    """Lower the calling thread's priority by `nice`; the threads it starts later inherit it.
    None when done, else why not (the thread then keeps its priority)."""
    if nice == 0:
        return None
    try:
        _lower(threading.get_native_id(), nice)
    except (OSError, AttributeError) as exc:  # not Linux, or a sandbox that refuses it
        return f"{type(exc).__name__}: {exc}"
    return None


def lower_process_priority(nice: int) -> str | None:
    """Lower every thread of this process to the calling thread's nice plus
    `nice` (a node whose whole work is the network). None when done, else why not.

    Threads keep being started while this runs (rospy's, after init_node): one
    started from a thread not yet lowered, after the thread list was read,
    would keep the old priority. So the threads are set to that one target
    (never lowered twice, never raised) pass after pass, until a pass finds
    none below it: every thread started after that pass's list comes from one
    already at the target and inherits it."""
    if nice == 0:
        return None
    try:
        target = min(19, os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) + nice)
        for _ in range(_MAX_PASSES):
            changed = False
            for tid in os.listdir("/proc/self/task"):
                try:
                    if os.getpriority(os.PRIO_PROCESS, int(tid)) < target:
                        os.setpriority(os.PRIO_PROCESS, int(tid), target)
                        changed = True
                except ProcessLookupError:  # a thread that ended meanwhile
                    pass
            if not changed:
                return None
    except (OSError, ValueError, AttributeError) as exc:  # no /proc (not Linux), or refused
        return f"{type(exc).__name__}: {exc}"
    return f"threads still being started below nice {target} after {_MAX_PASSES} passes"
