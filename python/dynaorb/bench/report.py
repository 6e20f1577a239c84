"""OUT/report.md and its plots from the benchmark's results (results.json).

Tables: per case (ATE, RPE, tracked %, ms/frame, fps, peak memory; medians
over the runs, ATE min-max), each dynamic preset against `off` on the same
sequence, dynaorb against ORB-SLAM3 pair by pair (ratios of ATE and of ms per
frame, the latter also run by run), and the tracking thread's stages. Plots: per sequence the
trajectories (ground truth, dynaorb off, ORB-SLAM3; first run of each, under
the evaluation's own alignment) and the error over time (every preset and
the peer), and a per-stage time bar chart.
"""
from __future__ import annotations

import collections
import copy
import json
import pathlib
import statistics

import numpy as np

from dynaorb.bench import common_frames

STAGES = ("preprocess", "dynamic", "extract", "stereo_matching", "tracking")
OVERLAPPED = "extract_overlapped"


def _median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def aggregate(records: list[dict]) -> list[dict]:
    """One row per case (in the order of the records): medians over its runs."""
    groups = collections.OrderedDict()
    for r in records:
        groups.setdefault(r["case"], []).append(r)
    rows = []
    for key, runs in groups.items():
        ok = [r for r in runs if not r.get("error")]
        ates = [r["ate_rmse"] for r in ok if r.get("ate_rmse") is not None]
        stage = collections.defaultdict(list)
        for r in ok:
            for k, v in (r.get("stage_ms_median") or {}).items():
                stage[k].append(v)
        first = runs[0]
        dyn = next((r.get("dynamic_filter") for r in ok if r.get("dynamic_filter")), None)
        rows.append({
            "case": key, "system": first["system"], "sequence": first["sequence"], "sensor": first["sensor"],
            "preset": first["preset"], "runs": len(runs), "runs_ok": len(ok), "runs_with_ate": len(ates),
            "labels": first.get("labels"),
            "errors": [r["error"].splitlines()[0] for r in runs if r.get("error")],
            "ate_reasons": sorted({r["ate_reason"] for r in ok if r.get("ate_reason")}),
            "ate_rmse": _median(ates), "ate_min": min(ates) if ates else None, "ate_max": max(ates) if ates else None,
            "rpe_trans_rmse": _median(r.get("rpe_trans_rmse") for r in ok),
            "rpe_rot_rmse": _median(r.get("rpe_rot_rmse") for r in ok),
            "align": next((r.get("align") for r in ok if r.get("align")), None),
            "tracked_fraction": _median(r.get("tracked_fraction") for r in ok),
            "frame_ms_median": _median(r.get("frame_ms_median") for r in ok),
            "track_call_ms_median": _median(r.get("track_call_ms_median") for r in ok),
            # The tracking thread's time for a frame's labels (a network behind the
            # camera), and the track call with them: what the pair table compares.
            "labels_ms_median": _median(r.get("labels_ms_median") for r in ok),
            "thread_ms_median": _median(_thread_ms(r) for r in ok),
            "fps": _median(r.get("fps") for r in ok),
            "keyframes": _median(r.get("keyframes") for r in ok),
            "keyframes_made": _median(r.get("keyframes_made") for r in ok),
            "peak_rss_mb": _median(r.get("peak_rss_mb") for r in runs),
            "stage_ms_median": {k: statistics.median(v) for k, v in stage.items()},
            "dynamic_stages": dyn.get("stages") if dyn else None,
            "network_ms_median": _median((r.get("network") or {}).get("inference_ms_median") for r in ok),
            "propagate_ms_median": _median((r.get("network") or {}).get("propagate_ms_median") for r in ok),
            "dynamic_ms_median": (dyn or {}).get("summary", {}).get("stage_ms_median", {}).get("dynamic") if dyn else None,
            "worker_ms_median": _worker_ms(ok),
            "dynamic_keypoints_median": (dyn or {}).get("summary", {}).get("dynamic_keypoints_median") if dyn else None,
        })
    return rows


def _worker_ms(runs: list[dict]) -> dict:
    """The filter's work beside the stages on its worker thread (part -> ms per
    frame), medians over the runs of each run's median."""
    parts = collections.defaultdict(list)
    for r in runs:
        summary = (r.get("dynamic_filter") or {}).get("summary") or {}
        for k, v in (summary.get("worker_ms_median") or {}).items():
            parts[k].append(v)
    return {k: statistics.median(v) for k, v in parts.items()}


def pairs(rows: list[dict], preset: str = "off", records: list[dict] | None = None,
          bench_dir: pathlib.Path | None = None) -> list[dict]:
    """dynaorb (in `preset`) against ORB-SLAM3 (plain) on each sequence both ran: ratios ours / theirs.
    With the per-run records, each pair also gets "common": both ATEs over the frames both systems
    tracked (common_frames.compare; their trajectory files are looked up as recorded or under bench_dir),
    "common_sim3": the same aligned with scale as well (stereo and RGB-D; common_frames.compare_sim3),
    and "common_ms": both median ms per frame over those frames (common_frames.compare_ms)."""
    ours = {(r["sequence"], r["sensor"]): r for r in rows if r["system"] == "dynaorb" and r["preset"] == preset}
    runs = collections.defaultdict(list)
    for rec in records or []:
        runs[rec["case"]].append(rec)
    out = []
    for r in rows:
        if r["system"] != "orbslam3":
            continue
        o = ours.get((r["sequence"], r["sensor"]))
        if o is None:
            continue
        common = common_frames.compare(runs[o["case"]], runs[r["case"]], bench_dir) if records else None
        common_sim3 = common_frames.compare_sim3(runs[o["case"]], runs[r["case"]], bench_dir) if records else None
        common_ms = common_frames.compare_ms(runs[o["case"]], runs[r["case"]], bench_dir) if records else None
        out.append({"sequence": r["sequence"], "sensor": r["sensor"], "ours": o, "theirs": r,
                    "ate_ratio": _ratio(o["ate_rmse"], r["ate_rmse"]),
                    "ms_ratio": _ratio(o["thread_ms_median"], r["track_call_ms_median"]),
                    "ms_ratio_runs": run_ms_ratios(runs[o["case"]], runs[r["case"]]), "common": common,
                    "common_sim3": common_sim3, "common_ms": common_ms})
    return out


def _thread_ms(record: dict):
    """A run's median ms per frame as the pair table compares it (with the labels' time where there is one)."""
    return record.get("track_call_plus_labels_ms_median") or record.get("track_call_ms_median")


def run_ms_ratios(ours: list[dict], theirs: list[dict]) -> list[float]:
    """Ours / theirs ms per frame run by run: run r of ours against the peer's run r, which the bench makes
    right after it on the same sequence (suite_runner), so that the machine's drift between runs (a third
    of the time per frame within minutes, seen here) falls on both; in run order, runs both finished."""
    mine = {r.get("run"): _thread_ms(r) for r in ours if not r.get("error")}
    peer = {r.get("run"): r.get("track_call_ms_median") for r in theirs if not r.get("error")}
    return [v for run in sorted(k for k in mine if k is not None and k in peer)
            if (v := _ratio(mine[run], peer[run])) is not None]


def preset_vs_off(rows: list[dict]) -> list[dict]:
    off = {(r["sequence"], r["sensor"]): r for r in rows if r["system"] == "dynaorb" and r["preset"] == "off"}
    out = []
    for r in rows:
        if r["system"] != "dynaorb" or r["preset"] == "off":
            continue
        o = off.get((r["sequence"], r["sensor"]))
        if o is None:
            continue
        out.append({"row": r, "off": o, "ate_ratio": _ratio(r["ate_rmse"], o["ate_rmse"]),
                    "ms_ratio": _ratio(r["frame_ms_median"], o["frame_ms_median"])})
    return out


def _ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None


def _f(v, fmt="{:.3f}", none="n/a"):
    return none if v is None else fmt.format(v)


def _pct(v):
    return _f(None if v is None else 100 * v, "{:.0f} %")


def markdown_table(header: list[str], rows) -> list[str]:
    """A Markdown table's lines: the header cells, the separator, one line per row of cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def _label(r: dict) -> str:
    return "ORB-SLAM3" if r["system"] == "orbslam3" else f"dynaorb {r['preset']}"


def _ate_cell(r: dict) -> str:
    if r["ate_rmse"] is None:
        return "n/a" + (f" ({'; '.join(r['ate_reasons'])})" if r["ate_reasons"] else "")
    spread = f" ({r['ate_min']:.4f}-{r['ate_max']:.4f})" if r["runs_with_ate"] > 1 else ""
    return f"{r['ate_rmse']:.4f}{spread}"


def case_table(rows: list[dict]) -> list[str]:
    return markdown_table(
        ["sequence", "sensor", "system", "runs ok", "ATE RMSE [m] median (min-max)", "RPE trans [m/frame]",
         "RPE rot [deg/frame]", "tracked", "tracking thread ms/frame", "track call ms/frame", "fps", "peak MB",
         "keyframes in the final map (made)"],
        ([r["sequence"], r["sensor"], _label(r), f"{r['runs_ok']}/{r['runs']}", _ate_cell(r),
          _f(r["rpe_trans_rmse"], "{:.4f}"), _f(r["rpe_rot_rmse"], "{:.3f}"), _pct(r["tracked_fraction"]),
          _f(r["frame_ms_median"], "{:.1f}", "-"), _f(r["track_call_ms_median"], "{:.1f}"), _f(r["fps"], "{:.1f}"),
          _f(r["peak_rss_mb"], "{:.0f}"), _keyframes_cell(r)] for r in rows))


def _keyframes_cell(r: dict) -> str:
    """Medians over the runs: the final map's keyframes, and (ours) how many it was given, the culled included."""
    cell = _f(r.get("keyframes"), "{:g}")
    return cell + (f" ({r['keyframes_made']:g})" if r.get("keyframes_made") is not None else "")


# Tracked fractions further apart than this: the two ATEs are over different
# stretches of the sequence, and their ratio says little.
COMPARABLE_TRACKED_GAP = 0.1


def _ate_ratio_cell(p: dict) -> str:
    cell = _f(p["ate_ratio"], "{:.2f}")
    ours, theirs = p["ours"].get("tracked_fraction"), p["theirs"].get("tracked_fraction")
    if p["ate_ratio"] is not None and ours is not None and theirs is not None and \
            abs(ours - theirs) > COMPARABLE_TRACKED_GAP:
        cell += f" (over {_pct(ours)} vs {_pct(theirs)} of the frames: not comparable)"
    return cell


def _common_cell(c: dict | None, value: str = "{:.4f}", unit: str = "m") -> str:
    """A common_frames comparison: the ratio, both medians in `unit` and the frames compared."""
    if not c or c["ratio"] is None:
        return "n/a"
    return f"{c['ratio']:.2f} ({value.format(c['ours'])} / {value.format(c['theirs'])} {unit}, {c['frames']} frames)"


def _common_sim3_cell(p: dict) -> str:
    if p["ours"].get("align") == "sim3":  # monocular: the column before is Sim3 already
        return "as before"
    return _common_cell(p.get("common_sim3"))


def pair_table(ps: list[dict]) -> list[str]:
    return markdown_table(
        ["sequence", "sensor", "ATE dynaorb [m]", "ATE ORB-SLAM3 [m]", "ATE ours/theirs",
         "ms/frame dynaorb (track call + labels)", "ms/frame ORB-SLAM3", "ms ours/theirs",
         "ms ours/theirs run by run", "tracked dynaorb", "tracked ORB-SLAM3",
         "ATE ours/theirs over the frames both tracked", "the same aligned with scale (Sim3)",
         "ms ours/theirs over the frames both tracked"],
        ([p["sequence"], p["sensor"], _f(p["ours"]["ate_rmse"], "{:.4f}"), _f(p["theirs"]["ate_rmse"], "{:.4f}"),
          _ate_ratio_cell(p), _ours_ms_cell(p["ours"]),
          _f(p["theirs"]["track_call_ms_median"], "{:.1f}"), _f(p["ms_ratio"], "{:.2f}"),
          " / ".join(f"{v:.2f}" for v in p.get("ms_ratio_runs") or []) or "n/a",
          _pct(p["ours"]["tracked_fraction"]), _pct(p["theirs"]["tracked_fraction"]), _common_cell(p.get("common")),
          _common_sim3_cell(p), _common_cell(p.get("common_ms"), "{:.1f}", "ms")]
         for p in ps))


def _ours_ms_cell(r: dict) -> str:
    cell = _f(r["thread_ms_median"], "{:.1f}")
    if r.get("labels_ms_median") is not None:
        cell += f" ({_f(r['track_call_ms_median'], '{:.1f}')} + labels {r['labels_ms_median']:.1f})"
    return cell


def _labels_cell(r: dict) -> str:
    labels = r["labels"] if r["labels"] and r["labels"].startswith("network") else \
        "label images" if r["labels"] else "none"
    if r.get("network_ms_median") is not None:
        labels += f", {r['network_ms_median']:.0f} ms/image on its own thread"
    if r.get("labels_ms_median") is not None:
        labels += (f"; taken and moved onto each frame in {r['labels_ms_median']:.1f} ms on the tracking thread, "
                   "before the track call")
    elif r.get("propagate_ms_median") is not None:
        labels += f"; moved onto each frame in {r['propagate_ms_median']:.1f} ms before the track call"
    return labels


def preset_table(ps: list[dict]) -> list[str]:
    return markdown_table(
        ["sequence", "sensor", "preset (stages)", "labels", "ATE [m]", "ATE off [m]", "ATE preset/off",
         "ms/frame", "ms/frame off", "ms preset/off", "dynamic filter ms", "dynamic keypoints (median)"],
        ([p["row"]["sequence"], p["row"]["sensor"],
          f"{p['row']['preset']} ({', '.join(p['row']['dynamic_stages'] or [])})", _labels_cell(p["row"]),
          _f(p["row"]["ate_rmse"], "{:.4f}"), _f(p["off"]["ate_rmse"], "{:.4f}"), _f(p["ate_ratio"], "{:.2f}"),
          _f(p["row"]["frame_ms_median"], "{:.1f}"), _f(p["off"]["frame_ms_median"], "{:.1f}"),
          _f(p["ms_ratio"], "{:.2f}"), _f(p["row"]["dynamic_ms_median"], "{:.1f}"),
          _f(p["row"]["dynamic_keypoints_median"], "{:.0f}")] for p in ps))


def stage_table(rows: list[dict]) -> list[str]:
    ours = [r for r in rows if r["system"] == "dynaorb"]
    extra = sorted({k for r in ours for k in r["stage_ms_median"] if k.startswith("dynamic.")})
    # The corner detection's own time where it ran beside the filter (not in the stage sum).
    extra += [OVERLAPPED] if any(OVERLAPPED in r["stage_ms_median"] for r in ours) else []
    cols = list(STAGES) + extra + ["frame_total"]
    # The filter's worker thread, beside the stages (not in the sum either).
    worker = sorted({k for r in ours for k in r.get("worker_ms_median") or {}})
    return markdown_table(["sequence", "sensor", "preset", *cols, *(f"{w} (worker)" for w in worker)],
                          ([r["sequence"], r["sensor"], r["preset"],
                            *(_f(r["stage_ms_median"].get(c), "{:.1f}", "-") for c in cols),
                            *(_f((r.get("worker_ms_median") or {}).get(w), "{:.1f}", "-") for w in worker)]
                           for r in ours))


# --- plots ---------------------------------------------------------------------------------------------

def _aligned(gt_file: pathlib.Path, est_file: pathlib.Path, sim3: bool):
    """(reference xyz, aligned estimate xyz, stamps, per-pose error) as the ATE aligns them, or None."""
    from evo.core import sync

    from dynaorb.evaluation import load_trajectory

    try:
        ref, est = load_trajectory(gt_file), load_trajectory(est_file)
        ref, est = sync.associate_trajectories(ref, est, max_diff=0.02)
        if ref.num_poses < 3:
            return None
        est = copy.deepcopy(est)
        est.align(ref, correct_scale=sim3)
    except Exception:  # no or too few poses: nothing to draw
        return None
    a, b = ref.positions_xyz, est.positions_xyz
    return a, b, np.asarray(est.timestamps) - float(est.timestamps[0]), np.linalg.norm(a - b, axis=1)


def sequence_plots(records: list[dict], out: pathlib.Path) -> dict:
    """{sequence key: [png paths]}: trajectories and error over time of the first run of each case."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by_seq = collections.OrderedDict()
    for r in records:
        if r.get("error") or r.get("run") != 0 or r.get("ate_rmse") is None:
            continue
        by_seq.setdefault(f"{r['sequence']}:{r['sensor']}", []).append(r)
    plots = {}
    out.mkdir(parents=True, exist_ok=True)
    for key, runs in by_seq.items():
        curves = []
        for r in runs:
            gt = pathlib.Path(r["out"]) / "groundtruth.tum"
            a = _aligned(gt, pathlib.Path(r["trajectory"]), r["sensor"] == "mono")
            if a is not None:
                curves.append((_label(r), r, a))
        if not curves:
            continue
        slug = key.replace("/", "_").replace(":", "_")
        fig, ax = plt.subplots(figsize=(6, 5))
        ref = curves[0][2][0]
        j = 2 if np.ptp(ref[:, 2]) > np.ptp(ref[:, 1]) else 1  # the wider of the two other axes
        ax.plot(ref[:, 0], ref[:, j], "k-", lw=2, label="ground truth")
        for name, r, (_, b, _, _) in curves:
            if r["preset"] == "off":  # ours off and the peer; presets are in the error plot
                ax.plot(b[:, 0], b[:, j], "-", label=name)
        ax.set_xlabel("x [m]")
        ax.set_ylabel(f"{'xyz'[j]} [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True)
        ax.legend(fontsize=8)
        ax.set_title(f"{key}: trajectories (aligned)")
        fig.tight_layout()
        traj_png = out / f"{slug}_trajectory.png"
        fig.savefig(traj_png, dpi=100)
        plt.close(fig)
        fig, ax = plt.subplots(figsize=(7, 3.5))
        for name, r, (_, _, t, err) in curves:
            ax.plot(t, err, "-", label=name, lw=2 if r["system"] == "orbslam3" else 1)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("position error [m]")
        ax.grid(True)
        ax.legend(fontsize=7)
        ax.set_title(f"{key}: error over time")
        fig.tight_layout()
        err_png = out / f"{slug}_error.png"
        fig.savefig(err_png, dpi=100)
        plt.close(fig)
        plots[key] = [traj_png, err_png]
    return plots


def stage_plot(rows: list[dict], out: pathlib.Path) -> pathlib.Path | None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ours = [r for r in rows if r["system"] == "dynaorb" and r["stage_ms_median"]]
    if not ours:
        return None
    fig, ax = plt.subplots(figsize=(max(6, 0.45 * len(ours) + 2), 4.5))
    x = np.arange(len(ours))
    bottom = np.zeros(len(ours))
    for stage in STAGES:
        v = np.array([r["stage_ms_median"].get(stage, 0.0) for r in ours])
        ax.bar(x, v, bottom=bottom, label=stage)
        bottom += v
    ax.set_xticks(x)
    ax.set_xticklabels([f"{r['sequence']}:{r['sensor']}:{r['preset']}" for r in ours], rotation=75, fontsize=7,
                       ha="right")
    ax.set_ylabel("ms per frame (median per stage)")
    ax.set_title("tracking thread stages")
    ax.legend(fontsize=7)
    ax.grid(True, axis="y")
    fig.tight_layout()
    path = out / "stages.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# --- the report -----------------------------------------------------------------------------------------

def build_text(b: dict | None) -> str:
    """The build a results.json measured, in words (older results have none)."""
    if not b:
        return "build not recorded"
    if b.get("commit"):
        commit = f"commit {b['commit'][:10]}" + (" with uncommitted changes" if b.get("dirty") else "")
    else:
        commit = "commit unknown"
    return f"dynaorb at {commit}, core fingerprint {b.get('core')}"


def selection_text(results: dict) -> str:
    """What the report's title adds where the bench ran only some clips or presets of the suite (--only,
    --presets): ", part of it (only ...; presets off, ...)", else ""."""
    parts = ([f"only {', '.join(results['only'])}"] if results.get("only") else []) + \
            ([f"presets off, {', '.join(results['presets'])}"] if results.get("presets") else [])
    return f", part of it ({'; '.join(parts)})" if parts else ""


def selection_args(results: dict) -> str:
    """The command-line options that picked the part of the suite, or ""."""
    return (f" --only {','.join(results['only'])}" if results.get("only") else "") + \
           (f" --presets {','.join(results['presets'])}" if results.get("presets") else "")


def render(results: dict, out: pathlib.Path, plots: dict | None = None, stages_png=None) -> str:
    rows = aggregate(results["records"])
    m = results.get("machine", {})
    peer = results.get("peer") or {}
    lines = [f"# Benchmark: suite {results['suite']}{selection_text(results)}", "",
             f"{results['runs']} run(s) per case; started {results.get('started')}, finished {results.get('finished')}; "
             f"{m.get('cpus')} CPUs ({m.get('cpu', 'unknown CPU')}), {m.get('platform')}; "
             f"{build_text(results.get('build'))}.", "",
             f"- dynaorb mode: {results.get('mapping')}. Medians over the runs; ATE min-max when more than one run.",
             "- ms/frame: *tracking thread* is the median of dynaorb's per-frame stage sum (preprocess, dynamic, "
             "extract, stereo_matching, tracking); *track call* is the wall time around the track call (image "
             "loading outside), taken the same way for dynaorb and ORB-SLAM3: the pair table compares those. "
             "Where the dynamic filter runs beside the ORB corner detection (Dynamic.overlap_extraction), "
             "*extract* is what the extraction adds after the filter and *extract_overlapped* the detection's "
             "own time on its worker thread (not in the sum). The motion cues' corners of the next frame "
             "(Harris: goodFeaturesToTrack, cornerSubPix; or FAST, Dynamic.motion_cues.detector, which `full` "
             "uses for RGB-D) and, for stereo, their depth by LK into the right image are "
             "found on the filter's worker thread once the frame's ORB features are extracted, beside stereo "
             "matching, tracking and the next frame's start: *corners_ahead (worker)* and "
             "*stereo_ahead (worker)*, not in the sum; they take the second core from the rest (local mapping, "
             "the network; the next frame's own use of it), so they wait until the extraction, which uses it for "
             "the right image (stereo) or half of the ORB pyramid levels (mono, RGB-D), is done. "
             "While the motion cues are computed, the same worker cuts the candidate regions DM-SLAM's stage "
             "decides on: *regions_ahead (worker)*, not in the sum.",
             "- fps: frames over the whole loop's wall time (image loading included). Peak MB: the run's process "
             "(VmHWM of its own address space), for ORB-SLAM3 the worker's python process. Keyframes: those "
             "in the map at the end (the current map, where tracking started a new one), medians over the runs; "
             "for dynaorb also how many that map was given in all, the ones local mapping culled as redundant "
             "included (ORB-SLAM3 does not report that).",
             "- ATE: evo, SE3 alignment (Sim3 for monocular), RMSE of the position error; RPE per frame. "
             "*ATE ours/theirs over the frames both tracked*: run r of each system cut to the frames both "
             "trajectories hold, each cut aligned and evaluated on its own, medians over the run pairs (where "
             "one system keeps a map the other loses, the full-trajectory ATEs cover different frames). "
             "*The same aligned with scale (Sim3)*: those cuts of stereo and RGB-D runs aligned with a scale as "
             "well, so that a ratio that comes from the trajectory's length (on a short clip 0.3 % of it can "
             "weigh more than the shape) shows apart from one that comes from its shape; monocular ATEs are "
             "Sim3 already. "
             "*ms ours/theirs over the frames both tracked*: the same for the per-frame times (ours with the "
             "labels' time), medians over the frames both systems tracked, then over the run pairs (monocular, "
             "each system's early frames do different work: ORB-SLAM3 extracts 5x the features until its map, "
             "ours 4x from before its map until a frame tracks 1000 points).",
             "- Semantic stages read the synthetic sequences' label images (PASCAL VOC ids as a network would "
             "output, parked car included). Real sequences have none: there the segmentation network runs "
             "asynchronously on its own thread (masks of older frames propagated by optical flow, as on a live "
             "camera), and its ms per image are given apart (labels column of the presets table). What the "
             "tracking thread spends on each frame's labels before the track call (the newest result taken, "
             "reduced to the model's movable classes, moved onto the frame by optical flow) is not in the track "
             "call's ms: the pair tables add it to dynaorb's (*track call + labels*, the median of the sum per "
             "frame); without a "
             "model (--no-network) the semantic stage marks nothing there. `dynaorb bench --suite "
             "segmentation` measures the network's latency per back end and thread count.",
             f"- ORB-SLAM3 peer: {peer.get('status', 'n/a')}"
             + (f" ({peer.get('package')}, own venv {peer.get('venv')}, our vocabulary as ORBvoc.txt "
                f"{peer.get('vocabulary')}); the same image files, calibration and ORB settings (features, "
                f"scale, levels, FAST thresholds); stereo rectified by ORB-SLAM3 itself inside its track call "
                f"(File.version 1.0 settings with Stereo.T_c1_c2); its trajectory is the one it saves at "
                f"shutdown, evaluated with the same code and ground truth." if peer.get("status") == "run" else ""),
             ""]
    if results.get("not_run"):
        lines += ["## Not run", ""] + [f"- {n['what']}: {n['reason']}" for n in results["not_run"]] + [""]
    failed = [r for r in rows if r["errors"]]
    if failed:
        lines += ["## Failed runs", ""] + [f"- {r['case']}: {e}" for r in failed for e in r["errors"]] + [""]
    for preset in ("off", "full"):
        ps = pairs(rows, preset, results["records"], out)
        if ps:
            lines += [f"## dynaorb ({preset}) against ORB-SLAM3 (plain)", "", *pair_table(ps), ""]
    lines += ["## Every case", "", *case_table(rows), ""]
    pv = preset_vs_off(rows)
    if pv:
        lines += ["## Dynamic presets against off", "", *preset_table(pv), ""]
    lines += ["## Tracking thread stages (median ms per frame)", "", *stage_table(rows), ""]
    if stages_png:
        lines += [f"![stages]({pathlib.Path(stages_png).relative_to(out)})", ""]
    if plots:
        lines += ["## Trajectories and error over time (first run)", ""]
        for key, pngs in plots.items():
            lines += [f"### {key}", ""] + [f"![{key}]({pathlib.Path(p).relative_to(out)})" for p in pngs] + [""]
    return "\n".join(lines)


def write(results: dict, out: pathlib.Path) -> pathlib.Path:
    out = pathlib.Path(out)
    rows = aggregate(results["records"])
    plots = sequence_plots(results["records"], out / "plots")
    stages_png = stage_plot(rows, out / "plots") if rows else None
    path = out / "report.md"
    path.write_text(render(results, out, plots, stages_png))
    return path


def load(out: pathlib.Path) -> dict:
    return json.loads((pathlib.Path(out) / "results.json").read_text())
