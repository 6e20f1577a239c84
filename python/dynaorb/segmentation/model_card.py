"""The model card: what a segmentation network expects and what it outputs.

A card is a small JSON file kept beside the model (`<model file>.card.json`):

    {"name": "deeplabv3_mnv2_pascal", "file": "deeplabv3_mnv2_pascal_quant.onnx",
     "backend": "onnx",                      # or "tflite"
     "input": {"height": 513, "width": 513, "layout": "NHWC", "dtype": "uint8",
               "color": "RGB", "mean": null, "std": null},
     "output": "labels",                     # or "logits" (argmax over the class axis)
     "labels": ["background", ...], "movable": [1, 2, ...],
     "sha256": "...", "source": "https://..."}

Float inputs are normalised as (pixel - mean) / std per channel.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import pathlib

CARD_SUFFIX = ".card.json"
BACKENDS = {".onnx": "onnx", ".tflite": "tflite"}


@dataclasses.dataclass
class InputSpec:
    height: int
    width: int
    layout: str = "NHWC"       # NHWC or NCHW
    dtype: str = "uint8"       # uint8 or float32
    color: str = "RGB"         # RGB or BGR
    mean: list[float] | None = None
    std: list[float] | None = None

    def validate(self, where: str) -> None:
        if self.height <= 0 or self.width <= 0:
            raise ValueError(f"{where}: input size {self.width}x{self.height} is not positive")
        if self.layout not in ("NHWC", "NCHW"):
            raise ValueError(f"{where}: input layout {self.layout!r} is not NHWC or NCHW")
        if self.dtype not in ("uint8", "float32"):
            raise ValueError(f"{where}: input dtype {self.dtype!r} is not uint8 or float32")
        if self.color not in ("RGB", "BGR"):
            raise ValueError(f"{where}: input color {self.color!r} is not RGB or BGR")
        for key in ("mean", "std"):
            v = getattr(self, key)
            if v is not None and len(v) != 3:
                raise ValueError(f"{where}: input {key} needs 3 values, got {v}")


@dataclasses.dataclass
class ModelCard:
    name: str
    file: str
    backend: str
    input: InputSpec
    labels: list[str]
    movable: list[int]
    output: str = "labels"     # labels (class id per pixel) or logits (scores per class)
    sha256: str | None = None
    source: str | None = None

    def validate(self, where: str = "model card") -> "ModelCard":
        if self.backend not in BACKENDS.values():
            raise ValueError(f"{where}: backend {self.backend!r} is not one of {sorted(BACKENDS.values())}")
        if self.output not in ("labels", "logits"):
            raise ValueError(f"{where}: output {self.output!r} is not 'labels' or 'logits'")
        if not self.labels or len(self.labels) > 256:
            raise ValueError(f"{where}: needs 1 to 256 label names, got {len(self.labels)}")
        bad = [i for i in self.movable if not 0 <= i < len(self.labels)]
        if bad:
            raise ValueError(f"{where}: movable ids {bad} are not label ids 0..{len(self.labels) - 1}")
        self.input.validate(where)
        return self

    @property
    def movable_names(self) -> list[str]:
        return [self.labels[i] for i in self.movable]

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict, where: str = "model card") -> "ModelCard":
        try:
            d = dict(d)
            d["input"] = InputSpec(**d["input"])
            d["labels"] = list(d["labels"])
            d["movable"] = [int(i) for i in d["movable"]]
            return cls(**d).validate(where)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"{where}: missing or unexpected key ({exc})") from None

    def save(self, path: str | pathlib.Path) -> pathlib.Path:
        path = pathlib.Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        return path

    @classmethod
    def load(cls, path: str | pathlib.Path) -> "ModelCard":
        path = pathlib.Path(path)
        try:
            d = json.loads(path.read_text())
        except FileNotFoundError:
            raise FileNotFoundError(f"{path}: model card does not exist") from None
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: model card is not valid JSON ({exc})") from None
        return cls.from_dict(d, where=str(path))


def card_path(model: str | pathlib.Path) -> pathlib.Path:
    model = pathlib.Path(model)
    return model.with_name(model.name + CARD_SUFFIX)


def backend_of(model: str | pathlib.Path) -> str:
    suffix = pathlib.Path(model).suffix.lower()
    if suffix not in BACKENDS:
        raise ValueError(f"{model}: unknown model format {suffix!r} (known: {', '.join(BACKENDS)})")
    return BACKENDS[suffix]


def sha256_of(path: str | pathlib.Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
