"""Writing image files: cv2.imwrite answers a full disk or a folder gone with False,
which left unchecked leaves a hole in a sequence or a cache unnoticed."""
from __future__ import annotations

import pathlib

import cv2
import numpy as np


def write_image(path: str | pathlib.Path, image: np.ndarray, what: str = "image") -> None:
    """cv2.imwrite(path, image), or OSError naming the file and what it holds."""
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{path}: cannot write the {what}")
