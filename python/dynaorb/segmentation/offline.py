"""`dynaorb segment`: label images for a whole sequence, as a mask cache.

Writes OUT/<frame image name> (8-bit PNG, pixel = class id) for every frame,
and OUT/labels.json naming the label set and its movable classes, so that
`dynaorb run --masks OUT` knows the PNGs are labels (DynaSLAM's mask folder,
with the label meaning kept beside it). Frames already in the cache are kept
unless overwrite is set; unreadable frames are counted and skipped.
"""
from __future__ import annotations

import collections
import json
import pathlib
import statistics

from dynaorb.image_files import write_image
from dynaorb.runner.frames import frame_file_name, readable_frames
from dynaorb.segmentation.segmenter import Segmenter

LABELS_FILE = "labels.json"


def write_label_info(out: pathlib.Path, segmenter: Segmenter) -> None:
    card = segmenter.card
    info = {"model": card.name, "model_file": str(segmenter.path), "labels": card.labels,
            "movable": card.movable}
    (out / LABELS_FILE).write_text(json.dumps(info, indent=2) + "\n")


def segment_sequence(kind: str, path: str, segmenter: Segmenter, out: str | pathlib.Path,
                     overwrite: bool = False, progress: bool = True) -> dict:
    from dynaorb import core

    provider = core().open_dataset(kind, path, None)
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_label_info(out, segmenter)
    counts = collections.Counter()
    ms = []
    for _, frame in readable_frames(provider, counts, progress, f"segmenting {pathlib.Path(path).name}"):
        target = out / frame_file_name(frame)
        if target.is_file() and not overwrite:
            counts["cached"] += 1
            continue
        seg = segmenter.segment(frame.image)
        write_image(target, seg.labels, "label image")
        ms.append(seg.total_ms)
        counts["segmented"] += 1
    return {"frames": len(provider), **counts, "ms_median": statistics.median(ms) if ms else None,
            "out": str(out), "model": segmenter.card.name}
