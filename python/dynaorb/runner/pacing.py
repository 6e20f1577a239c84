"""Frames delivered at the recording's rate, as a live camera or `rosbag play`
would deliver them (ORB-SLAM2's example runners sleep the same way).

A runner that hands frames to SLAM as fast as it can track them lets tracking
outrun a local-mapping thread that a live camera would give the time between
frames: monocular tracking then inserts keyframes only every few frames (its
keyframe rule waits for an idle mapper) and can starve its map. With a rate,
each frame is held back until its stamp, scaled by 1 / rate, has passed
since the first frame; a frame that is already late is handed over at once
(never dropped), and the lateness is counted.
"""
from __future__ import annotations

import math
import time


class Pacer:
    def __init__(self, rate: float, clock=time.perf_counter, sleep=time.sleep):
        if not (rate > 0 and math.isfinite(rate)):
            raise ValueError(f"realtime rate {rate!r}: expected a positive number (1 = the recording's speed)")
        self.rate = rate
        self._clock = clock
        self._sleep = sleep
        self._origin = None  # (first stamp, clock then)
        self._last = -math.inf  # the latest stamp paced
        self.frames = 0
        self.late_frames = 0      # handed over after their due time (tracking fell behind)
        self.max_late_ms = 0.0
        self.unpaced_frames = 0   # stamps that cannot be paced (not finite, or before an earlier one)
        self.waited_s = 0.0

    def wait(self, stamp: float) -> None:
        """Returns once the frame stamped `stamp` (seconds) is due."""
        self.frames += 1
        now = self._clock()
        if not math.isfinite(stamp):
            self.unpaced_frames += 1
            return
        if self._origin is None:
            self._origin = (stamp, now)
            self._last = stamp
            return
        if stamp < self._last:  # out of order: no due time of its own
            self.unpaced_frames += 1
            return
        self._last = stamp
        offset = stamp - self._origin[0]
        due = self._origin[1] + offset / self.rate
        if now >= due:
            late_ms = 1000.0 * (now - due)
            if late_ms > 1.0:  # a millisecond of scheduling noise is not falling behind
                self.late_frames += 1
                self.max_late_ms = max(self.max_late_ms, late_ms)
            return
        self._sleep(due - now)
        self.waited_s += due - now

    def summary(self) -> dict:
        return {"rate": self.rate, "frames": self.frames, "late_frames": self.late_frames,
                "max_late_ms": self.max_late_ms, "unpaced_frames": self.unpaced_frames,
                "waited_s": self.waited_s}
