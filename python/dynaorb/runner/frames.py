"""Iterating a dataset's frames (a progress bar, unreadable frames counted, not fatal) and their file names."""
from __future__ import annotations

import collections
import logging
import operator
import pathlib

from dynaorb import core

log = logging.getLogger(__name__)


def frame_range(spec, n: int) -> range:
    """The frames to run of a sequence of n: spec None (all), "START:END" (END
    not included; either side may be empty) or a (start, end) pair. ValueError
    naming what is wrong: not two numbers, negative, or no frame of the
    sequence in the range (an END past the last frame runs to the last)."""
    if spec is None:
        return range(n)
    # An open side: empty in a string, None in a pair.
    parts = [p.strip() or None for p in spec.split(":")] if isinstance(spec, str) else list(spec)
    if len(parts) != 2:
        raise ValueError(f"frames {spec!r}: give START:END (frame numbers from 0, END not included)")
    try:
        start, end = (d if p is None else int(p) if isinstance(p, str) else operator.index(p)
                      for p, d in zip(parts, (0, n)))
    except (ValueError, TypeError):
        raise ValueError(f"frames {spec!r}: START and END must be whole numbers") from None
    if start < 0 or end < 0:
        raise ValueError(f"frames {spec!r}: frame numbers count from 0")
    if start >= min(end, n):
        raise ValueError(f"frames {spec!r}: no frame of the sequence's {n} (0-{n - 1}) in that range")
    return range(start, min(end, n))


def readable_frames(provider, counts: collections.Counter, progress: bool, desc: str, indices: range | None = None):
    """(index, frame) for every frame of `indices` (default: all) that loads;
    the others are logged and counted in counts["unreadable"]."""
    indices = range(len(provider)) if indices is None else indices
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


def frame_file_name(frame) -> str:
    """The name a frame's per-frame files (masks, labels) have in a folder: its
    image file's (TUM: <stamp>.png, KITTI: %06d.png, EuRoC: <ns>.png), or the
    frame's own `file_name` where it has no file (a bag's frame: <stamp>.png,
    the stamp with 6 decimals)."""
    return getattr(frame, "file_name", "") or pathlib.Path(frame.image_path).name
