"""End to end, monocular (SLAM core II): `dynaorb run --sensor mono` on the
EuRoC MH_05 clip and on synthetic sequences, with the trajectory aligned to
ground truth by Sim3 (a monocular map has no metric scale).

Issue targets: initialise within the first 50 frames, >= 90 % of the frames
after initialisation tracked, ATE RMSE <= 0.10 m. With ORB-SLAM2's feature
count for the initial frames (2x) MH_05_difficult_head's first map comes at
frame 85; the defaults (4x, kept after the map until a frame tracks 1000 map
points or for 60 frames, measured in tracking/tracker.h) make it at frame 8.
Runs use synchronous mapping (the runner's default), so they are repeatable.
"""
from __future__ import annotations

import pytest

from dynaorb.runner import RunOptions, run_dataset


def _run(tmp_path, kind, path, name, **kw) -> dict:
    return run_dataset(RunOptions(kind=kind, path=str(path), out=str(tmp_path / name), progress=False,
                                  sensor="mono", **kw))


def _init_feature_switch(stats, n_features=1000, release=1000, window=60) -> int:
    """The frame from which keypoints go back to nFeatures after the map was
    made (TrackerOptions::mono_init_release_tracked / mono_init_feature_frames),
    checked against the per-frame records: every frame before it from the map
    on has the 4x count, every frame from it on about nFeatures, and the frame
    before it tracked `release` map points (or the window ran out)."""
    init = stats["init_frame"]
    frames = [f for f in stats["per_frame"] if f["index"] >= init]
    switch = next(f["index"] for f in frames if f["keypoints"] <= 1.05 * n_features)
    for f in frames:
        if f["index"] < switch:
            assert f["keypoints"] > 3 * n_features, f
        else:
            assert f["keypoints"] <= 1.05 * n_features, f
    before = next(f for f in frames if f["index"] == switch - 1)
    assert before["tracked_points"] >= release or switch - init > window
    return switch


def test_euroc_mh05_mono_initialises_and_tracks(data, tmp_path):
    stats = _run(tmp_path, "euroc", data / "euroc" / "MH_05_difficult_head", "mh05")
    assert stats["frames"] == 250 and stats["initializations"] == 1
    # Target: frame <= 50. Measured: 8.
    assert stats["init_frame"] is not None and stats["init_frame"] <= 50
    # Frames before the map say why they made none; tracked frames carry no message.
    before = [f for f in stats["per_frame"] if f["index"] < stats["init_frame"]]
    assert before and all(f["message"].startswith("monocular initialisation: ") for f in before), before
    assert all(f["message"] is None for f in stats["per_frame"] if f["state"] == "OK")
    # Target 0.9; measured 1.0 (242 of 242 frames from the initialisation on).
    assert stats["tracked_fraction_after_init"] >= 0.9
    # Target 0.10 m; measured 0.0153 m (Sim3 alignment).
    assert stats["ate"]["rmse"] <= 0.10
    assert stats["ate"]["rmse"] <= 0.03
    assert stats["map"]["keyframes"] >= 5 and stats["map"]["local_ba_runs"] >= 1
    assert stats["map"]["points_created"] > 0  # monocular points come from triangulation only
    # The 4x count stays until a frame tracks 1000 map points (frame 65; the
    # 60-frame window alone would end at frame 69). Released at 400 tracked
    # points instead, the switch comes at frame 10 and the map is lost (tracker.h).
    assert 40 <= _init_feature_switch(stats) <= stats["init_frame"] + 60


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
    # Measured: initialised at frame 4, every later frame tracked, ATE 0.0050 m (path 2.45 m).
    assert stats["init_frame"] <= 10
    assert stats["tracked_fraction_after_init"] >= 0.9
    assert stats["ate"]["rmse"] <= 0.05
    # Measured: back to nFeatures from frame 21 (frame 20 tracks 1035 points).
    assert _init_feature_switch(stats) <= 40


def test_synthetic_mono_movers_with_masks(tmp_path, mono_scenes):
    d = mono_scenes[3]
    stats = _run(tmp_path, "kitti", d, "masked", masks=str(d / "dynamic_masks"))
    # Measured: initialised at frame 4, every later frame tracked, ATE 0.0066 m.
    assert stats["init_frame"] <= 40
    assert stats["tracked_fraction_after_init"] >= 0.9
    assert stats["ate"]["rmse"] <= 0.05
