"""Relocalisation (SLAM core II, ORB-SLAM Sec. V-C) through the Python API.

A small vocabulary (k=10, L=5) is trained at test time on ORB descriptors
from the System's own extractor: EuRoC MH_05 (every 10th frame; another
place and camera than the test clips) and KITTI 06 (every 5th frame). Then
the clips run with consecutive frames blacked out: tracking is lost
during the blackout and found again by relocalisation against the map, with
no reset; without a vocabulary the same runs report lost frames and do not crash.

Measured (synchronous mapping, repeatable on this machine; vocabulary of
36 images, 40515 words, trained in 0.15 s):
- EuRoC V1_01 micro, frames 40-59 black: relocalised at frame 60 (the first
  one after) in 2.7 ms, ATE 0.00075 m (0.00072 m without the blackout). The
  clip moves 0.16 m: its map is a single keyframe.
- KITTI 06 (~1.2 m per frame, 26-29 keyframes), frames 25-26 black:
  relocalised at frame 27 against the keyframe of frame 23, the database's
  candidate, in 6.5 ms; ATE 0.063 m (0.057 m without the blackout).
- KITTI 06, frames 25-29 black (6 m): relocalised at frame 30 in 6.1 ms,
  ATE 0.074 m. Here the database's candidate fails and the keyframe that
  tracking last referenced succeeds: with a vocabulary trained on 36 images
  the bag-of-words score against a keyframe fades to the level of unrelated
  frames after ~3 frames (3.6 m) of KITTI's forward motion. 8 black frames
  (10 m) are beyond it for some start frames and seeds.
- EuRoC MH_05 monocular, frames 120-129 black, vocabulary from KITTI only:
  relocalised at frame 130 while keyframe culling erases keyframes from the
  map and the database (see the test).
"""
from __future__ import annotations

import numpy as np
import pytest

from dynaorb import core


@pytest.fixture(scope="module")
def vocabulary(real_vocabulary):
    assert real_vocabulary.k == 10 and real_vocabulary.L == 5 and real_vocabulary.size > 10000
    return real_vocabulary


def _run(provider, black, vocabulary):
    """Tracks every frame, the `black` ones replaced by black images."""
    system = core().System(provider.default_settings(), provider.sensor, synchronous_mapping=True,
                           vocabulary=vocabulary)
    results = []
    for i in range(len(provider)):
        f = provider.load(i)
        if i in black and provider.sensor == "mono":
            results.append(system.track_mono(np.zeros_like(f.image), f.stamp))
        elif i in black:
            results.append(system.track_stereo(np.zeros_like(f.image), np.zeros_like(f.right), f.stamp))
        else:
            results.append(system.track_frame(f))
    return system, results


def _ate(provider, system, align="se3") -> float:
    from evo.core.trajectory import PoseTrajectory3D

    from dynaorb.evaluation import evaluate

    gt_stamps, gt_poses = provider.ground_truth()
    stamps, poses = system.trajectory()
    result = evaluate(PoseTrajectory3D(poses_se3=list(gt_poses), timestamps=gt_stamps),
                      PoseTrajectory3D(poses_se3=list(poses), timestamps=stamps), align=align, rpe_delta=None)
    return result.ate["rmse"]


def _check_relocalised(system, results, black, within):
    """Lost during the blackout, relocalised within `within` frames after it,
    tracked from then on, never reset."""
    assert all(r.state == "LOST" and r.method == "lost" and r.keypoints == 0 for r in results[black.start:black.stop])
    # The first black frame is tried with the motion model and the reference
    # keyframe; every later lost frame is relocalised (a black one has nothing to try with).
    assert "relocalization" not in results[black.start].stage_ms
    assert all("relocalization" in r.stage_ms for r in results[black.start + 1:black.stop])
    first = next(i for i in range(black.stop, len(results)) if results[i].state == "OK")
    assert first - black.stop <= within, [r.method for r in results[black.stop:first + 1]]
    assert results[first].method == "relocalization"
    assert results[first].tracked_points >= 50
    assert all(r.state == "OK" for r in results[first:]), [r.method for r in results[first:]]
    assert all(r.method != "init" for r in results[black.start:])
    counters = system.counters()
    assert counters["initializations"] == 1
    assert counters["relocalizations"] == 1
    assert counters["lost"] == first - black.start
    assert counters["tracked"] == sum(r.state == "OK" for r in results)
    return first


def test_euroc_blackout_is_relocalised_without_a_reset(data, vocabulary):
    provider = core().open_dataset("euroc", str(data / "euroc" / "V1_01_easy_micro"))
    black = range(40, 60)
    system, results = _run(provider, black, vocabulary)
    first = _check_relocalised(system, results, black, within=2)
    # The motion model needs two tracked frames: the next one goes through the reference keyframe.
    assert results[first + 1].method == "reference_keyframe"
    assert results[first + 2].method == "motion_model"
    ate = _ate(provider, system)
    print(f"\nATE {ate:.5f} m")
    # Target 0.03 m; measured 0.0008 m, 0.0007 m without the blackout.
    assert ate <= 0.03
    assert ate <= 0.004
    assert len(system.trajectory()[0]) == len(results) - len(black)


@pytest.mark.parametrize("black", [range(25, 27), range(25, 30)], ids=["2_frames", "5_frames"])
def test_kitti_blackout_is_relocalised(data, vocabulary, black):
    provider = core().open_dataset("kitti", str(data / "kitti" / "sequences" / "06"))
    system, results = _run(provider, black, vocabulary)
    _check_relocalised(system, results, black, within=3)
    assert system.map_summary()["keyframes"] > 5  # a map the reset rule would never drop
    # Target 0.15 m (SLAM core I); measured 0.063 m / 0.074 m, 0.057 m without a blackout.
    ate = _ate(provider, system)
    print(f"\nATE {ate:.5f} m")
    assert ate <= 0.15
    assert ate <= 0.1


def test_mono_blackout_is_relocalised_while_keyframes_are_culled(data):
    """MH_05 monocular (initialised at frame 8), frames 120-129 black, with a
    vocabulary trained on KITTI 06 only: relocalised at frame 130 in ~7.5 ms.
    Keyframe culling removes ~150 keyframes from the map (and the database)
    meanwhile. Measured Sim3 ATE 0.013 m (0.016 m without the blackout); with
    the first map at frame 85 (ORB-SLAM2's 2x initial features) it was
    0.0085-0.011 m for training seeds 0-2."""
    _core = core()
    kitti = _core.open_dataset("kitti", str(data / "kitti" / "sequences" / "06"))
    settings = kitti.default_settings()
    vocabulary = _core.Vocabulary.train([_core.extract_orb(kitti.load(i).image, settings)[1]
                                         for i in range(0, len(kitti), 5)], k=10, L=5, seed=0)
    provider = _core.open_dataset("euroc", str(data / "euroc" / "MH_05_difficult_head"))
    assert provider.sensor == "mono"
    black = range(120, 130)
    system, results = _run(provider, black, vocabulary)
    _check_relocalised(system, results, black, within=2)
    assert system.map_summary()["keyframes_culled"] > 10
    # Target 0.10 m (monocular, Sim3); measured 0.013 m.
    ate = _ate(provider, system, align="sim3")
    print(f"\nSim3 ATE {ate:.5f} m")
    assert ate <= 0.10
    assert ate <= 0.03


def test_without_a_vocabulary_the_blackout_is_lost_and_nothing_crashes(data):
    provider = core().open_dataset("euroc", str(data / "euroc" / "V1_01_easy_micro"))
    black = range(40, 60)
    system, results = _run(provider, black, None)
    assert all(r.state == "LOST" for r in results[black.start:black.stop])
    assert not any("relocalization" in r.stage_ms or r.method == "relocalization" for r in results)
    counters = system.counters()
    assert counters["lost"] >= len(black) and counters["relocalizations"] == 0
    # Black frames could not start a map: the small map is kept, and the
    # reference keyframe finds the next frame again (brute-force matching).
    assert counters["initializations"] == 1
    assert results[black.stop].method == "reference_keyframe" and results[black.stop].state == "OK"


def test_vocabulary_api(tmp_path, data, vocabulary):
    _core = core()
    path = tmp_path / "voc.bin"
    vocabulary.save(path)
    loaded = _core.Vocabulary.load(path)
    assert loaded.size == vocabulary.size == len(loaded)
    provider = _core.open_dataset("euroc", str(data / "euroc" / "V1_01_easy_micro"))
    settings = provider.default_settings()
    _, d0 = _core.extract_orb(provider.load(0).image, settings)
    _, d1 = _core.extract_orb(provider.load(1).image, settings)
    b0, b1 = vocabulary.transform(d0), loaded.transform(d0)
    assert b0 == b1 and abs(sum(b0.values()) - 1.0) < 1e-9
    assert vocabulary.score(b0, b0) == pytest.approx(1.0)
    assert 0.0 < vocabulary.score(b0, vocabulary.transform(d1)) < 1.0
    # A System takes the vocabulary as an object or a path (binary or ORBvoc.txt).
    text = tmp_path / "voc.txt"
    vocabulary.save_text(text)
    for v in (loaded, path, str(text)):
        system = _core.System(settings, "stereo", vocabulary=v)
        assert system.track_frame(provider.load(0)).method == "init"
    with pytest.raises(ValueError, match="32"):
        _core.Vocabulary.train([np.zeros((5, 16), np.uint8)], k=10, L=5)
    with pytest.raises(ValueError):
        _core.Vocabulary.train([np.zeros((0, 32), np.uint8)], k=10, L=5)
    with pytest.raises(ValueError, match="nope"):
        _core.System(settings, "stereo", vocabulary=tmp_path / "nope.bin")
    with pytest.raises(TypeError):
        _core.System(settings, "stereo", vocabulary=3)
