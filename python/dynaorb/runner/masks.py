"""Per-frame masks from a folder (a mask cache, or synthetic label / ground-truth masks).

The mask of a frame is the file in the folder with the frame image's name
(TUM: <stamp>.png, KITTI: %06d.png, EuRoC: <ns>.png). Missing or unreadable
masks are counted, not fatal: the frame runs without one.

A folder with a labels.json (written by `dynaorb segment`) holds label
images: the movable classes it names become the mask. Otherwise every
non-zero pixel is masked (ground-truth dynamic masks, 0/255 masks).
"""
from __future__ import annotations

import collections
import json
import logging
import pathlib

import cv2
import numpy as np

log = logging.getLogger(__name__)


class MaskFolder:
    def __init__(self, folder: str | pathlib.Path):
        self.folder = pathlib.Path(folder)
        if not self.folder.is_dir():
            raise FileNotFoundError(f"{self.folder}: mask folder does not exist")
        self.counts = collections.Counter()
        self.label_info = None
        self._movable = None
        info = self.folder / "labels.json"
        if info.is_file():
            try:
                self.label_info = json.loads(info.read_text())
                ids = [int(i) for i in self.label_info["movable"]]
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"{info}: not a label description with a 'movable' id list ({exc})") from None
            self._movable = np.zeros(65536, bool)
            self._movable[ids] = True

    def for_image(self, image_path: str, shape: tuple[int, int]) -> np.ndarray | None:
        path = self.folder / pathlib.Path(image_path).name
        if not path.is_file():
            self.counts["missing"] += 1
            if self.counts["missing"] == 1:
                log.warning("no mask for %s in %s (further misses are counted only)", image_path, self.folder)
            return None
        mask = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if mask is None or mask.ndim != 2 or mask.shape != tuple(shape):
            self.counts["unusable"] += 1
            log.warning("mask %s is unreadable or not %dx%d single-channel: frame runs without it",
                        path, shape[1], shape[0])
            return None
        self.counts["used"] += 1
        if self._movable is not None:
            return np.where(self._movable[mask], np.uint8(255), np.uint8(0))
        return np.ascontiguousarray(mask.astype(np.uint8) if mask.dtype != np.uint16 else mask)


class LabelFolder:
    """Per-frame label images (class ids) for the dynamic filter's semantic stage.

    A folder written by `dynaorb segment` (with labels.json naming the label
    set and its movable ids), or a folder of label PNGs in the preset's label
    set (the synthetic sequences' labels/: PASCAL VOC ids). Missing or
    unreadable label images are counted: the frame runs without labels.
    """

    def __init__(self, folder: str | pathlib.Path):
        self.folder = pathlib.Path(folder)
        if not self.folder.is_dir():
            raise FileNotFoundError(f"{self.folder}: label folder does not exist")
        self.counts = collections.Counter()
        self.label_info = None
        self.movable: list[int] | None = None  # the folder's own movable ids (labels.json)
        info = self.folder / "labels.json"
        if info.is_file():
            try:
                self.label_info = json.loads(info.read_text())
                self.movable = [int(i) for i in self.label_info["movable"]]
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"{info}: not a label description with a 'movable' id list ({exc})") from None

    def for_image(self, image_path: str, shape: tuple[int, int]) -> np.ndarray | None:
        path = self.folder / pathlib.Path(image_path).name
        if not path.is_file():
            self.counts["missing"] += 1
            if self.counts["missing"] == 1:
                log.warning("no labels for %s in %s (further misses are counted only)", image_path, self.folder)
            return None
        labels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if labels is None or labels.ndim != 2 or labels.shape != tuple(shape) or labels.dtype not in (np.uint8,
                                                                                                      np.uint16):
            self.counts["unusable"] += 1
            log.warning("labels %s are unreadable or not %dx%d single-channel 8/16-bit: frame runs without them",
                        path, shape[1], shape[0])
            return None
        self.counts["used"] += 1
        return np.ascontiguousarray(labels)
