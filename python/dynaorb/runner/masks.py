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


def _read_named(folder: pathlib.Path, image_path: str, shape: tuple[int, int], counts: collections.Counter,
                what: str, form: str, dtypes: tuple | None = None) -> np.ndarray | None:
    """The single-channel image named like the frame's image in `folder`, of the frame's size (and of one of
    `dtypes` when given); None, counted as "missing" (the first one logged) or "unusable" (logged), otherwise."""
    path = folder / pathlib.Path(image_path).name
    if not path.is_file():
        counts["missing"] += 1
        if counts["missing"] == 1:
            log.warning("no %s for %s in %s (further misses are counted only)", what, image_path, folder)
        return None
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if (image is None or image.ndim != 2 or image.shape != tuple(shape)
            or (dtypes is not None and image.dtype not in dtypes)):
        counts["unusable"] += 1
        log.warning("%s %s: unreadable or not %dx%d %s: the frame runs without it", what, path, shape[1],
                    shape[0], form)
        return None
    counts["used"] += 1
    return image


def _label_info(folder: pathlib.Path) -> tuple[dict | None, list[int] | None]:
    """The folder's labels.json (written by `dynaorb segment`) and its movable ids; (None, None) without one.
    ValueError names a file that is not such a description."""
    info = folder / "labels.json"
    if not info.is_file():
        return None, None
    try:
        label_info = json.loads(info.read_text())
        return label_info, [int(i) for i in label_info["movable"]]
    except (ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{info}: not a label description with a 'movable' id list ({exc})") from None


class MaskFolder:
    def __init__(self, folder: str | pathlib.Path):
        self.folder = pathlib.Path(folder)
        if not self.folder.is_dir():
            raise FileNotFoundError(f"{self.folder}: mask folder does not exist")
        self.counts = collections.Counter()
        self.label_info, ids = _label_info(self.folder)
        self._movable = None
        if ids is not None:
            self._movable = np.zeros(65536, bool)
            self._movable[ids] = True

    def for_image(self, image_path: str, shape: tuple[int, int]) -> np.ndarray | None:
        mask = _read_named(self.folder, image_path, shape, self.counts, "mask", "single-channel")
        if mask is None:
            return None
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
        # The folder's own movable ids (labels.json), or None.
        self.label_info, self.movable = _label_info(self.folder)

    def for_image(self, image_path: str, shape: tuple[int, int]) -> np.ndarray | None:
        labels = _read_named(self.folder, image_path, shape, self.counts, "labels", "single-channel 8/16-bit",
                             dtypes=(np.uint8, np.uint16))
        return None if labels is None else np.ascontiguousarray(labels)
