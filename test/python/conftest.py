"""Shared fixtures: the shared data folder and small synthetic sequences."""
from __future__ import annotations

import os
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def shared_data() -> pathlib.Path:
    env = os.environ.get("DYNAORB_SHARED")
    return (pathlib.Path(env) if env else REPO.parent / "shared") / "data"


@pytest.fixture(scope="session")
def data() -> pathlib.Path:
    d = shared_data()
    if not d.is_dir():
        pytest.skip(f"shared data not found at {d}")
    return d


@pytest.fixture(scope="session")
def synth_rgbd(tmp_path_factory, data) -> pathlib.Path:
    from dynaorb.synth import SynthConfig, generate

    out = tmp_path_factory.mktemp("synth_rgbd")
    generate(out, SynthConfig(sensor="rgbd", movers=3, frames=8, seed=7, width=320, height=240, fx=262.5))
    return out


@pytest.fixture(scope="session")
def synth_stereo(tmp_path_factory, data) -> pathlib.Path:
    from dynaorb.synth import SynthConfig, generate

    out = tmp_path_factory.mktemp("synth_stereo")
    generate(out, SynthConfig(sensor="stereo", movers=2, frames=6, seed=3, width=320, height=240, fx=262.5))
    return out


@pytest.fixture(scope="session")
def real_vocabulary(data):
    """A small vocabulary (k=10, L=5) trained at test time with the System's own
    extractor on real images: EuRoC MH_05 (every 10th frame) and KITTI 06 (every
    5th): 36 images, about 40k words, 0.15 s."""
    from dynaorb import core

    _core = core()
    descriptors = []
    for kind, path, step in (("euroc", data / "euroc" / "MH_05_difficult_head", 10),
                             ("kitti", data / "kitti" / "sequences" / "06", 5)):
        provider = _core.open_dataset(kind, str(path))
        settings = provider.default_settings()
        for i in range(0, len(provider), step):
            descriptors.append(_core.extract_orb(provider.load(i).image, settings)[1])
    return _core.Vocabulary.train(descriptors, k=10, L=5, seed=0)


def _synth_pair(tmp_path_factory, sensor: str, seed: int) -> dict:
    """One room and path without and with movers (60 frames, 640x480): {movers: sequence folder}."""
    from dynaorb.synth import SynthConfig, generate

    out = {}
    for movers in (0, 3):
        d = tmp_path_factory.mktemp(f"{sensor}{movers}_s{seed}")
        generate(d, SynthConfig(sensor=sensor, movers=movers, frames=60, seed=seed))
        out[movers] = d if sensor == "rgbd" else d / "sequences" / "00"
    return out


@pytest.fixture(scope="session")
def synth_scenes(tmp_path_factory, data) -> dict:
    """The same room and path without and with movers (60 frames, 640x480, seed 0),
    for each sensor: {(sensor, movers): sequence folder}."""
    return {(sensor, movers): d for sensor in ("rgbd", "stereo", "mono")
            for movers, d in _synth_pair(tmp_path_factory, sensor, 0).items()}


@pytest.fixture(scope="session")
def synth_seeds(tmp_path_factory, synth_scenes) -> dict:
    """As synth_scenes for seeds 0, 1 and 2 (other rooms, paths and movers):
    {(sensor, movers, seed): sequence folder}. One seed's ratio of two
    3-6 mm ATEs moves by +-25 % with small changes; the median of three does not."""
    out = {(sensor, movers, 0): d for (sensor, movers), d in synth_scenes.items()}
    for sensor in ("rgbd", "stereo", "mono"):
        for seed in (1, 2):
            out.update({(sensor, movers, seed): d
                        for movers, d in _synth_pair(tmp_path_factory, sensor, seed).items()})
    return out
