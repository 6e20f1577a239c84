"""Train a bag-of-words vocabulary on images (`dynaorb vocab train`).

Descriptors come from dynaorb's own ORB extractor (the settings' ORBextractor
parameters), so the words match what tracking sees. The tree is a DBoW2-style
hierarchical k-means++ (C++, dynaorb._core.Vocabulary).
"""
from __future__ import annotations

import logging
import pathlib

import cv2

from dynaorb import core

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm"}
REPO = pathlib.Path(__file__).resolve().parents[3]
DEFAULT_CONFIG = REPO / "config" / "TUM3.yaml"  # ORB-SLAM2's extractor defaults: 1000 features, 1.2, 8 levels


def collect_images(paths: list[str], max_images: int | None = None) -> list[pathlib.Path]:
    """Image files given directly or found under folders (depth and label images skipped)."""
    found = []
    for p in map(pathlib.Path, paths):
        if p.is_dir():
            found += sorted(f for f in p.rglob("*") if f.suffix.lower() in IMAGE_SUFFIXES
                            and not {"depth", "labels", "dynamic_masks"} & set(f.parts))
        elif p.is_file():
            found.append(p)
        else:
            raise FileNotFoundError(f"{p}: no such image or folder")
    if not found:
        raise ValueError(f"no images found in {', '.join(paths)}")
    if max_images and len(found) > max_images:  # spread the picks over everything given
        step = len(found) / max_images
        found = [found[int(i * step)] for i in range(max_images)]
    return found


def descriptors_of(images: list[pathlib.Path], settings, progress: bool = False) -> list:
    _core = core()
    out, unreadable = [], 0
    it = images
    if progress:
        from tqdm import tqdm

        it = tqdm(images, desc="extracting ORB", unit="image")
    for path in it:
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            unreadable += 1
            log.warning("%s: unreadable image skipped", path)
            continue
        out.append(_core.extract_orb(image, settings)[1])
    if unreadable:
        log.warning("%d of %d images were unreadable", unreadable, len(images))
    return out


def train(paths: list[str], k: int = 10, L: int = 6, seed: int = 0, config: str | None = None,
          max_images: int | None = None, progress: bool = False):
    """A Vocabulary trained on the images under paths."""
    settings = core().Settings.load(str(config or DEFAULT_CONFIG))
    descriptors = descriptors_of(collect_images(paths, max_images), settings, progress)
    if not descriptors:
        raise ValueError("no readable image to train on")
    return core().Vocabulary.train(descriptors, k=k, L=L, seed=seed)


def save(vocabulary, out: str | pathlib.Path) -> pathlib.Path:
    """Binary form, or ORB-SLAM2's text format when the name ends in .txt."""
    out = pathlib.Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".txt":
        vocabulary.save_text(str(out))
    else:
        vocabulary.save(str(out))
    return out
