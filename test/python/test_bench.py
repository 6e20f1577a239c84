"""`dynaorb bench --suite quick|full`: suites, child runs, the ORB-SLAM3 peer's inputs, report, README section."""
from __future__ import annotations

import json
import pathlib

import pytest

from dynaorb.bench import readme, report
from dynaorb.bench.suites import Suite, build_suite, cases_for, synth_sequence
from dynaorb.peer import orbslam3


@pytest.fixture(scope="module")
def tiny_suite(tmp_path_factory, data):
    """One small synthetic RGB-D case with movers (20 frames, 320x240), off and the dm preset, run once."""
    from dynaorb.bench.suite_runner import BenchOptions, run_suite

    root = tmp_path_factory.mktemp("bench")
    # fx: the synthetic camera's field of view at 320x240 (as conftest's synth_rgbd)
    seq = synth_sequence("rgbd", 3, root / "synth", frames=20, seed=7, width=320, height=240, fx=262.5)
    cases, not_run = cases_for([seq], presets=("dm", "li"))
    suite = Suite("test", cases, [seq], not_run)
    results = run_suite(BenchOptions(out=str(root / "out"), runs=1, peer=False), suite=suite, progress=lambda m: None)
    return root / "out", results


def test_suite_runs_and_reports(tiny_suite):
    out, results = tiny_suite
    saved = json.loads((out / "results.json").read_text())
    assert saved["suite"] == "test" and saved["peer"]["status"].startswith("skipped")
    # li has no stage for RGB-D: listed as not run, with the reason.
    assert any(n["what"].endswith(":li") and "rgbd" in n["reason"] for n in saved["not_run"])
    records = {r["preset"]: r for r in saved["records"]}
    assert set(records) == {"off", "dm"}
    for preset, r in records.items():
        assert not r.get("error"), r.get("error")
        assert r["ate_rmse"] is not None and r["ate_rmse"] > 0.0, (preset, r.get("ate_reason"))
        assert r["tracked_fraction"] > 0.9
        assert r["peak_rss_mb"] > 50  # the child's own resident memory, numpy and the core loaded
        assert r["track_call_ms_median"] > 0 and r["frame_ms_median"] > 0
        # The final map's keyframes, and how many it was given, the ones culled as redundant included.
        assert r["keyframes"] >= 2 and r["keyframes_made"] >= r["keyframes"]
        assert r["keyframes_made"] == r["keyframes"] + r["stats"]["map"]["keyframes_culled"]
    # A 20-frame synthetic RGB-D clip (0.5 m path) with movers, mapping asynchronous. dm: centimetre-level
    # (measured 0.008-0.010 m over 6 runs). off is dragged by the movers (0.20-0.27 m over 11 runs, CI
    # included): bounded by the path's size, and far worse than dm, which shows the problem is real.
    assert records["dm"]["ate_rmse"] < 0.03, records["dm"]["ate_rmse"]
    assert records["off"]["ate_rmse"] < 1.0 and records["off"]["ate_rmse"] > 5 * records["dm"]["ate_rmse"]
    assert records["dm"]["labels"] and records["dm"]["dynamic_filter"]["stages"] == ["semantic", "dm"]
    assert records["off"]["labels"] is None
    # The build measured: the core fingerprint every run was started with, and the checkout's commit.
    from dynaorb.bench.build_info import core_fingerprint

    assert saved["build"]["core"] == core_fingerprint() and len(saved["build"]["core"]) == 16
    for r in saved["records"]:
        assert json.loads((pathlib.Path(r["out"]) / "spec.json").read_text())["core"] == core_fingerprint()
    text = (out / "report.md").read_text()
    assert f"core fingerprint {core_fingerprint()}" in text
    assert "## Every case" in text and "## Dynamic presets against off" in text and "li" in text
    assert f"{records['off']['ate_rmse']:.4f}" in text
    assert (out / "plots" / "stages.png").is_file()
    assert any(p.name.endswith("_error.png") for p in (out / "plots").iterdir())


def test_crashed_run_is_recorded(tmp_path):
    from dynaorb.bench.process import run_child

    import sys

    child = run_child([sys.executable, "-c", "import os; os.abort()"], tmp_path / "log", 30)
    assert not child.ok and "SIGABRT" in child.failure()
    child = run_child([sys.executable, "-c", "import time; time.sleep(30)"], tmp_path / "log2", 0.5)
    assert child.timed_out and child.returncode is None
    # Peak memory is the child's own: 200 MB touched shows, the parent's size does not.
    big = run_child([sys.executable, "-c", "b = bytearray(200 << 20); import time; time.sleep(0.3)"],
                    tmp_path / "log3", 30)
    small = run_child([sys.executable, "-c", "import time; time.sleep(0.3)"], tmp_path / "log4", 30)
    assert big.ok and big.peak_rss_mb > 200 and small.peak_rss_mb < 40


def test_a_run_on_another_core_build_refuses_to_start(tmp_path):
    """A rebuild while a benchmark runs: the child loads a core whose fingerprint is not the one the benchmark
    started with, and stops before running, naming both, instead of mixing two builds in one table."""
    from dynaorb.bench.suite_runner import run_spec

    spec = {"kind": "tum", "path": str(tmp_path / "nowhere"), "out": str(tmp_path / "run"),
            "result": str(tmp_path / "run" / "result.json"), "core": "0" * 16}
    child = run_spec(tmp_path / "run", spec, 120)
    assert child.returncode == 3, child.log_tail()
    assert "rebuilt while the benchmark ran" in child.log_tail() and "fingerprint 0000000000000000" in child.log_tail()
    assert not (tmp_path / "run" / "result.json").exists()


def test_report_names_the_build(tmp_path):
    assert report.build_text(None) == "build not recorded"
    assert report.build_text({"commit": "0123456789abcdef", "dirty": True, "core": "f" * 16}) == (
        "dynaorb at commit 0123456789 with uncommitted changes, core fingerprint " + "f" * 16)
    assert report.build_text({"commit": None, "dirty": None, "core": "a" * 16}).startswith("dynaorb at commit unknown")


def test_suites_cover_sensors_and_list_what_is_not_run(tmp_path, data):
    quick = build_suite("quick", data, tmp_path)
    full = build_suite("full", data, tmp_path)
    keys = {c.key for c in quick.cases}
    assert "euroc/V1_01_easy_micro:stereo:off" in keys and "kitti/06:stereo:li" in keys
    assert "synth/rgbd_m3:rgbd:ddl" in keys and "synth/stereo_m3:stereo:li" in keys
    assert not any(k.endswith("rgbd:li") for k in keys)  # li is stereo only
    full_keys = {c.key for c in full.cases}
    assert {"euroc/MH_05_difficult_head:mono:off", "synth/mono_m0:mono:off", "synth/rgbd_m0:rgbd:off"} <= full_keys
    for suite in (quick, full):
        assert any("fragment" in n["what"] and "not a sequence" in n["reason"] for n in suite.not_run)
    # A sensor the sequence has no data for is listed as not run, with the reader's reason, not run to fail.
    mh05 = data / "euroc" / "MH_05_difficult_head" / "mav0"
    if not (mh05 / "cam1").is_dir():
        assert "euroc/MH_05_difficult_head:stereo:off" not in full_keys
        assert any(n["what"] == "euroc/MH_05_difficult_head:stereo" and "no data for sensor 'stereo'" in n["reason"]
                   for n in full.not_run), full.not_run


def test_the_long_suite_runs_one_render_as_stereo_and_as_monocular(tmp_path, data):
    from dynaorb.bench.suites import LONG_FRAMES

    long = build_suite("long", data, tmp_path)
    assert {c.key for c in long.cases} == {f"synth/long_{LONG_FRAMES}:{s}:{p}" for s in ("stereo", "mono")
                                           for p in ("off", "full")}
    stereo, mono = long.sequences
    assert stereo.path == mono.path and stereo.synthetic == mono.synthetic  # rendered once
    assert stereo.synthetic["frames"] == LONG_FRAMES and stereo.synthetic["movers"] == 0
    with pytest.raises(ValueError, match="unknown suite"):
        build_suite("longer", data, tmp_path)


def test_resume_takes_finished_runs_from_their_folders(tiny_suite):
    from dynaorb.bench.suite_runner import BenchOptions, run_suite

    out, results = tiny_suite
    cases, not_run = cases_for([synth_sequence("rgbd", 3, out.parent / "synth", frames=20, seed=7, width=320,
                                               height=240, fx=262.5)], presets=("dm", "li"))
    seen = []
    again = run_suite(BenchOptions(out=str(out), runs=1, peer=False, resume=True),
                      suite=Suite("test", cases, [c.sequence for c in cases[:1]], not_run), progress=seen.append)
    # The same records (a run again would have its own wall time and memory), read from each run's record.json.
    assert again["records"] == results["records"], "resume ran a case again"
    assert again["finished"] and json.loads((out / "results.json").read_text())["finished"] == again["finished"]
    # A corrupt record is not trusted: that run is made again, the others are still reused.
    off = pathlib.Path(results["records"][0]["out"])
    (off / "record.json").write_text("{not json")
    third = run_suite(BenchOptions(out=str(out), runs=1, peer=False, resume=True),
                      suite=Suite("test", cases, [c.sequence for c in cases[:1]], not_run), progress=seen.append)
    assert third["records"][1:] == results["records"][1:]
    assert third["records"][0]["process_wall_s"] != results["records"][0]["process_wall_s"]
    assert json.loads((off / "record.json").read_text()) == third["records"][0]


def test_part_of_a_suite_by_sequence_sensor_and_preset():
    from dynaorb.bench.suites import Case, SelectionError, Sequence, select

    a_stereo, a_mono, b = (Sequence(f"synth/{n}", "kitti", f"/nowhere/{n}", sensor)
                           for n, sensor in (("a", "stereo"), ("a", "mono"), ("b", "stereo")))
    cases = [Case(seq, p) for seq in (a_stereo, a_mono, b) for p in ("off", "dm", "full")]
    not_run = [{"what": "synth/a:mono:li", "reason": "li is stereo only"},
               {"what": "euroc/X", "reason": "/data/euroc/X not found"},
               {"what": "synth/b:rgbd", "reason": "no data for sensor 'rgbd'"}]
    suite = Suite("full", cases, [a_stereo, a_mono, b], not_run)
    # By name: every sensor; by NAME:SENSOR: that one. What is said about the others goes with them.
    part = select(suite, ("synth/a",))
    assert part.sequences == [a_stereo, a_mono] and len(part.cases) == 6 and part.not_run == not_run[:1]
    part = select(suite, ("synth/a:mono", "synth/b"), ("full",))
    assert [c.key for c in part.cases] == ["synth/a:mono:off", "synth/a:mono:full", "synth/b:stereo:off",
                                           "synth/b:stereo:full"]
    assert part.not_run == not_run[:1] + not_run[2:]  # asked for by name: its sensor without data is said too
    assert select(suite, None, ("dm",)).sequences == suite.sequences  # presets alone: every clip, off and dm
    with pytest.raises(SelectionError, match=r"no sequence 'synth/c' \(it has: synth/a:stereo, synth/a:mono"):
        select(suite, ("synth/c",))
    with pytest.raises(SelectionError, match="not found"):  # a clip the suite lists as not run says why
        select(suite, ("euroc/X",))
    with pytest.raises(SelectionError, match=r"preset\(s\) li \(they run: dm, full, off\)"):
        select(suite, ("synth/a",), ("li",))


def test_the_peer_runs_beside_ours_sequence_by_sequence(tmp_path, monkeypatch):
    """Run r of every case of a sequence, then the peer's run r on it: both systems' runs on one sequence are
    made minutes apart, not a whole suite apart."""
    from dynaorb.bench import suite_runner
    from dynaorb.bench.suites import Case, Sequence

    made = []

    def fake(system, case, seq, run):
        made.append((system, case, run))
        return {"system": system, "case": case, "sequence": seq.name, "sensor": seq.sensor, "preset": "off",
                "run": run, "error": "not run (test)"}

    monkeypatch.setattr(suite_runner, "_ours_record", lambda case, run, out, opts:
                        fake("dynaorb", case.key, case.sequence, run))
    monkeypatch.setattr(suite_runner, "_peer_record", lambda seq, run, *a:
                        fake("orbslam3", f"{seq.key}:orbslam3", seq, run))
    monkeypatch.setattr(suite_runner, "_peer_setup", lambda opts, progress:
                        {"python": pathlib.Path("/peer/python"), "vocabulary": "voc.txt", "status": {"status": "run"}})
    monkeypatch.setattr(report, "write", lambda results, out: None)
    a, b = (Sequence(f"synth/{n}", "kitti", f"/nowhere/{n}", "stereo") for n in ("a", "b"))
    cases = [Case(a, "off"), Case(a, "dm"), Case(b, "off")]
    results = suite_runner.run_suite(suite_runner.BenchOptions(out=str(tmp_path / "out"), runs=2),
                                     suite=Suite("order", cases, [a, b], []), progress=lambda m: None)
    assert made == [("dynaorb", "synth/a:stereo:off", 0), ("dynaorb", "synth/a:stereo:dm", 0),
                    ("orbslam3", "synth/a:stereo:orbslam3", 0),
                    ("dynaorb", "synth/a:stereo:off", 1), ("dynaorb", "synth/a:stereo:dm", 1),
                    ("orbslam3", "synth/a:stereo:orbslam3", 1),
                    ("dynaorb", "synth/b:stereo:off", 0), ("orbslam3", "synth/b:stereo:orbslam3", 0),
                    ("dynaorb", "synth/b:stereo:off", 1), ("orbslam3", "synth/b:stereo:orbslam3", 1)]
    assert [(r["system"], r["case"], r["run"]) for r in results["records"]] == made
    assert results["peer"] == {"status": "run"} and results["finished"]
    # One clip again with more runs: its `off` beside the preset asked for, and the peer on it.
    made.clear()
    results = suite_runner.run_suite(suite_runner.BenchOptions(out=str(tmp_path / "part"), runs=3, only=("synth/a",),
                                                               presets=("dm",)),
                                     suite=Suite("order", cases + [Case(a, "full")], [a, b], []),
                                     progress=lambda m: None)
    assert made == [(system, case, run) for run in range(3) for system, case in
                    (("dynaorb", "synth/a:stereo:off"), ("dynaorb", "synth/a:stereo:dm"),
                     ("orbslam3", "synth/a:stereo:orbslam3"))]
    assert results["only"] == ["synth/a"] and results["presets"] == ["dm"]
    assert report.selection_text(results) == ", part of it (only synth/a; presets off, dm)"
    assert report.selection_args(results) == " --only synth/a --presets dm"


def test_peer_failure_is_recorded_and_the_bench_goes_on(tmp_path, data):
    from dynaorb.bench.suite_runner import _peer_record
    from dynaorb.bench.suites import Sequence

    mh05 = data / "euroc" / "MH_05_difficult_head"
    if (mh05 / "mav0" / "cam1").is_dir():
        pytest.skip("MH_05 here has a right camera")
    # The sequence cannot be read for stereo: each run gets the error, nothing is raised.
    seq = Sequence("euroc/MH_05_difficult_head", "euroc", str(mh05), "stereo")
    records = [_peer_record(seq, run, tmp_path, pathlib.Path("/nonexistent/python"), tmp_path / "voc.txt", 5.0)
               for run in range(2)]
    assert len(records) == 2 and all("no data for sensor 'stereo'" in r["error"] for r in records)
    assert all((tmp_path / "runs" / "euroc_MH_05_difficult_head_stereo_orbslam3" / str(i) / "record.json").is_file()
               for i in range(2))


def test_peer_trajectory_drops_a_repeated_line(tmp_path):
    """ORB-SLAM3 sometimes saves one frame twice (same stamp, same pose; seen on the synthetic monocular room
    with movers): the TUM file keeps the first, so its stamps increase and evo reads it."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("orbslam3_worker", orbslam3.WORKER)
    worker = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(worker)  # stdlib only: pyorbslam3 is imported by its main(), not here
    pose = "0.1 0.2 0.3 0 0 0 1"
    (tmp_path / "t.euroc").write_text(f"1050000000.000000 {pose}\n1100000000.000000 {pose}\n"
                                      f"1100000000.000000 {pose}\n1200000000.000000 {pose}\n")
    assert worker._euroc_to_tum(str(tmp_path / "t.euroc"), str(tmp_path / "t.tum")) == (3, 1)
    from dynaorb.evaluation import load_trajectory

    assert list(load_trajectory(tmp_path / "t.tum").timestamps) == [1.05, 1.1, 1.2]
    assert worker._euroc_to_tum(str(tmp_path / "missing"), str(tmp_path / "e.tum")) == (0, 0)


def test_peer_settings_and_manifest(tmp_path, data):
    # EuRoC stereo: raw cameras, T_c1_c2 from our rectification; ORB settings as ours.
    case = orbslam3.PeerCase("euroc", str(data / "euroc" / "V1_01_easy_micro"), "stereo", tmp_path / "euroc")
    manifest = json.loads(orbslam3.prepare(case, tmp_path / "ORBvoc.txt").read_text())
    import cv2
    import numpy as np

    fs = cv2.FileStorage(manifest["settings"], cv2.FILE_STORAGE_READ)
    ours = orbslam3.read_settings(case.out / "ours.yaml")
    assert fs.getNode("File.version").string() == "1.0" and fs.getNode("Camera.type").string() == "PinHole"
    assert fs.getNode("ORBextractor.nFeatures").real() == ours["ORBextractor.nFeatures"]
    assert fs.getNode("Camera1.fx").real() == pytest.approx(ours["LEFT"]["K"][0])
    assert fs.getNode("Camera2.k1").real() == pytest.approx(ours["RIGHT"]["D"][0])
    T = fs.getNode("Stereo.T_c1_c2").mat()
    # EuRoC's cam0-cam1 baseline (sensor.yaml): 0.110 m, mostly along x.
    assert np.linalg.norm(T[:3, 3]) == pytest.approx(0.1101, abs=1e-3) and T[0, 3] > 0.109
    assert fs.getNode("Stereo.ThDepth").isReal()  # ORB-SLAM3 refuses an integer here
    frames = manifest["frames"]
    assert len(frames) == 95 and all(pathlib.Path(f["right"]).is_file() for f in frames)
    assert "/cam1/" in frames[0]["right"] and pathlib.Path(frames[0]["right"]).name == pathlib.Path(frames[0]["image"]).name

    # Rectified stereo (KITTI): identical cameras, pure x baseline.
    kitti = orbslam3.orbslam3_settings(orbslam3.read_settings(_saved(data, "kitti", "kitti/sequences/06", "stereo",
                                                                     tmp_path)), "stereo")
    assert "Camera2.fx: 707.0912" in kitti and "Camera1.k1" not in kitti
    assert "data: [1.0, 0.0, 0.0, 0.537" in kitti


def test_peer_rgbd_manifest(tmp_path, synth_rgbd):
    case = orbslam3.PeerCase("tum", str(synth_rgbd), "rgbd", tmp_path / "rgbd")
    manifest = json.loads(orbslam3.prepare(case, tmp_path / "ORBvoc.txt").read_text())
    text = pathlib.Path(manifest["settings"]).read_text()
    assert "RGBD.DepthMapFactor: 5000.0" in text and "Stereo.b: 0.08" in text
    assert len(manifest["frames"]) == 8
    assert all(pathlib.Path(f["depth"]).is_file() and "depth" in f["depth"] for f in manifest["frames"])
    assert "realtime" not in manifest  # as fast as the track calls go
    paced = orbslam3.PeerCase("tum", str(synth_rgbd), "rgbd", tmp_path / "paced", realtime=2.0)
    assert json.loads(orbslam3.prepare(paced, tmp_path / "ORBvoc.txt").read_text())["realtime"] == 2.0


def test_realtime_paces_ours_and_the_peer_alike(tmp_path, monkeypatch):
    """--realtime RATE reaches our runs' spec (RunOptions.realtime) and the peer's case; without it neither
    is paced and the specs stay as before (an earlier bench's runs can be resumed)."""
    from dynaorb.bench import suite_runner
    from dynaorb.bench.process import ChildResult
    from dynaorb.bench.suites import Case, Sequence
    from dynaorb.peer import orbslam3 as peer

    specs, cases = [], []
    monkeypatch.setattr(suite_runner, "run_spec", lambda out, spec, timeout: specs.append(spec) or
                        ChildResult(returncode=1, peak_rss_mb=None, wall_s=0.0, timed_out=False,
                                    log=str(out / "run.log")))
    monkeypatch.setattr(peer, "run", lambda case, python, vocabulary, timeout_s: cases.append(case) or
                        {"error": "not run (test)"})
    seq = Sequence("synth/a", "kitti", "/nowhere/a", "stereo")
    for rate in (0.0, 2.0):
        opts = suite_runner.BenchOptions(out=str(tmp_path), realtime=rate)
        suite_runner._ours_record(Case(seq, "off"), 0, tmp_path / f"ours{rate}", opts)
        suite_runner._peer_record(seq, 0, tmp_path / f"peer{rate}", "python", "voc.txt", 10, realtime=rate)
    assert "realtime" not in specs[0] and specs[1]["realtime"] == 2.0
    assert [c.realtime for c in cases] == [0.0, 2.0]
    assert "2x the recording's rate" in suite_runner.mapping_mode(2.0)
    assert "as fast as" in suite_runner.mapping_mode(0.0)


def _saved(data, kind, rel, sensor, tmp_path) -> pathlib.Path:
    from dynaorb import core

    path = tmp_path / f"{kind}.yaml"
    core().open_dataset(kind, str(data / rel), sensor).default_settings().save(str(path))
    return path


def _record(case, system, preset, ate, ms, run=0):
    return {"system": system, "case": case, "sequence": "s", "sensor": "stereo", "preset": preset, "run": run,
            "out": "/nonexistent", "trajectory": "/nonexistent", "ate_rmse": ate, "ate_reason": None,
            "rpe_trans_rmse": 0.01, "rpe_rot_rmse": 0.1, "tracked_fraction": 1.0, "frame_ms_median": ms,
            "track_call_ms_median": ms, "fps": 10.0, "peak_rss_mb": 200.0,
            "stage_ms_median": {"extract": ms / 2, "tracking": ms / 2, "frame_total": ms}}


def test_report_renders_from_results(tmp_path):
    records = [_record("s:stereo:off", "dynaorb", "off", 0.02, 40.0), _record("s:stereo:off", "dynaorb", "off", 0.04, 50.0, 1),
               _record("s:stereo:orbslam3", "orbslam3", "off", 0.01, 60.0),
               {**_record("s:stereo:li", "dynaorb", "li", None, 1.0), "error": "died of signal SIGSEGV\n..."}]
    results = {"suite": "quick", "runs": 2, "records": records, "not_run": [{"what": "x", "reason": "why"}],
               "peer": {"status": "run"}, "machine": {"cpus": 2}}
    (tmp_path / "results.json").write_text(json.dumps(results))
    path = report.write(report.load(tmp_path), tmp_path)
    text = path.read_text()
    # dynaorb's ATE median 0.03 over two runs (0.02-0.04), ORB-SLAM3 0.01: ratio 3.00; ms 45 / 60 = 0.75.
    assert "| s | stereo | 0.0300 | 0.0100 | 3.00 | 45.0 | 60.0 | 0.75 | 0.67 |" in text  # run 1 has no peer run
    assert "0.0300 (0.0200-0.0400)" in text
    assert "s:stereo:li: died of signal SIGSEGV" in text and "- x: why" in text
    # Keyframes in the final map, medians over the runs; ours with how many the map was given in all.
    records[0].update(keyframes=10, keyframes_made=30)
    records[1].update(keyframes=14, keyframes_made=40)
    records[2].update(keyframes=19, keyframes_made=None)
    (tmp_path / "results.json").write_text(json.dumps(results))
    text = report.write(report.load(tmp_path), tmp_path).read_text()
    assert "| 200 | 12 (35) |" in text and "| 200 | 19 |" in text
    # Tracked on far fewer frames than the peer: the ATE ratio is flagged as not comparable.
    records[0]["tracked_fraction"] = records[1]["tracked_fraction"] = 0.1
    (tmp_path / "results.json").write_text(json.dumps(results))
    text = report.write(report.load(tmp_path), tmp_path).read_text()
    assert "| 3.00 (over 10 % vs 100 % of the frames: not comparable) |" in text


def test_pair_table_counts_the_labels_time_of_the_tracking_thread(tmp_path):
    # `full` with a network: 40 / 50 ms track calls, the labels 5 / 7 ms before them; the medians of the
    # per-frame sums 46 / 58 (not the sum of the medians): the pair compares their median, 52 ms, with the
    # peer's 60 (0.87), not the track calls' 45 (0.75).
    full = [{**_record("s:stereo:full", "dynaorb", "full", 0.02, ms, run), "labels_ms_median": labels,
             "track_call_plus_labels_ms_median": ms + labels + 1}
            for run, (ms, labels) in enumerate(((40.0, 5.0), (50.0, 7.0)))]
    records = full + [_record("s:stereo:off", "dynaorb", "off", 0.02, 40.0),
                      _record("s:stereo:orbslam3", "orbslam3", "off", 0.01, 60.0)]
    rows = report.aggregate(records)
    p = report.pairs(rows, "full")[0]
    assert p["ms_ratio"] == pytest.approx(52.0 / 60.0)
    assert "| 52.0 (45.0 + labels 6.0) | 60.0 | 0.87 |" in "\n".join(report.pair_table([p]))
    # Without a network (no labels' time) the track call alone, as before.
    assert report.pairs(rows, "off")[0]["ms_ratio"] == pytest.approx(40.0 / 60.0)


def test_ms_ratios_pair_each_run_with_the_peer_run_made_beside_it():
    # The machine got faster between the runs: ours 40 -> 20 ms, the peer's 50 -> 25. Run by run ours is
    # 0.80x both times. The ratio of the medians says 1.00 (30 / 30): the peer's third run, beside our
    # failed one, is in its median.
    records = [_record("s:stereo:full", "dynaorb", "full", 0.02, 40.0, 0), _record("s:stereo:full", "dynaorb", "full", 0.02, 20.0, 1),
               _record("s:stereo:orbslam3", "orbslam3", "off", 0.01, 25.0, 1), _record("s:stereo:orbslam3", "orbslam3", "off", 0.01, 50.0, 0),
               {**_record("s:stereo:full", "dynaorb", "full", None, 1.0, 2), "error": "died"},
               _record("s:stereo:orbslam3", "orbslam3", "off", 0.01, 30.0, 2)]
    p = report.pairs(report.aggregate(records), "full", records)[0]
    assert p["ms_ratio_runs"] == pytest.approx([0.8, 0.8])  # in run order; run 2 failed on our side
    assert p["ms_ratio"] == pytest.approx(1.0)
    assert "| 0.80 / 0.80 |" in "\n".join(report.pair_table([p]))
    # The labels' time counts as in the medians; without the records no run-by-run figure.
    records[0] = {**records[0], "track_call_plus_labels_ms_median": 45.0}
    assert report.pairs(report.aggregate(records), "full", records)[0]["ms_ratio_runs"] == pytest.approx([0.9, 0.8])
    assert report.pairs(report.aggregate(records), "full")[0]["ms_ratio_runs"] == []


def _tum(path: pathlib.Path, stamps, xyz) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"{t:.6f} {x:.6f} {y:.6f} {z:.6f} 0 0 0 1\n" for t, (x, y, z) in zip(stamps, xyz)))
    return str(path)


def test_ate_over_the_frames_both_tracked(tmp_path):
    import numpy as np

    from dynaorb.bench import common_frames

    # Ground truth: 30 poses on a helix. Ours tracks all 30 but frames 0-9 are 0.5 m off;
    # the peer tracks frames 10-29 only. Over frames 10-29 ours is 1 cm off, the peer 2 cm
    # (alternating up / down, so no rigid alignment removes it).
    t = 100.0 + 0.05 * np.arange(30)
    a = np.linspace(0, 2, 30)
    gt = np.stack([np.cos(a), np.sin(a), 0.2 * a], axis=1)
    sign = np.where(np.arange(30) % 2 == 0, 1.0, -1.0)[:, None]
    ours = gt + sign * [0, 0, 0.01]
    ours[:10] += [0.5, 0, 0]
    theirs = (gt + sign * [0, 0, 0.02])[10:]
    runs = tmp_path / "runs"
    rec = {"sensor": "stereo", "align": "se3", "run": 0}
    mine = {**rec, "case": "s:stereo:off", "out": str(runs / "ours" / "0"),
            "trajectory": _tum(runs / "ours" / "0" / "trajectory.tum", t, ours)}
    _tum(runs / "ours" / "0" / "groundtruth.tum", t, gt)
    peer = {**rec, "case": "s:stereo:orbslam3", "trajectory": _tum(runs / "peer" / "0" / "trajectory.tum", t[10:], theirs)}
    c = common_frames.compare([mine], [peer])
    assert c["frames"] == 20 and c["pairs"] == 1
    assert c["ours"] == pytest.approx(0.01, abs=0.002) and c["theirs"] == pytest.approx(0.02, abs=0.002)
    assert c["ratio"] == pytest.approx(0.5, abs=0.1)
    # The records moved with their bench folder: found under it by their runs/... part.
    moved = {**mine, "out": "/elsewhere/runs/ours/0", "trajectory": "/elsewhere/runs/ours/0/trajectory.tum"}
    assert common_frames.compare([moved], [peer]) is None
    assert common_frames.compare([moved], [peer], tmp_path)["frames"] == 20
    # Too few frames in common, or a missing trajectory: no figure.
    short = {**peer, "trajectory": _tum(runs / "peer" / "1" / "trajectory.tum", t[25:], theirs[15:])}
    assert common_frames.compare([mine], [short]) is None
    assert common_frames.compare([mine], [{**peer, "trajectory": "/nonexistent"}]) is None
    assert common_frames.compare([{**mine, "align": None}], [peer]) is None  # our run had no ATE
    (runs / "peer" / "2").mkdir()
    (runs / "peer" / "2" / "trajectory.tum").write_text("")  # a run that tracked nothing
    assert common_frames.compare([mine], [{**peer, "trajectory": str(runs / "peer" / "2" / "trajectory.tum")}]) is None
    # In the pair table, beside the full-trajectory ratio (whose 0.5 m frames ours alone tracked).
    rows = [{**_record("s:stereo:off", "dynaorb", "off", 0.3, 40.0), **mine},
            {**_record("s:stereo:orbslam3", "orbslam3", "off", 0.02, 60.0), **peer}]
    ps = report.pairs(report.aggregate(rows), "off", rows)
    c = ps[0]["common"]
    assert c["frames"] == 20 and c["ratio"] == pytest.approx(0.5, abs=0.1)
    cell = f"| {c['ratio']:.2f} ({c['ours']:.4f} / {c['theirs']:.4f} m, 20 frames) |"
    assert "| 15.00 |" in "\n".join(report.pair_table(ps)) and cell in "\n".join(report.pair_table(ps))


def test_ate_over_the_frames_both_tracked_aligned_with_scale(tmp_path):
    import numpy as np

    from dynaorb.bench import common_frames

    # 30 poses on a helix about 2 m long. Ours: the right shape, 1 mm off (alternating up / down),
    # but 1 % too short; the peer: the right length, 2 mm off. SE3 puts ours behind (the length),
    # Sim3 ahead (the shape): 1 / 2 mm.
    t = 100.0 + 0.05 * np.arange(30)
    a = np.linspace(0, 2, 30)
    gt = np.stack([np.cos(a), np.sin(a), 0.2 * a], axis=1)
    sign = np.where(np.arange(30) % 2 == 0, 1.0, -1.0)[:, None]
    runs = tmp_path / "runs"
    rec = {"sensor": "stereo", "align": "se3", "run": 0}
    mine = {**rec, "case": "s:stereo:off", "out": str(runs / "ours" / "0"),
            "trajectory": _tum(runs / "ours" / "0" / "trajectory.tum", t, 0.99 * gt + sign * [0, 0, 0.001])}
    _tum(runs / "ours" / "0" / "groundtruth.tum", t, gt)
    peer = {**rec, "case": "s:stereo:orbslam3",
            "trajectory": _tum(runs / "peer" / "0" / "trajectory.tum", t, gt + sign * [0, 0, 0.002])}
    se3, sim3 = common_frames.compare([mine], [peer]), common_frames.compare_sim3([mine], [peer])
    assert se3["ratio"] > 2
    assert sim3["frames"] == 30 and sim3["ratio"] == pytest.approx(0.5, abs=0.05)
    assert sim3["ours"] == pytest.approx(0.001, abs=2e-4)
    # Monocular runs are evaluated with Sim3 already: no second figure, and the cell says so.
    mono = {**mine, "sensor": "mono", "align": "sim3", "case": "s:mono:off"}
    assert common_frames.compare_sim3([mono], [{**peer, "case": "s:mono:orbslam3"}]) is None
    rows = [{**_record("s:stereo:off", "dynaorb", "off", 0.01, 40.0), **mine},
            {**_record("s:stereo:orbslam3", "orbslam3", "off", 0.002, 60.0), **peer},
            {**_record("s:mono:off", "dynaorb", "off", 0.01, 40.0), **mono},
            {**_record("s:mono:orbslam3", "orbslam3", "off", 0.002, 60.0), **peer, "case": "s:mono:orbslam3",
             "sensor": "mono"}]
    ps = {p["sensor"]: p for p in report.pairs(report.aggregate(rows), "off", rows)}
    assert ps["stereo"]["common_sim3"]["ratio"] == pytest.approx(0.5, abs=0.05)
    table = report.pair_table(list(ps.values()))
    header = table[0].split(" | ")
    column = header.index("the same aligned with scale (Sim3)")
    assert header[column - 1] == "ATE ours/theirs over the frames both tracked"
    cells = {line.split(" | ")[1]: line.split(" | ")[column] for line in table[2:]}
    c = ps["stereo"]["common_sim3"]
    assert cells["stereo"] == f"{c['ratio']:.2f} ({c['ours']:.4f} / {c['theirs']:.4f} m, 30 frames)"
    assert cells["mono"] == "as before"


def test_ms_over_the_frames_both_tracked(tmp_path):
    from dynaorb.bench import common_frames

    # 30 frames 0.05 s apart. Ours: no map on frames 0-4 (20 ms), 4x features on 5-14 (12 ms), then
    # 6 ms, 1 ms of it the labels' from frame 5 on; the peer: no map on frames 0-15 (30 ms), then 8 ms.
    # Over the whole clip the medians are 9 and 30 (0.30); over frames 16-29, which both tracked, 6 and
    # 8 (0.75).
    stamps = [100.0 + 0.05 * i for i in range(30)]
    ours = [{"stamp": t, "state": "OK" if i >= 5 else "NOT_INITIALIZED",
             "track_call_ms": 20.0 if i < 5 else 11.0 if i < 15 else 5.0, "labels_ms": 1.0 if i >= 5 else None}
            for i, t in enumerate(stamps)]
    ours.append({"stamp": 101.6, "state": None, "track_call_ms": None})  # a frame the core rejected
    peer = [{"stamp": t + 1e-7, "state": "OK" if i >= 16 else "NOT_INITIALIZED", "ms": 30.0 if i < 16 else 8.0}
            for i, t in enumerate(stamps)]
    runs = tmp_path / "runs"
    for who, name, frames in (("ours", "stats.json", ours), ("peer", "peer.json", peer)):
        (runs / who / "0").mkdir(parents=True)
        (runs / who / "0" / name).write_text(json.dumps({"per_frame": frames}))
    mine = {**_record("s:stereo:full", "dynaorb", "full", 0.02, 9.0), "out": str(runs / "ours" / "0")}
    theirs = {**_record("s:stereo:orbslam3", "orbslam3", "off", 0.02, 30.0), "out": str(runs / "peer" / "0")}
    c = common_frames.compare_ms([mine], [theirs])
    assert c == {"pairs": 1, "frames": 14, "ours": 6.0, "theirs": 8.0, "ratio": 0.75}
    assert common_frames.run_pair_ms(mine, theirs)["frames"] == 14
    # The records moved with their bench folder: found under it by their runs/... part.
    moved = {**mine, "out": "/elsewhere/runs/ours/0"}
    assert common_frames.compare_ms([moved], [theirs]) is None
    assert common_frames.compare_ms([moved], [theirs], tmp_path)["ratio"] == 0.75
    # A missing or unreadable file, or too few frames in common: no figure.
    assert common_frames.compare_ms([mine], [{**theirs, "out": str(runs / "none")}]) is None
    (runs / "peer" / "1").mkdir()
    for text in ("{not json", "[1, 2]", '{"per_frame": [3]}'):
        (runs / "peer" / "1" / "peer.json").write_text(text)
        assert common_frames.compare_ms([mine], [{**theirs, "out": str(runs / "peer" / "1")}]) is None
    late = [{**f, "state": "OK" if i >= 25 else "LOST"} for i, f in enumerate(peer)]
    (runs / "peer" / "2").mkdir()
    (runs / "peer" / "2" / "peer.json").write_text(json.dumps({"per_frame": late}))
    assert common_frames.compare_ms([mine], [{**theirs, "out": str(runs / "peer" / "2")}]) is None
    # In the pair table, beside the whole clip's ratio.
    ps = report.pairs(report.aggregate([mine, theirs]), "full", [mine, theirs])
    table = "\n".join(report.pair_table(ps))
    assert "| 0.30 |" in table and "| 0.75 (6.0 / 8.0 ms, 14 frames) |" in table


def test_stage_table_gives_the_filter_worker_apart(tmp_path):
    def full(run, corners, stereo):
        worker = {"corners_ahead": corners, **({"stereo_ahead": stereo} if stereo is not None else {})}
        return {**_record("s:stereo:full", "dynaorb", "full", 0.02, 40.0, run),
                "dynamic_filter": {"stages": ["semantic", "dm"], "summary": {"worker_ms_median": worker}}}

    # Medians over the runs: corners 14.0 / 16.0 -> 15.0; stereo given by one run only -> 7.0.
    records = [full(0, 14.0, 7.0), full(1, 16.0, None), _record("s:stereo:off", "dynaorb", "off", 0.02, 30.0)]
    results = {"suite": "quick", "runs": 2, "records": records, "machine": {"cpus": 2}}
    (tmp_path / "results.json").write_text(json.dumps(results))
    text = report.write(report.load(tmp_path), tmp_path).read_text()
    table = text.split("## Tracking thread stages")[1]
    header = next(line for line in table.splitlines() if line.startswith("| sequence"))
    assert header.endswith("| frame_total | corners_ahead (worker) | stereo_ahead (worker) |"), header
    # Not in the tracking thread's sum: frame_total stays the stages' 40.0.
    assert "| s | stereo | full | - | - | 20.0 | - | 20.0 | 40.0 | 15.0 | 7.0 |" in table
    assert "| s | stereo | off | - | - | 15.0 | - | 15.0 | 30.0 | - | - |" in table


def test_readme_section_is_replaced(tmp_path):
    text = f"# T\n\nintro\n\n## Results\n\n{readme.BEGIN}\nold numbers\n{readme.END}\n\n## Layout\nrest\n"
    new = readme.replace_section(text, "| new | table |")
    assert "old numbers" not in new and "| new | table |" in new
    assert new.startswith("# T\n\nintro") and new.endswith("## Layout\nrest\n")
    assert readme.replace_section(new, "again").count(readme.BEGIN) == 1
    with pytest.raises(ValueError):
        readme.replace_section("# no markers\n", "x")
    ours = {**_record("s:stereo:off", "dynaorb", "off", 0.02, 40.0), "keyframes": 12, "keyframes_made": 30}
    theirs = {**_record("s:stereo:orbslam3", "orbslam3", "off", 0.01, 60.0), "keyframes": 20}
    results = {"suite": "quick", "runs": 1, "records": [ours, theirs],
               "not_run": [], "peer": {"status": "run"}, "machine": {"cpus": 2}}
    (tmp_path / "results.json").write_text(json.dumps(results))
    path = tmp_path / "README.md"
    path.write_text(text)
    readme.update_readme(path, tmp_path)
    body = path.read_text()
    assert "| s | stereo | 0.0200 | 0.0100 | 2.00 |" in body and "old numbers" not in body
    # Every case of both systems, with the final map's keyframes (and ours made).
    cases = body.split("Every case, both systems")[1]
    assert "| s | stereo | dynaorb off | 0.0200 |" in cases and cases.count("| 12 (30) |") == 1
    assert "| s | stereo | ORB-SLAM3 | 0.0100 |" in cases and "| 20 |" in cases


def test_real_peer_run(tmp_path, synth_rgbd):
    """ORB-SLAM3 through pyorbslam3 on 8 synthetic RGB-D frames, when it can be installed here."""
    try:
        python = orbslam3.ensure_venv(log=lambda m: None)
    except orbslam3.PeerUnavailable as exc:
        pytest.skip(f"pyorbslam3 cannot be installed or loaded here: {exc}")
    vocabulary = orbslam3.vocabulary_text("default")
    # Paced at the recording's rate (30 Hz), as --realtime runs it: the worker loads dynaorb's pacing.py.
    stats = orbslam3.run(orbslam3.PeerCase("tum", str(synth_rgbd), "rgbd", tmp_path / "peer", realtime=1.0), python,
                         vocabulary, timeout_s=300)
    assert "error" not in stats, stats.get("error")
    assert stats["frames"] == 8 and stats["tracked_fraction"] > 0.5
    assert stats["realtime"]["rate"] == 1.0 and stats["realtime"]["frames"] == 8
    assert stats["ate"] is not None and stats["ate"]["rmse"] < 0.25
    assert stats["track_call_ms_median"] > 0 and stats["peak_rss_mb"] > 50
    assert stats["keyframes"] >= 1  # its map at shutdown: its first keyframe at least


def test_network_runs_where_there_are_no_label_images(tmp_path, data):
    """A sequence without label images (as the real ones): presets with a semantic stage run the network
    asynchronously, and its time is recorded apart from the tracking thread's."""
    import dataclasses

    from dynaorb.bench.suite_runner import BenchOptions, run_suite

    model = data.parent / "models" / "segmentation" / "deeplabv3_mnv2_dm05_pascal_quant.onnx"
    if not model.is_file():
        pytest.skip(f"model not found at {model}")
    seq = synth_sequence("rgbd", 3, tmp_path / "synth", frames=12, seed=7, width=320, height=240, fx=262.5)
    seq = dataclasses.replace(seq, name="unlabelled", labels=None)
    cases, not_run = cases_for([seq], presets=("dm",))
    run_suite(BenchOptions(out=str(tmp_path / "out"), runs=1, peer=False, segment_model=str(model)),
              suite=Suite("net", cases, [seq], not_run), progress=lambda m: None)
    records = {r["preset"]: r for r in json.loads((tmp_path / "out" / "results.json").read_text())["records"]}
    dm = records["dm"]
    assert not dm.get("error"), dm.get("error")
    assert dm["labels"] == "network deeplabv3_mnv2_dm05_pascal_quant (async)"
    assert dm["network"]["segmented"] > 0 and dm["network"]["inference_ms_median"] > 0
    assert records["off"].get("network") is None
    assert "ms/image on its own thread" in (tmp_path / "out" / "report.md").read_text()
