"""End to end, monocular (SLAM core II): `dynaorb run --sensor mono` on the
EuRoC MH_05 clip and on synthetic sequences, with the trajectory aligned to
ground truth by Sim3 (a monocular map has no metric scale).

Issue targets: initialise within the first 50 frames, >= 90 % of the frames
after initialisation tracked, ATE RMSE <= 0.10 m. With ORB-SLAM2's feature
count for the initial frames (2x) MH_05_difficult_head's first map comes at
frame 85; the defaults (4x, kept for 60 frames after the map, measured in
tracking/tracker.h) make it at frame 8.
Runs use synchronous mapping (the runner's default), so they are repeatable.
"""
from __future__ import annotations

import pytest

from dynaorb.runner import RunOptions, run_dataset


def _run(tmp_path, kind, path, name, **kw) -> dict:
    return run_dataset(RunOptions(kind=kind, path=str(path), out=str(tmp_path / name), progress=False,
                                  sensor="mono", **kw))


def test_euroc_mh05_mono_initialises_and_tracks(data, tmp_path):
    stats = _run(tmp_path, "euroc", data / "euroc" / "MH_05_difficult_head", "mh05")
    assert stats["frames"] == 250 and stats["initializations"] == 1
    # Target: frame <= 50. Measured: 8.
    assert stats["init_frame"] is not None and stats["init_frame"] <= 50
    # Target 0.9; measured 1.0 (242 of 242 frames from the initialisation on).
    assert stats["tracked_fraction_after_init"] >= 0.9
    # Target 0.10 m; measured 0.0115 m (Sim3 alignment).
    assert stats["ate"]["rmse"] <= 0.10
    assert stats["ate"]["rmse"] <= 0.03
    assert stats["map"]["keyframes"] >= 5 and stats["map"]["local_ba_runs"] >= 1
    assert stats["map"]["points_created"] > 0  # monocular points come from triangulation only


@pytest.fixture(scope="module")
def mono_scenes(tmp_path_factory, data):
    """The synthetic room and path, monocular, without and with movers (60 frames)."""
    from dynaorb.synth import SynthConfig, generate

    out = {}
    for movers in (0, 3):
        d = tmp_path_factory.mktemp(f"mono{movers}")
        generate(d, SynthConfig(sensor="mono", movers=movers, frames=60, seed=0))
        out[movers] = d / "sequences" / "00"
    return out


def test_synthetic_mono_static(tmp_path, mono_scenes):
    stats = _run(tmp_path, "kitti", mono_scenes[0], "static")
    # Measured: initialised at frame 6, every later frame tracked, ATE 0.016 m (path 2.45 m).
    assert stats["init_frame"] <= 10
    assert stats["tracked_fraction_after_init"] >= 0.9
    assert stats["ate"]["rmse"] <= 0.05


def test_synthetic_mono_movers_with_masks(tmp_path, mono_scenes):
    d = mono_scenes[3]
    stats = _run(tmp_path, "kitti", d, "masked", masks=str(d / "dynamic_masks"))
    # Measured: initialised at frame 28 (movers cover 32 % of the image), every
    # later frame tracked, ATE 0.0053 m.
    assert stats["init_frame"] <= 40
    assert stats["tracked_fraction_after_init"] >= 0.9
    assert stats["ate"]["rmse"] <= 0.05
