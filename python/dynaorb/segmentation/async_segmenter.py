"""Run the network on its own thread, always on the newest frame.

submit() never blocks: it replaces the frame waiting for the network (older
waiting frames are dropped, the network never falls behind a queue). The
worker keeps the newest result; latest() reads it. A failing network is
logged once and counted; the SLAM side keeps going without masks.

The worker thread runs `nice` steps below the thread that starts it
(priority.py): on busy cores tracking goes first.
"""
from __future__ import annotations

import dataclasses
import logging
import threading
import time

import numpy as np

from dynaorb.segmentation.priority import DEFAULT_NICE, check_nice, lower_thread_priority

log = logging.getLogger(__name__)


@dataclasses.dataclass
class SegmentResult:
    index: int               # frame the labels belong to
    labels: np.ndarray
    inference_ms: float
    total_ms: float
    done_at: float           # time.monotonic() when it finished


class AsyncSegmenter:
    def __init__(self, segmenter, nice: int = DEFAULT_NICE):
        self.segmenter = segmenter
        self.nice = check_nice(nice)
        self.nice_error: str | None = None   # why the worker could not lower its priority
        self._cv = threading.Condition()
        self._pending: tuple[int, np.ndarray] | None = None
        self._latest: SegmentResult | None = None
        self._busy = False
        self._stop = False
        self.submitted = self.processed = self.dropped = self.failures = 0
        self.last_error: str | None = None
        self._thread = threading.Thread(target=self._run, name="segmentation", daemon=True)
        self._thread.start()

    def submit(self, index: int, image: np.ndarray) -> None:
        with self._cv:
            if self._pending is not None:
                self.dropped += 1
            self._pending = (index, image)
            self.submitted += 1
            self._cv.notify()

    def latest(self) -> SegmentResult | None:
        with self._cv:
            return self._latest

    def wait_idle(self, timeout: float | None = None) -> bool:
        """True once no frame waits and none is being segmented (tests, end of a run)."""
        with self._cv:
            return self._cv.wait_for(lambda: self._pending is None and not self._busy, timeout)

    def close(self) -> None:
        with self._cv:
            self._stop = True
            self._cv.notify_all()
        self._thread.join()

    def _run(self) -> None:
        self.nice_error = lower_thread_priority(self.nice)
        if self.nice_error:
            log.warning("segmentation thread keeps tracking's priority (nice %d refused: %s)", self.nice,
                        self.nice_error)
        while True:
            with self._cv:
                self._cv.wait_for(lambda: self._pending is not None or self._stop)
                if self._stop:
                    return
                index, image = self._pending
                self._pending = None
                self._busy = True
            result = None
            try:
                seg = self.segmenter.segment(image)
                result = SegmentResult(index, seg.labels, seg.inference_ms, seg.total_ms, time.monotonic())
            except Exception as exc:  # the network must never take SLAM down
                with self._cv:
                    self.failures += 1
                    self.last_error = f"{type(exc).__name__}: {exc}"
                if self.failures == 1:
                    log.warning("segmentation failed (%s); SLAM continues geometric-only until it recovers "
                                "(further failures are counted only)", self.last_error)
            with self._cv:
                if result is not None:
                    self._latest = result
                    self.processed += 1
                self._busy = False
                self._cv.notify_all()
