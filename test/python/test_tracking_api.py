"""The tracking core through the Python API: per-frame results, the sparse
map, and degraded input (a frame that is all moving objects, a reset)."""
from __future__ import annotations

import numpy as np

from dynaorb import core


def _frames(path):
    provider = core().open_dataset("tum", str(path))
    return provider, [provider.load(i) for i in range(len(provider))]


def test_frames_report_pose_state_and_map(synth_rgbd):
    provider, frames = _frames(synth_rgbd)
    system = core().System(provider.default_settings(), "rgbd", synchronous_mapping=True)
    results = [system.track_frame(f) for f in frames]
    assert results[0].method == "init" and results[0].new_keyframe
    assert all(r.state == "OK" for r in results), [r.message for r in results]
    assert all(r.keypoints > 500 for r in results)
    assert all(r.tracked_points >= 30 for r in results)
    pose = results[-1].pose
    assert pose.shape == (4, 4) and np.allclose(pose[3], [0, 0, 0, 1])
    points = system.map_points()
    summary = system.map_summary()
    assert points.shape == (summary["points"], 3) and summary["points"] > 100
    assert np.all(np.isfinite(points))
    stamps, poses = system.trajectory()
    assert len(stamps) == len(frames) and poses.shape == (len(frames), 4, 4)


def test_a_frame_that_is_all_movers_is_lost_then_tracking_resumes(synth_rgbd):
    provider, frames = _frames(synth_rgbd)
    system = core().System(provider.default_settings(), "rgbd", synchronous_mapping=True)
    everything = np.full(frames[0].image.shape[:2], 255, np.uint8)
    results = [system.track_frame(f, everything if i == 4 else None) for i, f in enumerate(frames)]
    lost = results[4]
    assert lost.state == "LOST" and lost.keypoints == 0 and lost.pose is None
    assert "fully masked" in lost.message
    # The map survives: the next frame is found again against the reference keyframe.
    assert [r.state for r in results[5:]] == ["OK"] * (len(frames) - 5)
    assert results[5].method == "reference_keyframe"
    assert system.counters()["initializations"] == 1
    counters = system.counters()
    assert counters["lost"] == 1 and counters["tracked"] == len(frames) - 1


def test_reset_starts_a_new_map(synth_rgbd):
    provider, frames = _frames(synth_rgbd)
    system = core().System(provider.default_settings(), "rgbd", synchronous_mapping=True)
    for f in frames[:4]:
        system.track_frame(f)
    system.reset()
    assert system.map_summary()["points"] == 0 and len(system.trajectory()[0]) == 0
    r = system.track_frame(frames[5])
    assert r.state == "OK" and r.method == "init"


def test_asynchronous_mapping_tracks_the_same_sequence(synth_rgbd):
    provider, frames = _frames(synth_rgbd)
    system = core().System(provider.default_settings(), "rgbd")
    results = [system.track_frame(f) for f in frames]
    assert all(r.state == "OK" for r in results)


def test_textureless_and_tiny_images_degrade_without_a_crash(synth_rgbd):
    provider, frames = _frames(synth_rgbd)
    settings = provider.default_settings()
    system = core().System(settings, "rgbd")
    black = np.zeros_like(frames[0].image)
    r = system.track_rgbd(black, frames[0].depth, frames[0].stamp)
    assert r.state == "NOT_INITIALIZED" and r.keypoints == 0 and "initialise" in r.message
    tiny = np.zeros((3, 5), np.uint8)
    r = system.track_rgbd(tiny, np.zeros((3, 5), np.uint16), frames[1].stamp)
    assert r.rejected == "wrong_size"
    r = system.track_frame(frames[2])
    assert r.state == "OK" and r.method == "init"


def test_tracking_leaves_the_callers_images_alone(data):
    # EuRoC stereo is rectified inside the System: the rectified image used to
    # be written into the caller's left image.
    provider = core().open_dataset("euroc", str(data / "euroc" / "V1_01_easy_micro"))
    system = core().System(provider.default_settings(), "stereo", synchronous_mapping=True)
    for i in range(3):
        f = provider.load(i)
        left, right = f.image, f.right
        left_copy, right_copy = left.copy(), right.copy()
        assert system.track_stereo(left, right, f.stamp).state == "OK"
        assert np.array_equal(left, left_copy) and np.array_equal(right, right_copy)
    # A frame tracked twice (by two Systems) gives the same result.
    f = provider.load(0)
    a = core().System(provider.default_settings(), "stereo").track_frame(f)
    b = core().System(provider.default_settings(), "stereo").track_frame(f)
    assert a.state == b.state == "OK" and a.keypoints == b.keypoints


def test_wait_for_mapping_leaves_the_map_final(data):
    """Concurrent mapping: after the last frame, wait_for_mapping() returns once the queued keyframes are
    mapped (its last local BA run); nothing changes the map after it."""
    import time

    provider = core().open_dataset("kitti", str(data / "kitti" / "sequences" / "06"))
    system = core().System(provider.default_settings(), provider.sensor)
    results = [system.track_frame(provider.load(i)) for i in range(20)]
    assert all(r.state == "OK" for r in results)
    system.wait_for_mapping()
    done = system.map_summary()
    poses = system.trajectory()[1]
    time.sleep(0.3)
    assert system.map_summary() == done
    np.testing.assert_array_equal(system.trajectory()[1], poses)
    assert done["local_ba_runs"] >= 1
