"""`dynaorb bench --suite quick|full`: every case N times, each run in its own process, and the peer.

Ours: run_dataset with local mapping in its own thread (synchronous_mapping
False), as a live camera runs it, the frames handed over as fast as the
track calls take them or, with `realtime`, at the recording's rate (both
systems alike); ms per frame is the tracking thread's
frame_total median (its stages), and the wall time around the track call is
kept beside it for the comparison with the peer, which is timed that way.
The peer (ORB-SLAM3 through pyorbslam3) runs on each sequence N times in
`off` terms: no dynamic filter. The runs go sequence by sequence and run by
run: run r of each of the sequence's cases, then the peer's run r, so the
two systems on one sequence are measured minutes apart, not a whole suite
apart (this machine's speed moves by 15-30 % between sessions, and the
peer, when its runs came last, moved more than ours).

Writes OUT/results.json (every run, every number; rewritten after every
run of a sequence, so a bench stopped part way keeps what it measured, with
"finished" null), OUT/report.md and the plots (report.py); run folders under
OUT/runs/<case>/<run>, each with its spec and record.json. With `resume` a
run whose folder holds a record for the same spec is taken from there
instead of being run again (its times are from when it ran).
"""
from __future__ import annotations

import dataclasses
import datetime
import json
import logging
import os
import pathlib
import platform
import re
import sys

from dynaorb.bench.build_info import build, core_fingerprint
from dynaorb.bench.process import child_env, run_child
from dynaorb.bench.suites import Case, Sequence, Suite, build_suite, ensure_rendered, select

log = logging.getLogger(__name__)

RUN_TIMEOUT_S = 900.0  # one run of one case; a run past it is killed and recorded


@dataclasses.dataclass
class BenchOptions:
    suite: str = "quick"
    out: str = "out/bench"
    runs: int = 3
    peer: bool = True
    peer_venv: str | None = None
    vocabulary: str = "default"
    synth_root: str | None = None   # cache of the rendered synthetic sequences (default OUT/synth)
    timeout_s: float = RUN_TIMEOUT_S
    # Segmentation model for the presets with a semantic stage on sequences
    # without label images (the real ones): run asynchronously, as on a live
    # camera, its time reported apart from the tracking thread's. None: no network.
    segment_model: str | None = None
    resume: bool = False            # reuse OUT/runs/<case>/<run>/record.json written for the same spec
    # Frames delivered at this multiple of the recording's rate by their stamps, to ours and to the peer
    # alike (a camera or `rosbag play`; ORB-SLAM3's example runners pace the same way); 0: as fast as the
    # track calls take them.
    realtime: float = 0.0
    # Part of the suite (suites.select): sequences as NAME or NAME:SENSOR, and the presets run beside `off`;
    # None: all of them.
    only: tuple[str, ...] | None = None
    presets: tuple[str, ...] | None = None


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def reused_record(out: pathlib.Path, spec_name: str, spec: dict, resume: bool) -> dict | None:
    """The record an earlier bench left in out for the same spec (resume), else None."""
    record, spec_file = out / "record.json", out / spec_name
    if not (resume and record.is_file() and spec_file.is_file()):
        return None
    try:
        if json.loads(spec_file.read_text()) != spec:
            return None
        return json.loads(record.read_text())
    except (OSError, ValueError):
        return None


def _start(out: pathlib.Path, spec_name: str, spec: dict) -> None:
    """A run about to be made: its spec written, an older record of the folder dropped."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "record.json").unlink(missing_ok=True)
    (out / spec_name).write_text(json.dumps(spec, indent=1))


def keep_record(out: pathlib.Path, record: dict) -> dict:
    """A finished run's record, written where reused_record finds it (both suites use these)."""
    (out / "record.json").write_text(json.dumps(record, indent=1))
    return record


def _ours_record(case: Case, run: int, out: pathlib.Path, opts: BenchOptions) -> dict:
    seq = case.sequence
    out.mkdir(parents=True, exist_ok=True)
    spec = {"kind": seq.kind, "path": seq.path, "sensor": seq.sensor, "out": str(out), "dynamic": case.preset,
            "vocabulary": opts.vocabulary, "synchronous_mapping": False, "result": str(out / "result.json"),
            "core": core_fingerprint()}
    if opts.realtime:
        spec["realtime"] = opts.realtime
    # The semantic stage reads the label images; presets without it (li) run without labels.
    if case.preset != "off" and _has_semantic(case.preset, seq.sensor):
        if seq.labels:
            spec["labels"] = seq.labels
        elif opts.segment_model:
            spec.update(segment=opts.segment_model, segment_mode="async", segment_threads=1)
    reused = reused_record(out, "spec.json", spec, opts.resume)
    if reused is not None:
        return reused
    child = run_spec(out, spec, opts.timeout_s)
    record = {"system": "dynaorb", "case": case.key, "sequence": seq.name, "sensor": seq.sensor,
              "preset": case.preset, "run": run, "out": str(out),
              "labels": spec.get("labels") or (f"network {pathlib.Path(spec['segment']).stem} (async)"
                                               if spec.get("segment") else None),
              "trajectory": str(out / "trajectory.tum"),
              "peak_rss_mb": child.peak_rss_mb, "process_wall_s": child.wall_s}
    result = out / "result.json"
    if child.ok and result.is_file():
        stats = json.loads(result.read_text())
        record.update(_metrics(stats))
        # The child's own reading at its end is exact; the parent's sampling covers crashes.
        record["peak_rss_mb"] = max(v for v in (child.peak_rss_mb, stats.get("peak_rss_mb_self"), 0.0) if v is not None)
        record["stats"] = {k: stats.get(k) for k in ("frames", "tracked_frames", "init_frame", "states",
                                                      "lost_frames", "relocalizations", "map", "wall_s",
                                                      "frames_rejected", "frames_skipped", "realtime")}
        seg = stats.get("segmentation")
        # The network's own time, on its thread (not inside the tracking thread's ms).
        record["network"] = None if not seg else {k: seg.get(k) for k in (
            "model", "inference_ms_median", "propagate_ms_median", "age_median", "segmented", "dropped_unseen",
            "failures")}
        dyn = stats.get("dynamic_filter")
        record["dynamic_filter"] = None if not dyn else {k: dyn.get(k) for k in (
            "stages", "labels", "summary", "all_dynamic_frames", "stage_failures")}
    else:
        record["error"] = (child.failure() or "no result written") + "\n" + child.log_tail()
    return keep_record(out, record)


def run_spec(out: pathlib.Path, spec: dict, timeout_s: float):
    """Runs dynaorb on spec (RunOptions fields and "result") in a child process, its spec.json and run.log in
    out; the ChildResult (the stats are in spec's result file when it succeeded)."""
    _start(out, "spec.json", spec)
    return run_child([sys.executable, "-m", "dynaorb.bench.child", str(out / "spec.json")], out / "run.log",
                     timeout_s, env=child_env())


def _has_semantic(preset: str, sensor: str) -> bool:
    from dynaorb import core
    from dynaorb.runner.run import resolve_dynamic

    return "semantic" in core().DynamicFilterOptions.load(str(resolve_dynamic(preset))).stages_for(sensor)


def _metrics(stats: dict) -> dict:
    """The numbers the report tables use, from a run's stats (ours or the peer's)."""
    ate = stats.get("ate")
    return {
        "ate": ate, "ate_rmse": ate["rmse"] if ate else None, "ate_reason": None if ate else stats.get("reason"),
        "rpe_trans_rmse": (stats.get("rpe_trans") or {}).get("rmse"),
        "rpe_rot_rmse": (stats.get("rpe_rot") or {}).get("rmse"),
        "align": stats.get("align"),
        "tracked_fraction": stats.get("tracked_fraction"),
        "frame_ms_median": (stats.get("stage_ms_median") or {}).get("frame_total"),
        "track_call_ms_median": stats.get("track_call_ms_median"),
        "track_call_ms": stats.get("track_call_ms"),
        # With a network behind the camera: the tracking thread's time per frame
        # for the labels (before the track call), and both together.
        "labels_ms_median": stats.get("labels_ms_median"),
        "track_call_plus_labels_ms_median": stats.get("track_call_plus_labels_ms_median"),
        "fps": stats.get("fps"),
        "stage_ms_median": stats.get("stage_ms_median"),
        **_keyframes(stats),
    }


def _keyframes(stats: dict) -> dict:
    """Keyframes in the final map, and for ours how many that map was given in all (those culled as
    redundant included); the peer reports the first only."""
    m = stats.get("map")
    if not m:
        return {"keyframes": stats.get("keyframes"), "keyframes_made": None}
    return {"keyframes": m.get("keyframes"), "keyframes_made": m.get("keyframes", 0) + m.get("keyframes_culled", 0)}


def _peer_record(seq: Sequence, run: int, root: pathlib.Path, python, vocabulary, timeout_s: float,
                 resume: bool = False, realtime: float = 0.0) -> dict:
    """One run of the peer on seq (its record, also written to its run folder)."""
    return peer_record(seq, root / "runs" / _slug(f"{seq.key}:orbslam3") / str(run), python, vocabulary, timeout_s,
                       resume, realtime, {"run": run})


def peer_record(seq: Sequence, out: pathlib.Path, python, vocabulary, timeout_s: float, resume: bool = False,
                realtime: float = 0.0, fields: dict | None = None) -> dict:
    """One run of the peer on seq in the folder out (its record, with fields, also written there)."""
    from dynaorb.peer import orbslam3

    spec = {"kind": seq.kind, "path": seq.path, "sensor": seq.sensor, "vocabulary": str(vocabulary)}
    if realtime:
        spec["realtime"] = realtime
    reused = reused_record(out, "peer_spec.json", spec, resume)
    if reused is not None:
        return reused
    _start(out, "peer_spec.json", spec)
    try:
        stats = orbslam3.run(orbslam3.PeerCase(seq.kind, seq.path, seq.sensor, out, realtime), python, vocabulary,
                             timeout_s)
    except Exception as exc:  # e.g. the sequence cannot be read for this sensor: recorded, the bench goes on
        stats = {"error": f"{type(exc).__name__}: {exc}"}
    record = {"system": "orbslam3", "case": f"{seq.key}:orbslam3", "sequence": seq.name, "sensor": seq.sensor,
              "preset": "off", **(fields or {}), "out": str(out), "peak_rss_mb": stats.get("peak_rss_mb"),
              "process_wall_s": stats.get("wall_s")}
    if "error" in stats:
        record["error"] = stats["error"]
    else:
        record.update(_metrics(stats))
        record["trajectory"] = str(out / "trajectory.tum")
        record["stats"] = {k: stats.get(k) for k in ("frames", "tracked_frames", "states", "init_s", "exit",
                                                      "pyorbslam3", "trajectory_poses", "trajectory_repeats_dropped",
                                                      "realtime")}
        record.update(frames=stats.get("frames"), tracked_frames=stats.get("tracked_frames"))  # as the seeds suite's
    return keep_record(out, record)


def machine() -> dict:
    info = {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count()}
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return info


def run_suite(opts: BenchOptions, suite: Suite | None = None, progress=print) -> dict:
    """Runs every case (and the peer) and writes results.json and report.md; the results."""
    from dynaorb.bench import report
    from dynaorb.synth.textures import default_texture_dir

    out = pathlib.Path(opts.out)
    if suite is None:
        data = default_texture_dir()
        if data is None:
            raise FileNotFoundError("the shared data folder was not found (set DYNAORB_SHARED)")
        suite = build_suite(opts.suite, pathlib.Path(data),
                            pathlib.Path(opts.synth_root) if opts.synth_root else out / "synth")
    if opts.only or opts.presets:
        suite = select(suite, opts.only, opts.presets)  # before anything is written
    out.mkdir(parents=True, exist_ok=True)
    for seq in suite.sequences:
        if seq.synthetic:
            progress(f"rendering {seq.name} (once; cached in {seq.synthetic['out']})")
            ensure_rendered(seq)
    results = {"suite": suite.name, "runs": opts.runs, "started": datetime.datetime.now().isoformat(timespec="seconds"),
               "machine": machine(), "build": build(), "mapping": mapping_mode(opts.realtime),
               "realtime": opts.realtime or None,
               "vocabulary": opts.vocabulary, "not_run": list(suite.not_run),
               "only": list(opts.only) if opts.only else None, "presets": list(opts.presets) if opts.presets else None,
               "sequences": [dataclasses.asdict(s) for s in suite.sequences], "records": [], "peer": None,
               "finished": None}
    peer = _peer_setup(opts, progress)
    results["peer"] = peer["status"]
    # Sequence by sequence, run by run: run r of every case of a sequence,
    # then the peer's run r on it, so both systems' runs on one sequence are
    # minutes apart, not the whole suite apart (the machine's speed drifts).
    in_suite = {seq.key for seq in suite.sequences}
    order: dict[str, Sequence] = {}
    for seq in [c.sequence for c in suite.cases] + list(suite.sequences):
        order.setdefault(seq.key, seq)

    def take(record: dict) -> None:
        if record.get("error"):
            progress(f"  failed: {record['error'].splitlines()[0]}")
        results["records"].append(record)

    for key, seq in order.items():
        cases = [c for c in suite.cases if c.sequence.key == key]
        with_peer = peer["python"] is not None and key in in_suite
        for run in range(opts.runs):
            for case in cases:
                progress(f"dynaorb {case.key} run {run + 1}/{opts.runs}")
                take(_ours_record(case, run, out / "runs" / _slug(case.key) / str(run), opts))
            if with_peer:
                progress(f"orbslam3 {key} run {run + 1}/{opts.runs}")
                take(_peer_record(seq, run, out, peer["python"], peer["vocabulary"], opts.timeout_s, opts.resume,
                                  opts.realtime))
            _save(out, results)
    results["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
    _save(out, results)
    report.write(results, out)
    return results


def mapping_mode(realtime: float) -> str:
    """How the runs were made, for the report's header."""
    pace = (f"frames delivered at {realtime:g}x the recording's rate by their stamps, to both systems (as a "
            "camera or `rosbag play` delivers them; ORB-SLAM3's example runners pace the same way)"
            if realtime else "frames handed over as fast as each system's track calls take them")
    return f"local mapping in its own thread (synchronous_mapping False), as a live camera runs; {pace}"


def _save(out: pathlib.Path, results: dict) -> None:
    """results.json as it stands (written whole, then moved over the last one)."""
    part = out / "results.json.part"
    part.write_text(json.dumps(results, indent=1))
    part.replace(out / "results.json")


def _peer_setup(opts: BenchOptions, progress) -> dict:
    if not opts.peer:
        return {"python": None, "status": {"status": "skipped (--no-peer)"}}
    return peer_setup(opts.peer_venv, opts.vocabulary, progress)


def peer_setup(venv: str | None, vocabulary_spec: str, progress) -> dict:
    """The peer's venv and vocabulary, made before the first run ({"python": None} when it cannot run),
    and its status for results.json."""
    from dynaorb.peer import orbslam3

    try:
        python = orbslam3.ensure_venv(pathlib.Path(venv) if venv else None, log=progress)
        vocabulary = orbslam3.vocabulary_text(vocabulary_spec)
    except orbslam3.PeerUnavailable as exc:
        progress(f"peer not run: {exc}")
        return {"python": None, "status": {"status": f"not run: {exc}"}}
    return {"python": python, "vocabulary": vocabulary,
            "status": {"status": "run", "package": orbslam3.PYORBSLAM3, "venv": str(python.parent.parent),
                       "vocabulary": str(vocabulary)}}
