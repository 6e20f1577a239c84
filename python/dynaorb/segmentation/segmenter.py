"""Segmenter: one image in, a per-pixel label image of the same size out.

Pre-processing: BGR (OpenCV's order) or grey to the model's colour order,
bilinear resize to the model's input size, the card's dtype and normalisation.
Post-processing: argmax when the model outputs logits, nearest-neighbour
resize back to the image size (labels are ids, never interpolated).
"""
from __future__ import annotations

import dataclasses
import pathlib
import time

import cv2
import numpy as np

from dynaorb.segmentation.backends import open_backend
from dynaorb.segmentation.model_card import ModelCard, backend_of, card_path


@dataclasses.dataclass
class Segmentation:
    labels: np.ndarray         # HxW uint8 class ids
    inference_ms: float        # network only
    total_ms: float            # with pre- and post-processing


def load_card(model: str | pathlib.Path) -> ModelCard:
    """The card beside a model file, or the catalog's card when the file is a known public model."""
    from dynaorb.segmentation.catalog import CATALOG, entry_for_file

    model = pathlib.Path(model)
    beside = card_path(model)
    if beside.is_file():
        return ModelCard.load(beside)
    entry = entry_for_file(model)
    if entry is None:
        raise ValueError(f"{model}: no model card {beside.name} beside the model, and the file is not one of "
                         f"the known models ({', '.join(e.tflite for e in CATALOG.values())}); "
                         "write a card (see dynaorb.segmentation.model_card)")
    backend_of(model)  # a clear error for an unknown format
    return entry.card(model)


class Segmenter:
    """Loads a model (path to .onnx/.tflite, with or without a card) and segments images."""

    def __init__(self, model: str | pathlib.Path, threads: int = 2, card: ModelCard | None = None):
        self.path = pathlib.Path(model)
        self.card = card or load_card(self.path)
        self.backend = open_backend(self.card.backend, self.path, threads)
        self._check_input_shape()
        self.labels = list(self.card.labels)
        self.movable = np.zeros(256, bool)
        self.movable[self.card.movable] = True

    def _check_input_shape(self) -> None:
        spec = self.card.input
        expected = (1, spec.height, spec.width, 3) if spec.layout == "NHWC" else (1, 3, spec.height, spec.width)
        actual = self.backend.input_shape
        ok = len(actual) == 4 and all(not isinstance(a, int) or a == e for a, e in zip(actual, expected))
        if not ok:
            raise ValueError(f"{self.path}: the model's input shape {actual} does not match its card "
                             f"({spec.layout} {spec.width}x{spec.height}x3)")

    def preprocess(self, image: np.ndarray) -> np.ndarray:
        if image is None or image.ndim not in (2, 3) or image.size == 0:
            raise ValueError(f"segmentation needs a grey or 3-channel image, got "
                             f"{None if image is None else image.shape}")
        spec = self.card.input
        if image.ndim == 2:
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        elif image.shape[2] == 4:
            image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
        elif image.shape[2] != 3:
            raise ValueError(f"segmentation needs 1, 3 or 4 channels, got {image.shape[2]}")
        if image.dtype != np.uint8:
            raise ValueError(f"segmentation needs an 8-bit image, got {image.dtype}")
        if spec.color == "RGB":
            image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
        x = cv2.resize(image, (spec.width, spec.height), interpolation=cv2.INTER_LINEAR)
        if spec.dtype == "float32":
            x = x.astype(np.float32)
            if spec.mean is not None:
                x -= np.asarray(spec.mean, np.float32)
            if spec.std is not None:
                x /= np.asarray(spec.std, np.float32)
        if spec.layout == "NCHW":
            x = x.transpose(2, 0, 1)
        return np.ascontiguousarray(x[None])

    def postprocess(self, y: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        spec = self.card.input
        y = np.asarray(y)
        if y.ndim == 4 and y.shape[0] == 1:
            y = y[0]
        elif y.ndim == 3 and y.shape[0] == 1:
            y = y[0]
        if self.card.output == "logits":
            if y.ndim != 3:
                raise ValueError(f"{self.path}: logits output has shape {y.shape}, expected 3 dimensions")
            axis = -1 if spec.layout == "NHWC" else 0
            y = np.argmax(y, axis=axis)
        if y.ndim != 2:
            raise ValueError(f"{self.path}: label output has shape {y.shape}, expected HxW")
        if y.size and (y.min() < 0 or y.max() >= len(self.labels)):
            raise ValueError(f"{self.path}: label ids {int(y.min())}..{int(y.max())} outside the card's "
                             f"{len(self.labels)} labels")
        labels = y.astype(np.uint8)
        h, w = size
        if labels.shape != (h, w):
            labels = cv2.resize(labels, (w, h), interpolation=cv2.INTER_NEAREST)
        return labels

    def segment(self, image: np.ndarray) -> Segmentation:
        """image: HxW grey or HxWx3 BGR (OpenCV's order), uint8."""
        t0 = time.perf_counter()
        x = self.preprocess(image)
        t1 = time.perf_counter()
        y = self.backend.run(x)
        t2 = time.perf_counter()
        labels = self.postprocess(y, image.shape[:2])
        return Segmentation(labels, (t2 - t1) * 1e3, (time.perf_counter() - t0) * 1e3)

    def movable_mask(self, labels: np.ndarray) -> np.ndarray:
        """255 where the label is a movable class, else 0 (the core's exclusion mask)."""
        return np.where(self.movable[labels], np.uint8(255), np.uint8(0))
