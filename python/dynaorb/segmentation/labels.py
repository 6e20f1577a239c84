"""Label sets of the public segmentation models and their movable classes.

PASCAL VOC 2012 (21 labels, 0 = background) and Cityscapes train ids (19).
Movable: the classes whose instances can move (people, vehicles, animals);
STDyn-SLAM and DynaSLAM drop them, DM-SLAM treats them as potentially dynamic.
"""
from __future__ import annotations

PASCAL_VOC = (
    "background", "aeroplane", "bicycle", "bird", "boat", "bottle", "bus", "car", "cat", "chair", "cow",
    "diningtable", "dog", "horse", "motorbike", "person", "pottedplant", "sheep", "sofa", "train",
    "tvmonitor",
)
# The 14 movable VOC classes (DynaSLAM's / STDyn-SLAM's set).
PASCAL_VOC_MOVABLE = (1, 2, 3, 4, 6, 7, 8, 10, 12, 13, 14, 15, 17, 19)

CITYSCAPES = (
    "road", "sidewalk", "building", "wall", "fence", "pole", "traffic light", "traffic sign", "vegetation",
    "terrain", "sky", "person", "rider", "car", "truck", "bus", "train", "motorcycle", "bicycle",
)
CITYSCAPES_MOVABLE = (11, 12, 13, 14, 15, 16, 17, 18)

LABEL_SETS = {
    "pascal_voc": (PASCAL_VOC, PASCAL_VOC_MOVABLE),
    "cityscapes": (CITYSCAPES, CITYSCAPES_MOVABLE),
}


def label_set(name: str) -> tuple[tuple[str, ...], tuple[int, ...]]:
    """(label names, movable ids) of a known label set."""
    try:
        return LABEL_SETS[name]
    except KeyError:
        raise ValueError(f"unknown label set {name!r} (known: {', '.join(LABEL_SETS)})") from None
