"""dynaorb run: real files and stats, counted degradations on bad frames, clear CLI errors."""
from __future__ import annotations

import collections
import json
import shutil
import statistics
import subprocess
import sys

import pytest

from conftest import REPO
from dynaorb.runner import RunOptions, run_dataset


def test_run_writes_trajectory_and_stats(tmp_path, synth_rgbd):
    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path),
                                   masks=str(synth_rgbd / "dynamic_masks"), progress=False))
    on_disk = json.loads((tmp_path / "stats.json").read_text())
    assert on_disk == json.loads(json.dumps(stats))
    assert stats["frames"] == 8
    assert stats["masks"] == {"used": 8}
    assert sum(stats["states"].values()) == 8
    assert stats["stage_ms_median"]["preprocess"] > 0
    assert stats["fps"] > 0
    assert (tmp_path / "trajectory.tum").is_file()
    assert (tmp_path / "groundtruth.tum").read_text().count("\n") == 9  # header + 8 poses
    # Tracked frames and the trajectory file agree.
    lines = [l for l in (tmp_path / "trajectory.tum").read_text().splitlines() if not l.startswith("#")]
    assert len(lines) == stats["tracked_frames"]
    if stats["tracked_frames"] < 3:
        assert stats["ate"] is None and "tracked" in stats["reason"]


def test_kitti_run_writes_kitti_file(tmp_path, data):
    stats = run_dataset(RunOptions(kind="kitti", path=str(data / "kitti/sequences/06"), out=str(tmp_path),
                                   progress=False))
    assert stats["frames"] == 51 and stats["dataset"]["sensor"] == "stereo"
    assert (tmp_path / "trajectory.kitti").is_file()


def test_corrupt_frame_is_skipped_and_counted(tmp_path, synth_rgbd):
    seq = tmp_path / "seq"
    shutil.copytree(synth_rgbd, seq)
    victim = sorted((seq / "rgb").iterdir())[3]
    victim.write_bytes(b"\x89PNG broken")
    (seq / "dynamic_masks" / sorted((seq / "rgb").iterdir())[5].name).unlink()
    stats = run_dataset(RunOptions(kind="tum", path=str(seq), out=str(tmp_path / "out"),
                                   masks=str(seq / "dynamic_masks"), progress=False))
    assert stats["frames_skipped"] == {"unreadable": 1}
    assert sum(stats["states"].values()) == 7
    assert stats["masks"] == {"used": 6, "missing": 1}
    # One record per frame read, the unreadable one left out; they agree with the totals.
    frames = stats["per_frame"]
    assert [f["index"] for f in frames] == [0, 1, 2, 4, 5, 6, 7]
    assert collections.Counter(f["state"] for f in frames) == collections.Counter(stats["states"])
    assert [f["track_call_ms"] for f in frames] == stats["track_call_ms"]
    # The tracking stage's wait for the map lock, per frame and summarised.
    waits = [f["map_wait_ms"] for f in frames]
    assert all(w is not None and w >= 0 for w in waits)
    assert stats["map_wait_ms"]["max"] == max(waits) and stats["map_wait_ms"]["median"] <= max(waits)
    # Each frame's stage times; their medians are stage_ms_median's.
    extract = [f["stage_ms"]["extract"] for f in frames if "extract" in f["stage_ms"]]
    assert len(extract) == 7 and all(ms > 0 for ms in extract)
    assert stats["stage_ms_median"]["extract"] == pytest.approx(statistics.median(extract), abs=1e-3)
    assert all(f["map"] == 0 and not f["map_dropped"] and f["rejected"] is None for f in frames)
    assert sum(f["state"] == "OK" for f in frames) == stats["tracked_frames"]
    assert frames[0]["method"] == "init" and frames[0]["new_keyframe"] and frames[0]["keypoints"] > 0
    assert all(f["stamp"] < g["stamp"] for f, g in zip(frames, frames[1:]))


def test_unknown_dynamic_mode(tmp_path, synth_rgbd):
    with pytest.raises(ValueError, match="dynamic mode"):
        run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path), dynamic="magic"))


def test_cli_run_and_errors(tmp_path, synth_rgbd):
    ok = subprocess.run([sys.executable, "-m", "dynaorb", "run", "tum", str(synth_rgbd), "--out",
                         str(tmp_path / "o"), "--quiet"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert "frames tracked" in ok.stdout
    bad = subprocess.run([sys.executable, "-m", "dynaorb", "run", "kitti", str(tmp_path / "nowhere"), "--quiet"],
                         capture_output=True, text=True)
    assert bad.returncode == 2
    assert "times.txt" in bad.stderr and "Traceback" not in bad.stderr
    cfg = tmp_path / "broken.yaml"
    cfg.write_text("%YAML:1.0\nCamera.fx: 1\nCamera.fy: 1\nCamera.cx: 1\nCamera.cy: 1\n")
    bad = subprocess.run([sys.executable, "-m", "dynaorb", "run", "tum", str(synth_rgbd), "--config", str(cfg),
                          "--quiet", "--out", str(tmp_path / "o2")], capture_output=True, text=True)
    assert bad.returncode == 2 and "Camera.bf" in bad.stderr


def test_euroc_stereo_run_rectifies(tmp_path, data):
    stats = run_dataset(RunOptions(kind="euroc", path=str(data / "euroc/V1_01_easy_micro"), out=str(tmp_path),
                                   config=str(REPO / "config" / "EuRoC_stereo.yaml"), progress=False))
    assert stats["frames"] == 95 and not stats["frames_rejected"] and not stats["frames_skipped"]
    assert "stereo rectification: yes" in stats["settings"]
