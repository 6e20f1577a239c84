"""A map lost for too long is given up for a new one (ORB-SLAM3's policy).

ORB-SLAM3 v1.0 keeps a lost map "recently lost" for 3 s of frame stamps,
relocalising every frame, then starts a new map in its atlas. dynaorb has no
atlas: TrackerOptions.new_map_after_lost_s (default 3.0; 0 = never, as
ORB-SLAM2) drops the old map and the next frame that can initialise starts
map 1; the old map's poses stay in the trajectory as their own segment.

The scene: KITTI 06 stereo, frames 0-24 as recorded, then frames 25-50 of a
mirrored world (left' = flip(right), right' = flip(left): a valid rectified
pair of the mirror image, whose ORB descriptors and geometry the map cannot
explain, so relocalisation fails). Measured with new_map_after_lost_s = 1.0
(the clip is 5.2 s long), the tests' vocabulary and synchronous mapping:
lost at frames 25-34, map 0 given up at frame 35 (1.04 s after the first
lost frame), map 1 from frame 36, tracked to the end; map 0's ATE 0.034 m
(se3), map 1's path 16.90 m against the ground truth's 16.85 m.
"""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from dynaorb import core
from dynaorb.runner import run as runner

KIDNAP = 25


def _run(data, vocabulary, new_map_after_lost_s):
    provider = core().open_dataset("kitti", str(data / "kitti" / "sequences" / "06"))
    options = core().TrackerOptions()
    options.new_map_after_lost_s = new_map_after_lost_s
    system = core().System(provider.default_settings(), "stereo", synchronous_mapping=True,
                           vocabulary=vocabulary, tracker=options)
    results = []
    for i in range(len(provider)):
        f = provider.load(i)
        if i < KIDNAP:
            results.append(system.track_frame(f))
        else:
            results.append(system.track_stereo(cv2.flip(f.right, 1), cv2.flip(f.image, 1), f.stamp))
    return provider, system, results


def test_default_is_orbslam3_three_seconds():
    assert core().TrackerOptions().new_map_after_lost_s == 3.0


@pytest.mark.parametrize("value, shown", [(float("nan"), "nan"), (-1.0, "-1")])
def test_a_nan_or_negative_time_is_refused_by_name(data, tmp_path, value, shown):
    # Before TrackerOptions::validate a NaN silently meant "never".
    provider = core().open_dataset("kitti", str(data / "kitti" / "sequences" / "06"))
    options = core().TrackerOptions()
    options.new_map_after_lost_s = value
    with pytest.raises(ValueError, match=f"tracker option 'new_map_after_lost_s' is {shown}; it must be"):
        core().System(provider.default_settings(), "stereo", tracker=options)
    # The runner's `--tracker KEY=VALUE` reaches the same check before any output.
    with pytest.raises(ValueError, match="'new_map_after_lost_s' is nan"):
        runner.run_dataset(runner.RunOptions(kind="kitti", path=str(data / "kitti" / "sequences" / "06"),
                                             out=str(tmp_path / "run"), progress=False,
                                             tracker={"new_map_after_lost_s": "nan"}))
    assert not (tmp_path / "run" / "stats.json").exists()


def test_a_map_lost_for_too_long_is_replaced(data, real_vocabulary):
    provider, system, results = _run(data, real_vocabulary, 1.0)
    stamps = np.array([provider.stamp(i) for i in range(len(provider))])
    assert all(r.state == "OK" and r.map == 0 for r in results[:KIDNAP])
    dropped = [i for i, r in enumerate(results) if r.map_dropped]
    assert len(dropped) == 1
    d = dropped[0]
    # Lost (every frame relocalised and failing) until 1 s after the first lost frame.
    assert all(r.state == "LOST" and r.method == "lost" and r.map == 0 for r in results[KIDNAP:d + 1])
    assert all("relocalization" in r.stage_ms for r in results[KIDNAP + 1:d + 1])
    assert stamps[d] - stamps[KIDNAP] >= 1.0 > stamps[d - 1] - stamps[KIDNAP]
    assert "map 0 given up" in results[d].message
    assert results[d + 1].method == "init" and results[d + 1].map == 1
    assert all(r.state == "OK" and r.map == 1 for r in results[d + 1:])
    counters = system.counters()
    assert counters["maps_dropped"] == 1 and counters["initializations"] == 2
    assert counters["lost"] == d + 1 - KIDNAP
    # The new map holds only its own keyframes.
    assert 0 < system.map_summary()["keyframes"] <= len(results) - d - 1

    segments = system.trajectory_segments()
    assert [(m, len(s)) for m, s, _ in segments] == [(0, KIDNAP), (1, len(results) - d - 1)]
    np.testing.assert_array_equal(segments[0][1], stamps[:KIDNAP])
    np.testing.assert_array_equal(segments[1][1], stamps[d + 1:])
    # trajectory(): the map with the most frames (map 0 here).
    main_stamps, _ = system.trajectory()
    np.testing.assert_array_equal(main_stamps, stamps[:KIDNAP])

    from evo.core.trajectory import PoseTrajectory3D

    from dynaorb.evaluation import evaluate

    gt_stamps, gt_poses = provider.ground_truth()
    _, s0, p0 = segments[0]
    ate = evaluate(PoseTrajectory3D(poses_se3=list(gt_poses), timestamps=gt_stamps),
                   PoseTrajectory3D(poses_se3=list(p0), timestamps=s0), align="se3", rpe_delta=None).ate["rmse"]
    assert ate <= 0.15  # issue 3's KITTI bound; measured 0.034 m
    # Map 1 starts its own world at the first frame and follows the mirrored
    # path, as long as the real one (a mirror keeps lengths).
    _, s1, p1 = segments[1]
    np.testing.assert_allclose(p1[0], np.eye(4), atol=1e-9)
    idx = [int(np.argmin(np.abs(gt_stamps - s))) for s in s1]
    length = np.sum(np.linalg.norm(np.diff(p1[:, :3, 3], axis=0), axis=1))
    gt_length = np.sum(np.linalg.norm(np.diff(gt_poses[idx, :3, 3], axis=0), axis=1))
    print(f"\nmap 0 ATE {ate:.4f} m; map 1's path {length:.2f} m against {gt_length:.2f} m")
    assert length == pytest.approx(gt_length, rel=0.05)  # measured 0.3 %


def test_zero_keeps_the_lost_map(data, real_vocabulary):
    _, system, results = _run(data, real_vocabulary, 0.0)
    assert all(r.state == "LOST" and not r.map_dropped and r.map == 0 for r in results[KIDNAP:])
    counters = system.counters()
    assert counters["maps_dropped"] == 0 and counters["initializations"] == 1
    assert [(m, len(s)) for m, s, _ in system.trajectory_segments()] == [(0, KIDNAP)]


class _TwoMaps:
    """The System call the runner makes for its per-map trajectory files."""

    def __init__(self):
        poses = np.repeat(np.eye(4)[None], 5, axis=0)
        self.segments = [(0, np.array([0.0, 0.1]), poses[:2]), (1, np.array([0.5, 0.6, 0.7]), poses[:3])]

    def trajectory_segments(self):
        return self.segments


def test_runner_writes_every_map(tmp_path):
    two = _TwoMaps()
    maps = runner._write_segments(two, tmp_path, two.segments[1][1])
    assert [(m["map"], m["frames"], m["in_trajectory_tum"], m["file"]) for m in maps] == [
        (0, 2, False, "trajectory_map0.tum"), (1, 3, True, "trajectory_map1.tum")]
    assert maps[1]["first_stamp"] == 0.5 and maps[1]["last_stamp"] == 0.7
    stamps, _ = core().read_tum(str(tmp_path / "trajectory_map0.tum"))
    np.testing.assert_allclose(stamps, [0.0, 0.1])
    json.dumps(maps)  # stats.json takes it as is
