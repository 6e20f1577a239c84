"""A segmentation network behind the camera, emulated on a label folder.

`dynaorb run ... --labels DIR --labels-delay N` gives each frame the labels a
network that needs N frames per image would have ready, as the asynchronous
segmentation (`--segment`) and the ROS node's live labels do, but repeatably
and with exact labels: the network starts on frame 0 (the first frame waits
for its labels, SemanticOptions.first_wait_s), finishes it when frame N
arrives, then takes the newest frame, N, finishes it at frame 2N, and so on.
Frame t thus has the labels of frame N * (t // N - 1) (of frame 0 before
frame N), N to 2N - 1 frames old, moved onto it by optical flow along the
frames since (the core's LiveLabels, as the runner's and the node's live
labels are), or as they are with propagate False. What a lagging network
costs the filter, and what the propagation gives back, measured without a
network's own errors.
"""
from __future__ import annotations

import collections
import statistics

import numpy as np

from dynaorb.segmentation.propagation import to_grey


class DelayedLabels:
    def __init__(self, delay: int, propagate: bool = True, max_age: int = 30, flow_scale: float = 0.5,
                 classes=()):
        if isinstance(delay, bool) or not isinstance(delay, int) or delay < 1:
            raise ValueError(f"labels delay {delay!r} is not a whole number of frames >= 1")
        if delay > max_age:
            raise ValueError(f"labels delay {delay} exceeds the labels' maximum age ({max_age} frames): "
                             "no frame would get labels")
        from dynaorb import core

        self.delay = delay
        self.propagate = propagate
        self._live = core().LiveLabels(propagate=propagate, flow_scale=flow_scale, max_age=float(max_age),
                                      frames_kept=max(64, max_age + 2), classes=[int(c) for c in classes])
        self._pending: dict[int, np.ndarray | None] = {}   # frames' labels the emulated network is "working on"
        self._delivered = -1
        self.sources = collections.Counter()
        self.ages: list[int] = []
        self.propagate_ms: list[float] = []

    def source_frame(self, index: int) -> int:
        """The frame whose labels frame `index` gets."""
        return 0 if index < self.delay else self.delay * (index // self.delay - 1)

    def labels_for(self, index: int, own_labels: np.ndarray | None, image: np.ndarray) -> np.ndarray | None:
        """own_labels: the folder's labels of this frame (what the network will deliver later)."""
        if index % self.delay == 0:
            self._pending[index] = own_labels
        source = self.source_frame(index)
        if source > self._delivered:
            labels = self._pending.pop(source, None)
            for k in [k for k in self._pending if k < source]:
                del self._pending[k]
            self._delivered = source
            if labels is not None:
                self._live.add_labels(float(source), labels)
        labels, kind, age, ms = self._live.labels_for(float(index), to_grey(image))
        self.sources[kind] += 1
        if labels is not None:
            self.ages.append(int(round(age)))
            if ms > 0:
                self.propagate_ms.append(ms)
        return labels

    def summary(self) -> dict:
        return {"delay_frames": self.delay, "propagate": self.propagate, "frames": dict(self.sources),
                "age_median": statistics.median(self.ages) if self.ages else None,
                "age_max": max(self.ages) if self.ages else None,
                "propagate_ms_median": statistics.median(self.propagate_ms) if self.propagate_ms else None}
