"""Textures for the synthetic scenes: crops of real images (so that ORB features
behave as on real data), or procedural noise when no real images are at hand."""
from __future__ import annotations

import logging
import os
import pathlib

import cv2
import numpy as np

log = logging.getLogger(__name__)


def default_texture_dir() -> pathlib.Path | None:
    """$DYNAORB_SHARED/data, else ../shared/data beside the repository, else None."""
    env = os.environ.get("DYNAORB_SHARED")
    candidates = [pathlib.Path(env) / "data"] if env else []
    repo = pathlib.Path(__file__).resolve().parents[3]
    candidates.append(repo.parent / "shared" / "data")
    for c in candidates:
        if c.is_dir():
            return c
    return None


def find_images(root: pathlib.Path, limit: int = 400) -> list[pathlib.Path]:
    images = sorted(p for p in root.rglob("*.png") if "depth" not in p.parts)
    if len(images) > limit:  # spread the picks over all sequences
        step = len(images) / limit
        images = [images[int(i * step)] for i in range(limit)]
    return images


def procedural(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """Multi-octave value noise with blobs and edges: corner-rich, aperiodic enough."""
    img = np.zeros((size, size), np.float32)
    for octave in range(1, 7):
        cells = 2 ** octave
        noise = rng.random((cells + 1, cells + 1)).astype(np.float32)
        img += cv2.resize(noise, (size, size), interpolation=cv2.INTER_CUBIC) / octave
    img = (img - img.min()) / (np.ptp(img) + 1e-6) * 160 + 40
    for _ in range(60):
        c = tuple(int(v) for v in rng.integers(0, size, 2))
        colour = float(rng.integers(0, 255))
        if rng.random() < 0.5:
            cv2.circle(img, c, int(rng.integers(4, 30)), colour, -1)
        else:
            d = rng.integers(6, 50, 2)
            cv2.rectangle(img, c, (c[0] + int(d[0]), c[1] + int(d[1])), colour, -1)
    return np.clip(img, 0, 255).astype(np.uint8)


class TextureBank:
    """Picks textures deterministically for a seed: grey uint8 images, tinted later."""

    def __init__(self, rng: np.random.Generator, source: pathlib.Path | None = None):
        self.rng = rng
        self.images = find_images(source) if source else []
        if source and not self.images:
            raise FileNotFoundError(f"{source}: holds no PNG images to use as textures")
        self.source = source if self.images else None
        if not self.images:
            log.warning("no real images for textures: using procedural noise textures")

    def grey(self, size: int = 512) -> np.ndarray:
        if not self.images:
            return procedural(self.rng, size)
        path = self.images[int(self.rng.integers(len(self.images)))]
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError(f"{path}: cannot decode texture image")
        h, w = img.shape
        s = min(h, w, size)
        y, x = int(self.rng.integers(0, h - s + 1)), int(self.rng.integers(0, w - s + 1))
        crop = img[y:y + s, x:x + s]
        # Stretch contrast so that every surface carries corners.
        crop = cv2.equalizeHist(crop)
        return cv2.resize(crop, (size, size), interpolation=cv2.INTER_LINEAR)

    def colour(self, size: int = 512) -> np.ndarray:
        """BGR texture: the grey crop tinted with a random colour."""
        g = self.grey(size).astype(np.float32)
        tint = self.rng.uniform(0.55, 1.0, 3).astype(np.float32)
        return np.clip(g[..., None] * tint[None, None, :] + 20, 0, 255).astype(np.uint8)


def pyramid(texture: np.ndarray, levels: int = 6) -> list[np.ndarray]:
    """Mip levels (level k is 2^k smaller) to sample far surfaces without aliasing."""
    out = [texture]
    for _ in range(levels - 1):
        if min(out[-1].shape[:2]) < 16:
            break
        out.append(cv2.pyrDown(out[-1]))
    return out
