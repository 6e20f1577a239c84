"""Iterating a dataset's frames: a progress bar, and unreadable frames counted, not fatal."""
from __future__ import annotations

import collections
import logging

from dynaorb import core

log = logging.getLogger(__name__)


def readable_frames(provider, counts: collections.Counter, progress: bool, desc: str):
    """(index, frame) for every frame that loads; the others are logged and
    counted in counts["unreadable"]."""
    indices = range(len(provider))
    if progress:
        from tqdm import tqdm

        indices = tqdm(indices, desc=desc, unit="frame")
    for i in indices:
        try:
            frame = provider.load(i)
        except core().InputError as exc:
            counts["unreadable"] += 1
            log.warning("frame %d skipped: %s", i, exc)
            continue
        yield i, frame
