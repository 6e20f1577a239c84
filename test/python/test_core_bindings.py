"""The pybind11 module: providers over ../shared/data, settings and System input checks."""
from __future__ import annotations

import os
import pathlib
import threading
import time

import numpy as np
import pytest

from dynaorb import core


@pytest.mark.parametrize("kind, rel, sensor, n, size", [
    ("tum", "tum/rgbd_dataset_freiburg3_walking_xyz_fragment", "rgbd", 2, (480, 640)),
    ("kitti", "kitti/sequences/06", "stereo", 51, (370, 1226)),
    ("euroc", "euroc/V1_01_easy_micro", "stereo", 95, (480, 752)),
    ("euroc", "euroc/MH_05_difficult_head", "mono", 250, (480, 752)),
])
def test_every_shared_sequence_loads(data, kind, rel, sensor, n, size):
    provider = core().open_dataset(kind, str(data / rel))
    assert provider.sensor == sensor
    assert len(provider) == n
    for i in (0, n - 1):
        frame = provider.load(i)
        assert frame.image.shape[:2] == size
        if sensor == "stereo":
            assert frame.right.shape[:2] == size
        if sensor == "rgbd":
            assert frame.depth.dtype == np.uint16 and frame.depth.shape == size
    stamps, poses = provider.ground_truth()
    assert len(stamps) > 0 and poses.shape[1:] == (4, 4)
    assert np.allclose(poses[:, 3, :], [0, 0, 0, 1])
    provider.default_settings().validate(sensor)


def test_errors_are_value_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown dataset kind"):
        core().open_dataset("vicon", str(tmp_path))
    with pytest.raises(core().InputError, match="rgb.txt"):
        core().open_dataset("tum", str(tmp_path))
    with pytest.raises(ValueError, match="sensor"):
        core().parse_sensor("lidar")
    (tmp_path / "s.yaml").write_text("%YAML:1.0\nCamera.fx: 500\n")
    with pytest.raises(core().InputError, match="Camera.fy"):
        core().Settings.load(str(tmp_path / "s.yaml"))


def test_system_counts_bad_frames(data):
    settings = core().open_dataset("tum", str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment")) \
        .default_settings()
    system = core().System(settings, "rgbd")
    rgb = np.zeros((480, 640, 3), np.uint8)
    depth = np.full((480, 640), np.nan, np.float32)
    r = system.track_rgbd(rgb, depth, 1.0)
    assert r.rejected == "none" and r.invalid_depth_pixels == 480 * 640
    assert system.track_rgbd(rgb, depth, 0.5).rejected == "stamp_not_increasing"
    assert system.track_rgbd(rgb[:100], depth[:100], 2.0).rejected == "wrong_size"
    assert system.track_rgbd(rgb, depth.astype(np.float64).astype(np.float32)[:, :, None].repeat(2, 2),
                             3.0).rejected == "wrong_type"
    with pytest.raises(ValueError, match="dtype"):
        system.track_rgbd(rgb.astype(np.float64), depth, 4.0)
    with pytest.raises(ValueError, match="track_mono"):
        system.track_mono(rgb, 5.0)
    counters = system.counters()
    assert counters["frames"] == 4 and counters["rejected"] == 3
    stamps, poses = system.trajectory()
    assert stamps.shape == (0,) and poses.shape == (0, 4, 4)


def test_tracker_options_reach_the_system(data):
    """TrackerOptions from Python: the monocular initialisation's feature
    factor changes how many keypoints the first frame gets."""
    o = core().TrackerOptions()
    assert o.mono_init_feature_factor == 4 and o.mono_init_feature_frames == 60  # chosen on MH_05 (tracker.h)
    assert o.mono_init_release_tracked == 1000
    provider = core().open_dataset("euroc", str(data / "euroc/MH_05_difficult_head"))
    settings = provider.default_settings()
    frame = provider.load(0)
    counts = {}
    for factor in (1, 4):
        o.mono_init_feature_factor = factor
        system = core().System(settings, "mono", synchronous_mapping=True, tracker=o)
        counts[factor] = system.track_mono(frame.image, frame.stamp).keypoints
    n = settings.n_features
    assert counts[1] <= n * 1.05
    assert counts[4] > 2 * n


def test_run_names_a_bad_tracker_option(data, tmp_path):
    from dynaorb.runner import RunOptions, run_dataset
    base = dict(kind="euroc", path=str(data / "euroc/MH_05_difficult_head"), out=str(tmp_path / "o"),
                vocabulary="none", progress=False)
    with pytest.raises(ValueError, match="unknown tracker option 'mono_init_factor'"):
        run_dataset(RunOptions(**base, tracker={"mono_init_factor": 5}))
    with pytest.raises(ValueError, match="'mono_init_feature_frames': 2.5 is not a whole number"):
        run_dataset(RunOptions(**base, tracker={"mono_init_feature_frames": 2.5}))


def test_switch_options_from_the_shell():
    """A switch (a bool option) from `--tracker KEY=true|false`: set as given,
    1 / 0 accepted, anything else refused rather than rounded."""
    from dynaorb.cli.commands import key_values
    from dynaorb.runner.run import core_options

    values = key_values(["motion_vo_points=false", "mask_margin=3"], "--tracker")
    assert values == {"motion_vo_points": False, "mask_margin": 3.0}
    o = core_options(core().TrackerOptions, values, "tracker")
    assert o.motion_vo_points is False and o.mask_margin == 3
    assert core_options(core().TrackerOptions, key_values(["motion_vo_points=TRUE"], "-t"), "tracker").motion_vo_points
    assert not core_options(core().TrackerOptions, {"motion_vo_points": 0}, "tracker").motion_vo_points
    with pytest.raises(ValueError, match="'motion_vo_points': 0.5 is not true / false"):
        core_options(core().TrackerOptions, {"motion_vo_points": 0.5}, "tracker")
    with pytest.raises(ValueError, match="--tracker 'motion_vo_points=yes': expected KEY=NUMBER or KEY=true / false"):
        key_values(["motion_vo_points=yes"], "--tracker")
    with pytest.raises(ValueError, match="tracker option 'mask_margin' is -1"):
        core_options(core().TrackerOptions, {"mask_margin": -1}, "tracker").validate()


def test_run_takes_tracker_options(data, tmp_path):
    from dynaorb.runner import RunOptions, run_dataset
    stats = run_dataset(RunOptions(kind="tum", path=str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"),
                                   out=str(tmp_path / "o"), vocabulary="none", progress=False,
                                   tracker={"min_init_keypoints": 400}))
    assert stats["tracker_options"] == {"min_init_keypoints": 400}
    assert stats["tracked_frames"] >= 1


def test_mapping_and_loop_options_reach_the_system(data):
    """LocalMapperOptions from Python: without local BA no local BA runs, with
    the defaults (ORB-SLAM2's) it runs on the keyframes of KITTI 06's first
    frames."""
    o = core().LocalMapperOptions()
    assert o.neighbors_stereo == 10 and o.min_found_ratio == 0.25 and o.local_ba
    assert core().LoopCloserOptions().ransac.min_inliers == 20
    provider = core().open_dataset("kitti", str(data / "kitti/sequences/06"), "stereo")
    settings = provider.default_settings()
    runs, summaries = {}, {}
    for local_ba in (True, False):
        o.local_ba = local_ba
        system = core().System(settings, "stereo", synchronous_mapping=True, mapping=o,
                               loop=core().LoopCloserOptions())
        for i in range(12):
            system.track_frame(provider.load(i), None, None)
        summaries[local_ba] = s = system.map_summary()
        runs[local_ba] = s["local_ba_runs"]
    assert runs[True] > 0 and runs[False] == 0
    # The last window: the new keyframe and its covisibles optimised, fixed ones around them.
    s = summaries[True]
    assert 2 <= s["local_ba_window_last"] <= s["local_ba_window_max"] <= s["keyframes"]
    assert s["local_ba_fixed_last"] >= 0 and summaries[False]["local_ba_window_max"] == 0
    # Local BAs that a new keyframe may not abort (asynchronous mapping) all run to the end.
    o.local_ba, o.abort_ba_for_keyframes = True, False
    system = core().System(settings, "stereo", synchronous_mapping=False, mapping=o, loop=core().LoopCloserOptions())
    for i in range(30):
        system.track_frame(provider.load(i), None, None)
    system.wait_for_mapping()
    s = system.map_summary()
    assert s["local_ba_runs"] > 0 and s["local_ba_aborted"] == 0


def test_synchronous_mapping_optimises_on_every_core_with_the_same_result(data):
    """Under synchronous mapping tracking waits for local BA, so its Ceres
    threads are ba_threads_synchronous (0, the default: every core); one
    thread or two give the same map to rounding (Ceres' threaded sums)."""
    import numpy as np

    assert core().LocalMapperOptions().ba_threads_synchronous == 0
    assert core().LoopCloserOptions().threads_synchronous == 0
    provider = core().open_dataset("kitti", str(data / "kitti/sequences/06"), "stereo")
    poses = {}
    for threads in (1, 2):
        o = core().LocalMapperOptions()
        o.ba_threads_synchronous = threads
        system = core().System(provider.default_settings(), "stereo", synchronous_mapping=True, mapping=o)
        for i in range(15):
            assert system.track_frame(provider.load(i), None, None).state == "OK"
        assert system.map_summary()["local_ba_runs"] > 0
        poses[threads] = np.asarray(system.trajectory()[1])
    assert poses[1].shape == poses[2].shape and np.allclose(poses[1], poses[2], atol=1e-9)
    o = core().LocalMapperOptions()
    o.ba_threads_synchronous = -1
    with pytest.raises(ValueError, match="local mapping option 'ba_threads_synchronous' is -1"):
        core().System(provider.default_settings(), "stereo", mapping=o)


def test_mapping_and_loop_options_are_checked(data, tmp_path):
    """A value out of range is refused where the System is made, naming the
    option; an unknown or malformed one by the runner before anything loads."""
    provider = core().open_dataset("tum", str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"))
    settings = provider.default_settings()
    mapping = core().LocalMapperOptions()
    mapping.min_found_ratio = float("nan")
    with pytest.raises(ValueError, match="local mapping option 'min_found_ratio' is nan"):
        core().System(settings, "rgbd", mapping=mapping)
    loop = core().LoopCloserOptions()
    loop.ransac.chi2 = -1.0  # a nested field, changed in place
    with pytest.raises(ValueError, match="loop closing option 'ransac.chi2' is -1"):
        core().System(settings, "rgbd", loop=loop)

    from dynaorb.runner import RunOptions, run_dataset
    base = dict(kind="tum", path=str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"),
                out=str(tmp_path / "o"), vocabulary="none", progress=False)
    with pytest.raises(ValueError, match="unknown local mapping option 'neighbours_stereo'"):
        run_dataset(RunOptions(**base, mapping={"neighbours_stereo": 5}))
    with pytest.raises(ValueError, match="unknown loop closing option 'ransac.inliers' \\(known in ransac: chi2"):
        run_dataset(RunOptions(**base, loop={"ransac.inliers": 5}))
    with pytest.raises(ValueError, match="'ransac' is a group of options"):
        run_dataset(RunOptions(**base, loop={"ransac": 5}))
    with pytest.raises(ValueError, match="'ransac.min_inliers': 2.5 is not a whole number"):
        run_dataset(RunOptions(**base, loop={"ransac.min_inliers": 2.5}))
    with pytest.raises(ValueError, match="local mapping option 'redundant_ratio' is 1.5"):
        run_dataset(RunOptions(**base, mapping={"redundant_ratio": 1.5}))
    stats = run_dataset(RunOptions(**base, mapping={"neighbors_stereo": 15}, loop={"ransac.chi2": 7.8}))
    assert stats["mapping_options"] == {"neighbors_stereo": 15}
    assert stats["loop_options"] == {"ransac.chi2": 7.8}


def test_tracker_option_groups_reach_the_system(data, tmp_path):
    """TrackerOptions' nested groups (reloc, reloc.pnp, two_view) from Python
    and the shell: read and written in place, checked by the System."""
    o = core().TrackerOptions()
    assert o.reloc.min_inliers == 50 and o.reloc.pnp.chi2 == 5.991 and o.two_view.ratio_h == 0.4
    o.reloc.pnp.probability = 1.5
    assert o.reloc.pnp.probability == 1.5  # in place, not on a copy
    with pytest.raises(ValueError, match="tracker option 'reloc.pnp.probability' is 1.5"):
        o.validate()
    provider = core().open_dataset("tum", str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"))
    with pytest.raises(ValueError, match="tracker option 'reloc.pnp.probability' is 1.5"):
        core().System(provider.default_settings(), "rgbd", tracker=o)

    from dynaorb.runner import RunOptions, run_dataset
    base = dict(kind="tum", path=str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"),
                out=str(tmp_path / "o"), vocabulary="none", progress=False)
    with pytest.raises(ValueError, match="tracker option 'two_view.min_parallax_deg' is 95"):
        run_dataset(RunOptions(**base, tracker={"two_view.min_parallax_deg": 95}))
    with pytest.raises(ValueError, match="unknown tracker option 'reloc.pnp.inliers' \\(known in reloc.pnp: chi2"):
        run_dataset(RunOptions(**base, tracker={"reloc.pnp.inliers": 5}))
    with pytest.raises(ValueError, match="tracker option 'reloc.pnp.seed': -1 is not an integer >= 0"):
        run_dataset(RunOptions(**base, tracker={"reloc.pnp.seed": -1}))
    stats = run_dataset(RunOptions(**base, tracker={"reloc.min_inliers": 40}))
    assert stats["tracker_options"] == {"reloc.min_inliers": 40} and stats["tracked_fraction"] > 0


def _thread_nices() -> list[int]:
    """Nice values of this process's threads (field 19 of /proc/self/task/*/stat)."""
    out = []
    for task in pathlib.Path("/proc/self/task").iterdir():
        try:
            stat = (task / "stat").read_text()
        except OSError:  # the thread ended meanwhile
            continue
        out.append(int(stat[stat.rindex(")") + 2:].split()[16]))
    return out


@pytest.mark.skipif(not pathlib.Path("/proc/self/task").is_dir(), reason="per-thread nice values are Linux's")
def test_background_threads_run_nicer_than_tracking(data):
    """The local mapping and loop closing threads take background_nice above
    the process's nice value; the calling thread keeps its own."""
    provider = core().open_dataset("tum", str(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"))
    settings = provider.default_settings()
    base = os.getpriority(os.PRIO_PROCESS, 0)
    if base > 12:
        pytest.skip(f"the tests already run at nice {base}")
    before = _thread_nices().count(base + 7)
    system = core().System(settings, "rgbd", background_nice=7)
    frame = provider.load(0)
    system.track_rgbd(frame.image, frame.depth, frame.stamp)  # the threads start with the first frame
    deadline = time.monotonic() + 5
    while _thread_nices().count(base + 7) < before + 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert _thread_nices().count(base + 7) >= before + 1  # local mapping (and loop closing, with a vocabulary)
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == base
    del system
    with pytest.raises(ValueError, match="background_nice must be in \\[0, 19\\], got 20"):
        core().System(settings, "rgbd", background_nice=20)


def test_non_contiguous_arrays_cross_as_copies(data):
    """A slice or a Fortran-ordered array reaches the core as its own copy (numpy_mat.h's as_mat):
    the same result as the C-ordered array, never the freed temporary pybind11 made for it."""
    import cv2

    frames = sorted((data / "euroc" / "MH_05_difficult_head" / "mav0" / "cam0" / "data").glob("*.png"))[:2]
    a, b = (cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in frames)
    labels = np.zeros_like(a)
    labels[100:300, 200:350] = 15
    prop = core().LabelPropagator(0.5)
    expected = prop.warp(labels, a, b)
    assert (expected == 15).sum() > 20000
    for variant in (np.asfortranarray, lambda m: np.hstack([m, m])[:, : m.shape[1]]):
        got = prop.warp(variant(labels), variant(a), variant(b))
        assert np.array_equal(got, expected)


def test_live_labels_forget_the_time_before(data):
    """LiveLabels.forget_after: time went back (a bag played again); the labels of the time
    before are dropped, and the new time's frames get their own (a capped store would
    otherwise drop the new labels first, as the oldest)."""
    import cv2

    grey = cv2.imread(str(sorted((data / "kitti" / "sequences" / "06" / "image_0").glob("*.png"))[0]),
                      cv2.IMREAD_GRAYSCALE)
    labels = np.zeros_like(grey)
    labels[100:200, 300:400] = 7
    for forget in (False, True):
        live = core().LiveLabels(frames_kept=4)
        for k in range(4):
            live.labels_for(10.0 + 0.1 * k, grey)
            live.add_labels(10.0 + 0.1 * k, labels)
        if forget:
            live.forget_after(1.0)
        live.add_labels(1.0, labels)
        got, source, age, _ = live.labels_for(1.0, grey)
        if forget:
            assert source == "fresh" and age == 0.0 and np.array_equal(got, labels)
        else:
            assert source == "stale" and got is None
    with pytest.raises(ValueError, match="forget_after's stamp is not finite"):
        live.forget_after(float("nan"))
