"""Iterating a dataset's frames (a progress bar, unreadable frames counted, not fatal) and their file names."""
from __future__ import annotations

import collections
import logging
import pathlib

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


def frame_file_name(frame) -> str:
    """The name a frame's per-frame files (masks, labels) have in a folder: its
    image file's (TUM: <stamp>.png, KITTI: %06d.png, EuRoC: <ns>.png), or the
    frame's own `file_name` where it has no file (a bag's frame: <stamp>.png,
    the stamp with 6 decimals)."""
    return getattr(frame, "file_name", "") or pathlib.Path(frame.image_path).name
