"""`dynaorb models fetch`: install the public segmentation models into a user cache.

Each model's TFLite original is downloaded (or copied with --from DIR) and its
SHA-256 checked against the catalog. The ONNX version is copied when the
source folder has one, converted with tf2onnx when that is installed, and
otherwise the TFLite file is used through LiteRT. Every installed file gets
its model card beside it.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import logging
import os
import pathlib
import shutil
import subprocess
import sys
import urllib.error
import urllib.request

from dynaorb.segmentation.catalog import CATALOG, DEFAULT_MODEL, CatalogEntry
from dynaorb.segmentation.model_card import card_path, sha256_of

log = logging.getLogger(__name__)


def cache_dir() -> pathlib.Path:
    if os.environ.get("DYNAORB_MODEL_CACHE"):
        return pathlib.Path(os.environ["DYNAORB_MODEL_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "dynaorb" / "models"


@dataclasses.dataclass
class Installed:
    name: str
    model: pathlib.Path     # the file to use (.onnx when available)
    backend: str
    how: str                # copied / downloaded / converted, for the report


def _download(url: str, part: pathlib.Path, progress: bool) -> None:
    try:
        with urllib.request.urlopen(url, timeout=60) as r, open(part, "wb") as f:
            total = int(r.headers.get("Content-Length") or 0) or None
            bar = None
            if progress:
                from tqdm import tqdm

                bar = tqdm(total=total, unit="B", unit_scale=True, desc=url.rsplit("/", 1)[-1])
            while chunk := r.read(1 << 16):
                f.write(chunk)
                if bar:
                    bar.update(len(chunk))
            if bar:
                bar.close()
    except (urllib.error.URLError, OSError) as exc:
        part.unlink(missing_ok=True)
        raise ConnectionError(f"cannot download {url}: {exc}") from None


def _verified(path: pathlib.Path, expected: str, origin: str) -> None:
    actual = sha256_of(path)
    if actual != expected:
        path.unlink(missing_ok=True)
        raise ValueError(f"{origin}: SHA-256 {actual} does not match the published {expected}; "
                         "the file was removed")


def _convert(tflite: pathlib.Path, onnx: pathlib.Path) -> bool:
    """tf2onnx conversion (opset 17) when tf2onnx is installed; False otherwise."""
    if importlib.util.find_spec("tf2onnx") is None:
        return False
    cmd = [sys.executable, "-m", "tf2onnx.convert", "--tflite", str(tflite), "--output", str(onnx),
           "--opset", "17"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0 or not onnx.is_file():
        log.warning("tf2onnx could not convert %s (the TFLite model is used instead): %s",
                    tflite.name, done.stderr.strip().splitlines()[-1:] or done.returncode)
        onnx.unlink(missing_ok=True)
        return False
    return True


def install(entry: CatalogEntry, dest: pathlib.Path, from_dir: pathlib.Path | None = None,
            base_url: str | None = None, force: bool = False, progress: bool = True) -> Installed:
    dest.mkdir(parents=True, exist_ok=True)
    tflite = dest / entry.tflite
    onnx = dest / (entry.stem + ".onnx")
    how = "cached"
    if force or not tflite.is_file() or sha256_of(tflite) != entry.sha256:
        part = tflite.with_name(tflite.name + ".part")  # the cache never holds an unverified model
        if from_dir is not None:
            origin = from_dir / entry.tflite
            if not origin.is_file():
                raise FileNotFoundError(f"{origin}: not in the --from folder")
            shutil.copyfile(origin, part)
            how = "copied"
        else:
            origin = (base_url.rstrip("/") + "/" + entry.tflite) if base_url else entry.url
            _download(origin, part, progress)
            how = "downloaded"
        _verified(part, entry.sha256, str(origin))
        part.replace(tflite)
    entry.card(tflite, sha256=entry.sha256).save(card_path(tflite))

    if force or not onnx.is_file():
        src_onnx = from_dir / onnx.name if from_dir is not None else None
        if src_onnx is not None and src_onnx.is_file():
            shutil.copyfile(src_onnx, onnx)
            how += ", ONNX copied"
        elif _convert(tflite, onnx):
            how += ", converted to ONNX with tf2onnx"
    if onnx.is_file():
        entry.card(onnx, sha256=sha256_of(onnx)).save(card_path(onnx))
        return Installed(entry.name, onnx, "onnx", how)
    return Installed(entry.name, tflite, "tflite", how + ", TFLite backend (tf2onnx not installed)")


def fetch(names: list[str] | None = None, from_dir: str | None = None, cache: str | None = None,
          base_url: str | None = None, force: bool = False, progress: bool = True) -> list[Installed]:
    """Installs the named catalog models (default: all) into the cache; returns what was installed."""
    names = names or list(CATALOG)
    unknown = [n for n in names if n not in CATALOG]
    if unknown:
        raise ValueError(f"unknown model(s) {', '.join(unknown)} (known: {', '.join(CATALOG)})")
    src = pathlib.Path(from_dir) if from_dir else None
    if src is not None and not src.is_dir():
        raise FileNotFoundError(f"{src}: --from folder does not exist")
    dest = pathlib.Path(cache) if cache else cache_dir()
    return [install(CATALOG[n], dest, src, base_url, force, progress) for n in names]


def resolve_model(spec: str | None = None, cache: str | None = None) -> pathlib.Path:
    """A model file from a path, or from a catalog name installed in the cache (default model: None)."""
    spec = spec or DEFAULT_MODEL
    path = pathlib.Path(spec)
    if path.suffix in (".onnx", ".tflite"):
        if not path.is_file():
            raise FileNotFoundError(f"{path}: model file does not exist")
        return path
    if spec not in CATALOG:
        raise ValueError(f"{spec!r} is neither a model file (.onnx, .tflite) nor a known model "
                         f"({', '.join(CATALOG)})")
    dest = pathlib.Path(cache) if cache else cache_dir()
    entry = CATALOG[spec]
    for candidate in (dest / (entry.stem + ".onnx"), dest / entry.tflite):
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f"model {spec} is not installed in {dest}: run `dynaorb models fetch {spec}` "
                            "(or `dynaorb models fetch --from DIR` with a folder holding the files)")
