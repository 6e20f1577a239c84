"""`dynaorb bench --suite seeds`: seed parsing, the summary's arithmetic, and one small sweep run for real."""
from __future__ import annotations

import json
import os

import pytest

from dynaorb.bench import seeds_peer
from dynaorb.bench.seeds import SeedsOptions, parse_seeds, render, run_seeds, summarize


def test_seeds_parse_as_count_range_and_list():
    assert parse_seeds("12") == tuple(range(12))
    assert parse_seeds("3-5") == (3, 4, 5)
    assert parse_seeds("0-2,7, 9") == (0, 1, 2, 7, 9)
    assert parse_seeds("4-4") == (4,)
    for bad, says in [("0", "count must be >= 1"), ("5-3", "empty range"), ("a", "not a seed"),
                      ("1-", "not a seed"), ("", "not a seed")]:
        with pytest.raises(ValueError, match=says):
            parse_seeds(bad)


def test_options_refuse_what_cannot_run():
    for kwargs, says in [({"sensors": ("lidar",)}, "lidar"), ({"conditions": ("full",)}, "include static"),
                         ({"conditions": ("static", "best")}, "best"), ({"jobs": 0}, "jobs"),
                         ({"seeds": ()}, "at least one seed"), ({"preset": "fastest"}, "unknown dynamic mode"),
                         ({"preset": "li", "sensors": ("rgbd",)}, "no stage list for the rgbd sensor"),
                         ({"tracker": {"min_pose_iniers": 5}}, "unknown tracker option 'min_pose_iniers'"),
                         ({"mapping": {"redundant_ratio": 2}}, "local mapping option 'redundant_ratio' is 2"),
                         ({"loop": {"ransac.chi2": 0}}, "loop closing option 'ransac.chi2' is 0"),
                         ({"realtime": float("nan")}, "expected a positive number"),
                         ({"realtime": 1.0, "jobs": 2}, "jobs must be 1 with realtime")]:
        with pytest.raises(ValueError, match=says):
            SeedsOptions(**kwargs).validate()


def _record(sensor, seed, condition, ate=None, error=None):
    r = {"sensor": sensor, "seed": seed, "condition": condition}
    if error:
        r["error"] = error
    else:
        r.update(ate_rmse=ate, frames=60, tracked_frames=60 if ate is not None else 12)
    return r


def test_summary_medians_worst_seed_and_targets():
    static = {0: 0.002, 1: 0.004, 2: 0.003, 3: 0.005}
    full = {0: 0.0022, 1: 0.006, 2: 0.0027, 3: 0.060}          # ratios 1.1, 1.5, 0.9, 12
    off = {0: 0.02, 1: 0.008, 2: 0.3, 3: None}                   # 10, 2, 100, no ATE (lost)
    records = [_record("stereo", s, "static", a) for s, a in static.items()]
    records += [_record("stereo", s, "full", a) for s, a in full.items()]
    records += [_record("stereo", s, "off", a) for s, a in off.items()]
    records.append(_record("stereo", 4, "static", error="died of signal SIGSEGV\nlog"))
    records.append(_record("stereo", 4, "full", 0.003))            # no static run to compare with: left out
    results = {"options": {"seeds": [0, 1, 2, 3, 4], "frames": 60, "width": 640, "height": 480,
                           "sensors": ["stereo"]},
               "conditions": {"static": {}, "full": {}, "off": {}},
               "targets": {"full": ["<=", 1.2], "off": [">=", 3.0]},
               "records": records, "started": "t0", "finished": "t1"}
    rows = {r["condition"]: r for r in summarize(results)}
    full_row, off_row = rows["full"], rows["off"]
    assert full_row["seeds"] == 4 and full_row["median"] == pytest.approx((1.1 + 1.5) / 2)
    assert full_row["worst_seed"] == 3 and full_row["worst"] == pytest.approx(12.0)
    assert full_row["meeting"] == 2 and full_row["median_meets"] is False
    assert full_row["test_seeds_median"] == pytest.approx(1.1)
    # off must be at least 3x worse: its worst seed is the smallest ratio.
    assert off_row["seeds"] == 3 and off_row["worst_seed"] == 1 and off_row["worst"] == pytest.approx(2.0)
    assert off_row["meeting"] == 2 and off_row["median_meets"] is True
    text = render(results)
    assert "| stereo | full | <= 1.2 | 4 | 1.30 | 1.10 | 12.00 (seed 3) | 2/4 | missed |" in text
    assert "| 4 | failed | 3.00 | n/a | n/a | n/a | - / 60 / - of 60 |" in text
    assert "- stereo seed 4 static: died of signal SIGSEGV" in text


def test_a_small_sweep_runs_every_condition(tmp_path, data):
    """One seed of a small RGB-D room (20 frames, 320x240), the four conditions run as child processes."""
    opts = SeedsOptions(out=str(tmp_path / "out"), seeds=(7,), sensors=("rgbd",), jobs=2, frames=20,
                        width=320, height=240, fx=262.5, tracker={"reloc.min_inliers": 45})
    results = run_seeds(opts, progress=lambda m: None)
    runs = {r["condition"]: r for r in results["records"]}
    assert set(runs) == {"static", "full", "masks", "off"}
    for condition, r in runs.items():
        assert not r.get("error"), (condition, r.get("error"))
        assert r["tracked_frames"] == r["frames"] == 20, condition
        spec = json.loads((tmp_path / "out" / "runs" / "rgbd" / "s7" / condition / "spec.json").read_text())
        assert spec["synchronous_mapping"] is True and spec["tracker"] == {"reloc.min_inliers": 45}
        # Two runs at a time: each one's synchronous BAs take its share of the cores.
        share = max(1, (os.cpu_count() or 1) // 2)
        assert spec["mapping"] == {"ba_threads_synchronous": share} and spec["loop"] == {"threads_synchronous": share}
        assert ("labels" in spec) == (condition == "full") and ("masks" in spec) == (condition == "masks")
        assert ("_m0_" in spec["path"]) == (condition == "static")
    # Measured on this small room (synchronous, so every run repeats it): static 5.3 mm, full 8.9 mm
    # (1.68x), masks 7.9 mm (1.48x), off 0.18 m (34x): the movers' harm is real and both remedies remove
    # most of it. The 60-frame 640x480 rooms the suite renders by default do better (seeds.md).
    static = runs["static"]["ate_rmse"]
    assert static < 0.01
    assert runs["full"]["ate_rmse"] < 2.5 * static and runs["masks"]["ate_rmse"] < 2.5 * static
    assert runs["off"]["ate_rmse"] > 10 * static
    saved = json.loads((tmp_path / "out" / "seeds.json").read_text())
    assert saved["finished"] and {r["condition"] for r in saved["summary"]} == {"full", "masks", "off"}
    text = (tmp_path / "out" / "seeds.md").read_text()
    assert "## rgbd" in text and f"{runs['off']['ate_rmse'] * 1000:.2f}" in text


def test_a_paced_sweep_maps_asynchronously(tmp_path, data):
    """--realtime: each run as a camera delivers it, local mapping in its own thread."""
    opts = SeedsOptions(out=str(tmp_path / "out"), seeds=(7,), sensors=("rgbd",), conditions=("static", "full"),
                        frames=20, width=320, height=240, fx=262.5, realtime=4.0)
    results = run_seeds(opts, progress=lambda m: None)
    runs = {r["condition"]: r for r in results["records"]}
    assert set(runs) == {"static", "full"}
    for condition, r in runs.items():
        assert not r.get("error"), (condition, r.get("error"))
        assert r["tracked_frames"] == r["frames"] == 20, condition
        run = tmp_path / "out" / "runs" / "rgbd" / "s7" / condition
        spec = json.loads((run / "spec.json").read_text())
        assert spec["synchronous_mapping"] is False and spec["realtime"] == 4.0
        assert "mapping" not in spec  # one run at a time: no share of the cores to set
        stats = json.loads((run / "stats.json").read_text())
        assert stats["synchronous_mapping"] is False and stats["realtime"]["rate"] == 4.0
        assert stats["realtime"]["frames"] == 20
    assert results["options"]["realtime"] == 4.0
    text = (tmp_path / "out" / "seeds.md").read_text()
    assert "asynchronous mapping with the frames delivered at 4x the recording's rate" in text


def test_cli_refuses_bad_seed_options_before_running(tmp_path, capsys):
    from dynaorb.cli.main import main

    out = tmp_path / "out"
    for extra, says in [(["--seeds", "0"], "one seed S alone: S-S"), (["--sensors", "rgbd,lidar"], "lidar"),
                        (["--conditions", "full,off"], "include static"), (["--jobs", "0"], "jobs"),
                        (["--realtime", "--jobs", "2"], "jobs must be 1 with realtime"),
                        (["--realtime", "-1"], "expected a positive number")]:
        assert main(["bench", "--suite", "seeds", "--out", str(out), *extra]) == 2, extra
        assert says in capsys.readouterr().err
    assert not out.exists()
    # The quick / full suites refuse a rate that is not a finite positive number before any run.
    for rate in ("-1", "nan", "inf"):
        assert main(["bench", "--suite", "quick", "--realtime", rate, "--out", str(out)]) == 2, rate
        assert "expected a positive number" in capsys.readouterr().err
    assert not out.exists()
    # --only / --presets: clips and presets of the quick / full / long suites, refused before any run.
    assert main(["bench", "--suite", "seeds", "--only", "synth/rgbd_m3", "--out", str(out)]) == 2
    assert "--sensors, --conditions and --preset" in capsys.readouterr().err
    assert main(["bench", "--suite", "quick", "--only", "synth/mono_m3", "--out", str(out)]) == 2
    assert "suite quick has no sequence 'synth/mono_m3' (it has: " in capsys.readouterr().err
    assert main(["bench", "--suite", "quick", "--only", "synth/rgbd_m3", "--presets", "dm,nope", "--out", str(out)]) == 2
    assert "preset(s) nope" in capsys.readouterr().err
    assert not out.exists()


def test_peer_ratios_are_ours_over_orbslam3_seed_by_seed():
    static = {0: 0.003, 1: 0.004, 2: 0.002}
    peer_static = {0: 0.0025, 1: 0.005, 2: 0.002}             # ours / theirs 1.2, 0.8, 1.0
    full = {0: 0.0033, 1: 0.0044, 2: 0.004}
    peer_movers = {0: 0.011, 1: 0.43, 2: None}                # 0.3, 0.0102, no ATE (lost)
    records = [_record("stereo", s, "static", a) for s, a in static.items()]
    records += [_record("stereo", s, "peer_static", a) for s, a in peer_static.items()]
    records += [_record("stereo", s, "full", a) for s, a in full.items()]
    records += [_record("stereo", s, "peer_movers", a) for s, a in peer_movers.items()]
    records.append(_record("stereo", 0, "full_static", 0.005))  # the filter on the room without movers: 2.0
    results = {"options": {"seeds": [0, 1, 2], "frames": 60, "width": 640, "height": 480, "sensors": ["stereo"]},
               "conditions": {"static": {}, "full": {}, "peer_static": {}, "peer_movers": {}, "full_static": {}},
               "targets": {"full": ["<=", 1.2]}, "records": records, "started": "t0", "finished": "t1"}
    # The peer's runs are no condition of ours: only full / static is a ratio to static.
    assert {r["condition"] for r in summarize(results)} == {"full", "full_static"}
    rows = {r["condition"]: r for r in seeds_peer.summarize(results, ("rgbd", "stereo", "mono"), (0, 1, 2))}
    assert rows["static"]["median"] == pytest.approx(1.0) and rows["static"]["test_seeds_median"] == pytest.approx(1.0)
    assert rows["static"]["no_worse"] == 2 and rows["static"]["peer"] == "peer_static"
    assert rows["full"]["seeds"] == 2 and rows["full"]["test_seeds_median"] is None
    assert rows["full"]["median"] == pytest.approx((0.3 + 0.0044 / 0.43) / 2) and rows["full"]["no_worse"] == 2
    assert rows["full_static"]["peer"] == "peer_static" and rows["full_static"]["median"] == pytest.approx(2.0)
    text = render(results)
    assert "| stereo | static | peer_static | 3 | 1.00 | 1.00 | 2/3 |" in text
    assert "| 0 | 3.00 | 3.30 | 2.50 | 11.00 | 5.00 | 1.10 | 1.67 | 60 / 60 / 60 / 60 / 60 of 60 |" in text


def test_paced_peer_sweeps_compare_speed_seed_by_seed(tmp_path):
    """--realtime with the peer: ms ours / ORB-SLAM3's per seed, whole clip and over the frames both tracked."""
    def run(seed, condition, ms, per_frame):
        out = tmp_path / "runs" / f"s{seed}" / condition
        out.mkdir(parents=True)
        peer = condition.startswith("peer")
        key = "ms" if peer else "track_call_ms"
        frames = [{"stamp": 0.05 * i, "state": "OK" if ok else "NOT_INITIALIZED", key: t}
                  for i, (ok, t) in enumerate(per_frame)]
        (out / ("peer.json" if peer else "stats.json")).write_text(json.dumps({"per_frame": frames}))
        return {**_record("mono", seed, condition, 0.004), "out": str(out), "track_call_ms_median": ms}

    # Seed 0: ours tracks from frame 2, the peer from frame 6 (its first frames cost 25 ms): over the whole
    # clip ours 10 / 9 ms, over frames 6-19 both 8 ms against 9 ms.
    ours0 = [(i >= 2, 13.0 if i < 6 else 8.0) for i in range(20)]
    theirs0 = [(i >= 6, 25.0 if i < 6 else 9.0) for i in range(20)]
    ours1 = [(True, 6.0)] * 20
    theirs1 = [(True, 12.0)] * 20
    records = [run(0, "full", 10.0, ours0), run(0, "peer_movers", 9.0, theirs0),
               run(1, "full", 6.0, ours1), run(1, "peer_movers", 12.0, theirs1),
               _record("mono", 0, "static", 0.004), _record("mono", 1, "static", 0.004)]
    results = {"options": {"seeds": [0, 1], "frames": 20, "width": 640, "height": 480, "sensors": ["mono"],
                           "realtime": 1.0},
               "conditions": {"static": {}, "full": {}, "peer_movers": {}}, "targets": {"full": ["<=", 1.2]},
               "records": records, "started": "t0", "finished": "t1"}
    by = seeds_peer.speed_ratios(results)
    assert by[("mono", "full")][0] == pytest.approx((10.0 / 9.0, 8.0 / 9.0))
    assert by[("mono", "full")][1] == pytest.approx((0.5, 0.5))
    row, = seeds_peer.speed_summary(results, ("rgbd", "stereo", "mono"), (0, 1, 2))
    assert row["median"] == pytest.approx((10.0 / 9.0 + 0.5) / 2) and row["no_slower"] == 1 and row["compared"] == 2
    assert row["common_median"] == pytest.approx((8.0 / 9.0 + 0.5) / 2) and row["test_seeds_median"] is None
    text = render(results)
    assert "## Speed against ORB-SLAM3" in text and "| mono | full | peer_movers | 2 | 0.81 | - | 1/2 | 0.69 (2 seeds) |" in text
    assert "| 0 | 1.11 / 0.89 |" in text and "| 1 | 0.50 / 0.50 |" in text
    # Seed 2 without its per-frame file (the ratio of the medians still), seed 3's peer run failed: no pair.
    missing = {**_record("mono", 2, "full", 0.004), "out": str(tmp_path / "runs" / "gone"), "track_call_ms_median": 9.0}
    records += [missing, run(2, "peer_movers", 10.0, theirs1), run(3, "full", 6.0, ours1),
                _record("mono", 3, "peer_movers", error="ORB-SLAM3 died of signal SIGSEGV")]
    by = seeds_peer.speed_ratios(results)
    assert by[("mono", "full")][2] == (pytest.approx(0.9), None) and 3 not in by[("mono", "full")]
    row, = seeds_peer.speed_summary(results, ("rgbd", "stereo", "mono"), (0, 1, 2))
    assert row["seeds"] == 3 and row["compared"] == 3 and row["common_seeds"] == 2
    assert "| 2 | 0.90 / - |" in render(results)
    # Synchronous: our track call waits for mapping, no speed ratio.
    results["options"]["realtime"] = 0.0
    text = render(results)
    assert "## Speed against ORB-SLAM3" not in text and "not compared in a synchronous sweep" in text


def test_peer_conditions_run_orbslam3_on_the_same_rooms(tmp_path, monkeypatch, data):
    """The peer's runs get the room of their condition and land in the records; without pyorbslam3 they are
    recorded as failed and the sweep goes on."""
    from dynaorb.bench import suite_runner

    calls = []

    def fake_peer_record(seq, out, python, vocabulary, timeout_s, resume=False, realtime=0.0, fields=None):
        calls.append((seq.path, out, python, fields))
        return {"system": "orbslam3", "sensor": seq.sensor, **fields, "ate_rmse": 0.004, "frames": 20,
                "tracked_frames": 19, "stats": {"frames": 20, "tracked_frames": 19}}

    monkeypatch.setattr(suite_runner, "peer_record", fake_peer_record)
    monkeypatch.setattr(seeds_peer, "setup", lambda conditions, venv, vocabulary, progress:
                        {"python": "/peer/python", "vocabulary": "voc.txt", "status": {"status": "run"}})
    opts = SeedsOptions(out=str(tmp_path / "out"), seeds=(7,), sensors=("rgbd",), jobs=1, frames=20, width=320,
                        height=240, fx=262.5, conditions=("static", "peer_static", "peer_movers"))
    results = run_seeds(opts, progress=lambda m: None)
    assert [("_m0_" in path, fields["condition"]) for path, _, python, fields in calls] == \
        [(True, "peer_static"), (False, "peer_movers")]
    assert all(python == "/peer/python" and out.name == fields["condition"] for _, out, python, fields in calls)
    runs = {r["condition"]: r for r in results["records"]}
    assert runs["peer_movers"]["tracked_frames"] == 19 and results["peer"] == {"status": "run"}
    assert results["conditions"]["peer_movers"] == {"movers": 3, "system": "orbslam3"}
    assert "## Against ORB-SLAM3" in (tmp_path / "out" / "seeds.md").read_text()

    calls.clear()
    monkeypatch.setattr(seeds_peer, "setup", lambda conditions, venv, vocabulary, progress:
                        {"python": None, "status": {"status": "not run: no libGL"}})
    opts.out, opts.resume = str(tmp_path / "out2"), False
    results = run_seeds(opts, progress=lambda m: None)
    runs = {r["condition"]: r for r in results["records"]}
    assert not calls and runs["static"].get("ate_rmse")
    assert runs["peer_static"]["error"] == "ORB-SLAM3 not run: no libGL"
    assert "- rgbd seed 7 peer_static: ORB-SLAM3 not run: no libGL" in (tmp_path / "out2" / "seeds.md").read_text()
