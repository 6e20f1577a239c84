"""Map save / load, localisation-only mode and reset (SLAM core II) through
the Python API and the runner.

KITTI 06 (stereo, ~1.2 m per frame): frames 0-24 are mapped with a
vocabulary trained at test time (as in test_relocalization.py), the map is
saved, and a new System loads it and tracks the same frames in
localisation-only mode: the first frame is relocalised in the loaded map,
every frame is tracked, and the map does not grow.

Measured (vocabulary as in test_relocalization.py, synchronous mapping): the
map of frames 0-24 has 14 keyframes and 2174 points, 3.07 MB, saved in
16-32 ms and loaded in 60-82 ms (bags of words and database included).
Localisation over frames 0-24: relocalised at frame 0, then the reference
keyframe and the motion model, ATE 0.033 m (the mapping run's: 0.033 m).
Over all 51 frames (26 beyond the map): every frame tracked, 7 of them by
visual odometry, the map unchanged, ATE 0.049 m. A map of all 51 frames:
30 keyframes, 3984 points, 6.5 MB, saved in 36 ms, loaded in 102 ms.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

from dynaorb import core

FRAMES = 25


@pytest.fixture(scope="module")
def vocabulary(real_vocabulary):
    return real_vocabulary


@pytest.fixture(scope="module")
def kitti(data):
    return core().open_dataset("kitti", str(data / "kitti" / "sequences" / "06"))


@pytest.fixture(scope="module")
def saved(tmp_path_factory, kitti, vocabulary):
    """(path, map summary, map points, save seconds) of KITTI 06 frames 0-24."""
    system = core().System(kitti.default_settings(), "stereo", synchronous_mapping=True, vocabulary=vocabulary)
    for i in range(FRAMES):
        assert system.track_frame(kitti.load(i)).state == "OK"
    path = tmp_path_factory.mktemp("map") / "kitti06.map"
    t0 = time.perf_counter()
    system.save_map(path)
    save_s = time.perf_counter() - t0
    return path, system.map_summary(), system.map_points(), save_s


def _ate(provider, system) -> float:
    from evo.core.trajectory import PoseTrajectory3D

    from dynaorb.evaluation import evaluate

    gt_stamps, gt_poses = provider.ground_truth()
    stamps, poses = system.trajectory()
    return evaluate(PoseTrajectory3D(poses_se3=list(gt_poses), timestamps=gt_stamps),
                    PoseTrajectory3D(poses_se3=list(poses), timestamps=stamps), align="se3",
                    rpe_delta=None).ate["rmse"]


def test_saved_map_is_localised_in_without_growing(saved, kitti, vocabulary):
    path, summary, points, save_s = saved
    assert summary["keyframes"] > 5
    size = path.stat().st_size
    assert path.read_bytes()[:8] == b"DYNAOMAP"
    system = core().System(kitti.default_settings(), "stereo", synchronous_mapping=True, vocabulary=vocabulary)
    t0 = time.perf_counter()
    system.load_map(path)
    load_s = time.perf_counter() - t0
    loaded = system.map_summary()
    assert (loaded["keyframes"], loaded["points"]) == (summary["keyframes"], summary["points"])
    np.testing.assert_array_equal(system.map_points(), points)
    system.localization_mode = True
    assert system.localization_mode
    results = [system.track_frame(kitti.load(i)) for i in range(FRAMES)]
    methods = [r.method for r in results]
    assert all(r.state == "OK" for r in results), methods
    assert methods[0] == "relocalization"
    assert not any(r.new_keyframe for r in results)
    assert all(m in ("relocalization", "reference_keyframe", "motion_model") for m in methods), methods
    after = system.map_summary()
    assert (after["keyframes"], after["points"]) == (summary["keyframes"], summary["points"])
    counters = system.counters()
    assert counters["initializations"] == 0 and counters["relocalizations"] >= 1
    ate = _ate(kitti, system)
    print(f"map file {size} bytes, {summary['keyframes']} keyframes, {summary['points']} points; "
          f"save {save_s * 1e3:.1f} ms, load {load_s * 1e3:.1f} ms; localisation ATE {ate:.4f} m; {methods}")
    # Measured 0.033 m, as the mapping run's on these frames.
    assert ate <= 0.06


def test_localisation_beyond_the_map_uses_visual_odometry(saved, kitti, vocabulary):
    path, summary, _, _ = saved
    system = core().System(kitti.default_settings(), "stereo", synchronous_mapping=True, vocabulary=vocabulary)
    system.load_map(path)
    system.set_localization_mode(True)
    results = [system.track_frame(kitti.load(i)) for i in range(len(kitti))]
    methods = [r.method for r in results]
    assert all(r.state == "OK" for r in results), methods
    assert "visual_odometry" in methods[FRAMES:], methods
    assert "visual_odometry" not in methods[:FRAMES], methods
    after = system.map_summary()
    assert (after["keyframes"], after["points"]) == (summary["keyframes"], summary["points"])
    # Measured 0.049 m over the 51 frames.
    assert _ate(kitti, system) <= 0.1
    # And back to SLAM.
    system.set_localization_mode(False)
    assert not system.localization_mode


def test_reset_empties_the_map_and_a_new_one_starts(saved, kitti, vocabulary):
    path, summary, _, _ = saved
    system = core().System(kitti.default_settings(), "stereo", synchronous_mapping=True, vocabulary=vocabulary)
    system.load_map(path)
    assert system.map_summary()["keyframes"] == summary["keyframes"]
    system.reset()
    assert system.map_summary()["keyframes"] == 0 and system.map_summary()["points"] == 0
    assert len(system.map_points()) == 0
    r = system.track_frame(kitti.load(0))
    assert r.method == "init" and r.state == "OK"
    assert system.map_summary()["keyframes"] == 1


def test_loading_into_another_sensor_or_calibration_is_refused(saved, data, kitti, vocabulary):
    _core = core()
    path, _, _, _ = saved
    mono = _core.System(kitti.default_settings(), "mono", vocabulary=vocabulary)
    with pytest.raises(_core.InputError, match="stereo camera, this system is mono"):
        mono.load_map(path)
    euroc = _core.open_dataset("euroc", str(data / "euroc" / "V1_01_easy_micro"))
    other = _core.System(euroc.default_settings(), "stereo", vocabulary=vocabulary)
    with pytest.raises(_core.InputError, match=r"kitti06\.map.*map refused") as e:
        other.load_map(path)
    print(e.value)
    # The refused system still works from scratch.
    assert other.track_frame(euroc.load(0)).method == "init"


def test_bad_files_and_missing_vocabulary_are_clear_errors(saved, tmp_path, kitti, vocabulary):
    _core = core()
    path, _, _, _ = saved
    system = _core.System(kitti.default_settings(), "stereo", vocabulary=vocabulary)
    with pytest.raises(_core.InputError, match="nope.map.*cannot open"):
        system.load_map(tmp_path / "nope.map")
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"not a map")
    with pytest.raises(_core.InputError, match="bad.map.*not a dynaorb map file"):
        system.load_map(bad)
    cut = tmp_path / "cut.map"
    cut.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(_core.InputError, match="cut.map.*truncated"):
        system.load_map(cut)
    with pytest.raises(_core.InputError, match="vocabulary"):
        _core.System(kitti.default_settings(), "stereo").load_map(path)
    with pytest.raises(_core.InputError, match="no map yet"):
        system.save_map(tmp_path / "empty.map")


def test_runner_saves_and_loads_maps(tmp_path, data, vocabulary):
    from dynaorb.runner import RunOptions, run_dataset

    voc = tmp_path / "voc.bin"
    vocabulary.save(voc)
    seq = str(data / "euroc" / "V1_01_easy_micro")
    out_map = tmp_path / "v101.map"
    first = run_dataset(RunOptions(kind="euroc", path=seq, out=str(tmp_path / "a"), progress=False,
                                   vocabulary=str(voc), save_map=str(out_map)))
    assert out_map.is_file() and first["map_file"]["saved"]["bytes"] == out_map.stat().st_size
    second = run_dataset(RunOptions(kind="euroc", path=seq, out=str(tmp_path / "b"), progress=False,
                                    vocabulary=str(voc), load_map=str(out_map), localization=True))
    assert second["map_file"]["loaded"]["keyframes"] == first["map"]["keyframes"]
    assert second["map"]["keyframes"] == first["map"]["keyframes"]
    assert second["initializations"] == 0 and second["relocalizations"] >= 1
    assert second["tracked_frames"] == second["frames"]
    assert second["localization"] is True
    with pytest.raises(ValueError, match="vocabulary"):
        run_dataset(RunOptions(kind="euroc", path=seq, out=str(tmp_path / "c"), progress=False,
                               load_map=str(out_map), vocabulary="none"))
