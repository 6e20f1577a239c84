"""The public segmentation models dynaorb knows: where to get them, what they are.

The DeepLab v3 TFLite originals are published in google-coral/test_data
(Apache-2.0). Checksums are those of the published files.
"""
from __future__ import annotations

import dataclasses
import pathlib

from dynaorb.segmentation.labels import label_set
from dynaorb.segmentation.model_card import InputSpec, ModelCard, backend_of

CORAL = "https://github.com/google-coral/test_data/raw/master/"


@dataclasses.dataclass(frozen=True)
class CatalogEntry:
    name: str
    tflite: str          # file name of the original
    sha256: str          # of the original
    label_set: str
    note: str

    @property
    def url(self) -> str:
        return CORAL + self.tflite

    @property
    def stem(self) -> str:
        return pathlib.Path(self.tflite).stem

    def card(self, model_file: str | pathlib.Path, sha256: str | None = None) -> ModelCard:
        labels, movable = label_set(self.label_set)
        return ModelCard(name=self.name, file=pathlib.Path(model_file).name, backend=backend_of(model_file),
                         input=InputSpec(height=513, width=513, layout="NHWC", dtype="uint8", color="RGB"),
                         labels=list(labels), movable=list(movable), output="labels",
                         sha256=sha256, source=self.url).validate(self.name)


CATALOG = {e.name: e for e in (
    CatalogEntry("deeplabv3_mnv2_pascal", "deeplabv3_mnv2_pascal_quant.tflite",
                 "350af47fd346ea6d74b58833a351f583ba860e9806ec5bd292ff8d8f1f249398", "pascal_voc",
                 "DeepLab v3, MobileNetV2, PASCAL VOC (default)"),
    CatalogEntry("deeplabv3_mnv2_dm05_pascal", "deeplabv3_mnv2_dm05_pascal_quant.tflite",
                 "0470d2a782aa54eeeb99d32e7b6b3fb7722905c7c4f5d26bd957ec861366d48b", "pascal_voc",
                 "DeepLab v3, half-width MobileNetV2, PASCAL VOC (fastest)"),
    CatalogEntry("deeplab_edgetpu_slim_cityscapes", "deeplab_mobilenet_edgetpu_slim_cityscapes_quant.tflite",
                 "322fe29945cb1693f426952f2a330ab67ea5678545ddee6f2548e0cfd0ca03e5", "cityscapes",
                 "DeepLab v3, MobileNet EdgeTPU slim, Cityscapes (street scenes)"),
)}
DEFAULT_MODEL = "deeplabv3_mnv2_pascal"


def entry_for_file(model: str | pathlib.Path) -> CatalogEntry | None:
    """The catalog entry whose original (or a conversion of it) this file is, by file name."""
    stem = pathlib.Path(model).stem
    for e in CATALOG.values():
        if stem == e.stem:
            return e
    return None
