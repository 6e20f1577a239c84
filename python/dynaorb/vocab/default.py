"""The default vocabulary: trained by dynaorb itself on sequences it renders, and cached.

No third-party vocabulary is shipped. `dynaorb vocab default` (run by the
set-up of `make demo` / `make test`) renders synthetic sequences
(`dynaorb synth`: rooms textured with crops of real images when
../shared/data is there, procedural textures otherwise), extracts ORB with
the default extractor settings and trains k=10, L=6. The file lands in
$DYNAORB_VOCAB_CACHE or ~/.cache/dynaorb/vocab; later runs find it there.
"""
from __future__ import annotations

import logging
import os
import pathlib
import tempfile

from dynaorb.vocab.train import DEFAULT_CONFIG, descriptors_of

log = logging.getLogger(__name__)

# Bump when the recipe changes so that stale caches are not used.
RECIPE = {"version": 1, "k": 10, "L": 6, "seed": 0, "sequences": [("rgbd", 0), ("rgbd", 1), ("stereo", 2),
                                                                   ("rgbd", 3)], "frames": 50}
FILE_NAME = f"dynaorb_default_v{RECIPE['version']}_k{RECIPE['k']}_L{RECIPE['L']}.bin"


def cache_dir() -> pathlib.Path:
    if os.environ.get("DYNAORB_VOCAB_CACHE"):
        return pathlib.Path(os.environ["DYNAORB_VOCAB_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "dynaorb" / "vocab"


def default_vocabulary_path() -> pathlib.Path:
    return cache_dir() / FILE_NAME


def build_default(force: bool = False, progress: bool = False) -> pathlib.Path:
    """Path of the cached default vocabulary, training it first when missing (about a minute)."""
    from dynaorb import core
    from dynaorb.synth import SynthConfig, generate

    path = default_vocabulary_path()
    if path.is_file() and not force:
        return path
    settings = core().Settings.load(str(DEFAULT_CONFIG))
    descriptors = []
    with tempfile.TemporaryDirectory(prefix="dynaorb_vocab_") as tmp:
        for sensor, seed in RECIPE["sequences"]:
            out = pathlib.Path(tmp) / f"{sensor}{seed}"
            log.info("rendering %s sequence (seed %d) for the default vocabulary", sensor, seed)
            generate(out, SynthConfig(sensor=sensor, movers=3, frames=RECIPE["frames"], seed=seed))
            folder = out / "rgb" if sensor == "rgbd" else out / "sequences" / "00" / "image_0"
            descriptors += descriptors_of(sorted(folder.glob("*.png")), settings, progress)
    vocabulary = core().Vocabulary.train(descriptors, k=RECIPE["k"], L=RECIPE["L"], seed=RECIPE["seed"])
    path.parent.mkdir(parents=True, exist_ok=True)
    part = path.with_name(f"{path.name}.{os.getpid()}.part")  # concurrent builds do not collide
    vocabulary.save(str(part))
    part.replace(path)
    log.info("default vocabulary: %d words from %d images -> %s", vocabulary.size, len(descriptors), path)
    return path
