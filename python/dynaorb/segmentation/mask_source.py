"""Per-frame semantic labels for the SLAM loop, without ever stalling it.

mode "sync": the network runs on every frame before it is tracked
(repeatable, slow). mode "async": the network runs on its own thread on the
newest frame; a frame without a fresh result gets the newest labels moved to
it by optical flow along the frames since (the core's LiveLabels, as the ROS
node does), and its age (frames since the network saw the image the labels
come from) is recorded. Labels older than max_age_frames are not
used: the frame runs geometric-only, which is logged once and counted.
The first frame waits for its own labels (at most first_wait_s): tracking
builds its first map from that frame, and movers' points taken into it stay
there.
"""
from __future__ import annotations

import collections
import dataclasses
import logging
import math
import statistics
import time

import numpy as np

from dynaorb.segmentation.async_segmenter import AsyncSegmenter
from dynaorb.segmentation.priority import DEFAULT_NICE, check_nice
from dynaorb.segmentation.propagation import to_grey

log = logging.getLogger(__name__)


@dataclasses.dataclass
class SemanticOptions:
    mode: str = "async"          # async | sync
    max_age_frames: int = 30     # older labels are dropped (about 1 s at 30 Hz)
    propagate: bool = True       # move old labels by optical flow (else use them as they are)
    flow_scale: float = 0.5      # resolution of the flow, relative to the image
    # async: the label ids carried from frame to frame (the model's movable
    # classes: the only ones the filter reads); the others become background,
    # and labels without any of them need no flow. Empty: all ids.
    classes: tuple[int, ...] = ()
    # async: the network thread's nice above the caller's (0-19), so tracking
    # gets the cores first on a busy machine (see async_segmenter).
    nice: int = DEFAULT_NICE
    # async: how long the first frame waits for its labels (s; 0: it does not
    # wait). The map starts from it: without labels, the movers in view become
    # map points (see the README's segmentation section for the measurement).
    first_wait_s: float = 10.0

    def validate(self) -> "SemanticOptions":
        if self.mode not in ("async", "sync"):
            raise ValueError(f"segmentation mode {self.mode!r} is not 'async' or 'sync'")
        if self.max_age_frames < 0:
            raise ValueError(f"max_age_frames {self.max_age_frames} is negative")
        check_nice(self.nice, "segmentation nice")
        bad = [c for c in self.classes if isinstance(c, bool) or not isinstance(c, (int, np.integer))
               or not 0 <= c <= 65535]
        if bad:
            raise ValueError(f"class ids {bad} are not label ids (0-65535)")
        if not (self.first_wait_s >= 0) or math.isinf(self.first_wait_s):
            raise ValueError(f"first_wait_s {self.first_wait_s} is not a finite number of seconds >= 0")
        return self


@dataclasses.dataclass
class FrameLabels:
    labels: np.ndarray | None
    source: str                  # fresh | propagated | as_is (propagate off) | stale | none
    age: int                     # frames; -1 without labels


class SemanticMasks:
    def __init__(self, segmenter, options: SemanticOptions | None = None):
        self.segmenter = segmenter
        self.options = (options or SemanticOptions()).validate()
        self.worker = (AsyncSegmenter(segmenter, nice=self.options.nice)
                       if self.options.mode == "async" else None)
        self.counts = collections.Counter()
        self.ages: list[int] = []
        self.inference_ms: list[float] = []
        self.propagate_ms: list[float] = []
        self.propagate_skipped = 0           # propagations of background-only labels, skipped
        self.sync_failures = 0
        self._seen_result = -1               # frame index of the last network result taken
        # Which labels each frame gets, keyed by frame index (max_age in frames).
        self._live = None
        if self.worker is not None:
            from dynaorb import core

            self._live = core().LiveLabels(propagate=self.options.propagate, flow_scale=self.options.flow_scale,
                                          max_age=float(self.options.max_age_frames),
                                          frames_kept=max(64, self.options.max_age_frames + 2),
                                          classes=[int(c) for c in self.options.classes])
        self._stale_logged = False
        self.first_wait_ms: float | None = None   # how long the first frame waited for its labels
        self.first_wait_timed_out = False

    def labels_for(self, index: int, image: np.ndarray) -> FrameLabels:
        out = self._sync(image) if self.worker is None else self._async(index, image)
        self.counts[out.source] += 1
        if out.labels is not None:
            self.ages.append(out.age)
        return out

    def _sync(self, image: np.ndarray) -> FrameLabels:
        try:
            seg = self.segmenter.segment(image)
        except Exception as exc:  # the network must never take SLAM down
            self.sync_failures += 1
            if self.sync_failures == 1:
                log.warning("segmentation failed (%s: %s); SLAM continues geometric-only "
                            "(further failures are counted only)", type(exc).__name__, exc)
            return FrameLabels(None, "none", -1)
        self.inference_ms.append(seg.inference_ms)
        return FrameLabels(seg.labels, "fresh", 0)

    def _async(self, index: int, image: np.ndarray) -> FrameLabels:
        self.worker.submit(index, image)
        grey = to_grey(image)
        if self.first_wait_ms is None and self.options.first_wait_s > 0:
            self._wait_first()
        result = self.worker.latest()
        if result is not None and result.index > self._seen_result:
            # A new network result (it may be a few frames old).
            self._seen_result = result.index
            self.inference_ms.append(result.inference_ms)
            self._live.add_labels(float(result.index), result.labels)
        labels, source, age, ms = self._live.labels_for(float(index), grey)
        if source == "stale" and not self._stale_logged:
            self._stale_logged = True
            log.warning("segmentation is %d frames behind (limit %d): SLAM continues geometric-only "
                        "until a fresh mask arrives (counted as 'stale')", index - self._seen_result,
                        self.options.max_age_frames)
        if labels is None:
            return FrameLabels(None, source, -1)
        if source == "propagated":
            if ms > 0:
                self.propagate_ms.append(ms)
            else:
                # Only background: any flow carries it to background. No flow
                # on scenes without objects (2 ms per frame at 752x480).
                self.propagate_skipped += 1
        return FrameLabels(labels, source, int(round(age)))

    def _wait_first(self) -> None:
        """Wait for the network to finish the first frame (a failing network finishes at once)."""
        t = time.perf_counter()
        done = self.worker.wait_idle(self.options.first_wait_s)
        self.first_wait_ms = (time.perf_counter() - t) * 1e3
        if not done:
            self.first_wait_timed_out = True
            log.warning("segmentation gave no labels for the first frame within %.1f s: tracking starts "
                        "without them (movers in view may enter the first map)", self.options.first_wait_s)

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()

    def summary(self) -> dict:
        med = lambda v: statistics.median(v) if v else None  # noqa: E731
        s = {"mode": self.options.mode, "frames": dict(self.counts),
             "age_median": med(self.ages), "age_max": max(self.ages) if self.ages else None,
             "inference_ms_median": med(self.inference_ms), "propagate_ms_median": med(self.propagate_ms),
             "propagate_skipped": self.propagate_skipped,
             "failures": self.sync_failures}
        if self.worker is not None:
            s.update(submitted=self.worker.submitted, segmented=self.worker.processed,
                     dropped_unseen=self.worker.dropped, failures=self.worker.failures,
                     last_error=self.worker.last_error, nice=self.worker.nice,
                     nice_error=self.worker.nice_error, first_wait_ms=self.first_wait_ms,
                     first_wait_timed_out=self.first_wait_timed_out)
        return s
