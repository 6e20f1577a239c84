"""dynaorb run: real files and stats, counted degradations on bad frames, clear CLI errors."""
from __future__ import annotations

import collections
import json
import os
import re
import shutil
import signal
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


class _CtrlCAt:
    """A dataset's frames, with Ctrl-C (SIGINT to this process, `times` times) while frame `at` loads."""

    def __init__(self, provider, at: int, times: int = 1):
        self._provider, self._at, self._times = provider, at, times

    def __len__(self):
        return len(self._provider)

    def __getattr__(self, name):
        return getattr(self._provider, name)

    def load(self, i: int):
        frame = self._provider.load(i)
        if i == self._at:
            for _ in range(self._times):
                os.kill(os.getpid(), signal.SIGINT)
        return frame


def test_ctrl_c_stops_between_frames_and_keeps_the_outputs(tmp_path, synth_rgbd):
    from dynaorb import core
    from dynaorb.cli.commands import _exit_status, summary_line

    # The handler in place before the run is what it hands back: Python's own,
    # or SIG_IGN where the tests run in the background of a shell without job
    # control (the handler is installed over SIG_IGN as well).
    before = signal.getsignal(signal.SIGINT)
    provider = _CtrlCAt(core().open_dataset("tum", str(synth_rgbd), None), at=5)
    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path), vocabulary="none",
                                   provider=provider, progress=False))
    # Frames 0-4 tracked, frame 5 (loading when Ctrl-C came) and the rest not run.
    assert stats["interrupted"] == {"frames_run": 5}
    assert [f["index"] for f in stats["per_frame"]] == [0, 1, 2, 3, 4]
    assert stats["tracked_frames"] == 5 and stats["tracked_fraction"] == 1.0
    rows = [l for l in (tmp_path / "trajectory.tum").read_text().splitlines() if not l.startswith("#")]
    assert len(rows) == 5
    assert json.loads((tmp_path / "stats.json").read_text())["interrupted"] == {"frames_run": 5}
    assert stats["ate"] is not None  # over the frames run
    assert signal.getsignal(signal.SIGINT) is before  # handed back
    assert _exit_status(stats) == 130
    assert "5/5 frames tracked (interrupted: 5 of 8 frames run)" in summary_line(tmp_path, stats)
    # A second Ctrl-C quits at once, without outputs.
    twice = _CtrlCAt(core().open_dataset("tum", str(synth_rgbd), None), at=2, times=2)
    with pytest.raises(KeyboardInterrupt):
        run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "twice"), vocabulary="none",
                               provider=twice, progress=False))
    assert not (tmp_path / "twice" / "stats.json").exists()
    assert signal.getsignal(signal.SIGINT) is before


def test_a_frame_range_runs_those_frames_only(tmp_path, synth_rgbd):
    from dynaorb import core
    from dynaorb.cli.main import main

    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "a"), vocabulary="none",
                                   frames="2:6", progress=False))
    assert stats["frames"] == 4 and stats["frame_range"] == [2, 6] and stats["dataset"]["frames"] == 8
    assert [f["index"] for f in stats["per_frame"]] == [2, 3, 4, 5]
    assert stats["init_frame"] == 2 and stats["tracked_fraction"] == stats["tracked_fraction_after_init"] == 1.0
    rows = [l.split() for l in (tmp_path / "a" / "trajectory.tum").read_text().splitlines() if not l.startswith("#")]
    provider = core().open_dataset("tum", str(synth_rgbd), None)
    assert [float(r[0]) for r in rows] == pytest.approx([provider.stamp(i) for i in range(2, 6)], abs=1e-6)
    assert stats["matched_poses"] == 4
    # Ctrl-C within a range: the fractions are over the frames of the range run.
    cut = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "b"), vocabulary="none",
                                 frames=(3, None), provider=_CtrlCAt(provider, at=6), progress=False))
    assert cut["interrupted"] == {"frames_run": 3} and cut["tracked_fraction"] == 1.0
    assert cut["tracked_fraction_after_init"] == 1.0
    assert main(["run", "tum", str(synth_rgbd), "--out", str(tmp_path / "c"), "--vocabulary", "none", "--quiet",
                 "--frames", ":3"]) == 0
    assert json.loads((tmp_path / "c" / "stats.json").read_text())["frame_range"] == [0, 3]


def test_a_long_synchronous_run_mostly_mapping_says_async_mapping_exists(tmp_path, synth_rgbd, monkeypatch, caplog):
    from dynaorb.runner import run as runner

    monkeypatch.setattr(runner, "SYNC_HINT_MIN_WALL_S", 0.0)
    monkeypatch.setattr(runner, "SYNC_HINT_SHARE", 0.0)  # any local mapping at all
    with caplog.at_level("INFO", logger=runner.log.name):
        run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "a"), vocabulary="none",
                               progress=False))
    assert "--async-mapping" in caplog.text
    caplog.clear()
    with caplog.at_level("INFO", logger=runner.log.name):
        run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "b"), vocabulary="none",
                               synchronous_mapping=False, progress=False))
    assert "--async-mapping" not in caplog.text


@pytest.mark.parametrize("spec,message", [("5:2", "no frame"), ("8:", "no frame"), ("a:3", "whole numbers"),
                                          ("1:2:3", "START:END"), ("-1:4", "from 0"), ("3", "START:END"),
                                          ("None:4", "whole numbers"), ((0.5, 4), "whole numbers")])
def test_a_frame_range_that_is_wrong_is_named(spec, message):
    from dynaorb.runner.frames import frame_range

    with pytest.raises(ValueError, match=message):
        frame_range(spec, 8)
    assert frame_range("6:100", 8) == range(6, 8) and frame_range(None, 8) == range(8)
    assert frame_range(":", 8) == range(8) and frame_range((2, None), 8) == range(2, 8)


def test_cli_ctrl_c_writes_the_frames_so_far(tmp_path, data):
    """`dynaorb run` paced at half KITTI 06's rate, Ctrl-C once its progress bar has passed frame 5."""
    proc = subprocess.Popen([sys.executable, "-m", "dynaorb", "run", "kitti", str(data / "kitti" / "sequences" / "06"),
                             "--out", str(tmp_path), "--vocabulary", "none", "--realtime", "0.5"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = ""
    try:
        while max(map(int, re.findall(r"(\d+)/51", seen)), default=0) < 5:  # tqdm's "N/51"
            char = proc.stderr.read(1)
            assert char, f"the run ended before frame 5: {seen}"
            seen += char
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, seen + err
    assert "interrupted:" in out and "of 51 frames run" in out
    stats = json.loads((tmp_path / "stats.json").read_text())
    assert 5 <= stats["interrupted"]["frames_run"] < 51
    assert stats["tracked_frames"] == stats["interrupted"]["frames_run"]
    assert (tmp_path / "trajectory.kitti").is_file()


def test_euroc_stereo_run_rectifies(tmp_path, data):
    stats = run_dataset(RunOptions(kind="euroc", path=str(data / "euroc/V1_01_easy_micro"), out=str(tmp_path),
                                   config=str(REPO / "config" / "EuRoC_stereo.yaml"), progress=False))
    assert stats["frames"] == 95 and not stats["frames_rejected"] and not stats["frames_skipped"]
    assert "stereo rectification: yes" in stats["settings"]
