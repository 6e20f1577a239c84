"""ATE and ms per frame of dynaorb and of ORB-SLAM3 over the frames both of them tracked.

Where the two systems track different stretches of a sequence (one keeps
its first monocular map, the other loses it and starts a new one later;
one is lost on frames the other tracks), their ATEs are over different
frames and their ratio says little. Here run r of ours and run r of the
peer are cut to the stamps both trajectories hold, and each cut is
evaluated on its own against the run's ground truth, with the alignment of
the full evaluation (Sim3 monocular, SE3 otherwise). The medians over the
run pairs go into the pair table beside the full-trajectory ratio.

Stereo and RGB-D trajectories have a metric scale, and their SE3 ATE holds
its error: on a short clip a trajectory 0.3 % too long or short can weigh
more than its shape (docs/slam-core.md, "The synthetic stereo room's
scale"). compare_sim3 gives the same cut pairs aligned with scale as well,
so the pair table says which of the two an ATE ratio comes from.

The same holds for time: a frame without a map costs each system what its
initialisation costs (ORB-SLAM3 extracts 5x the features until its map,
which comes at frame 21-22 on the synthetic monocular room with movers; ours
at frame 7), so the per-frame medians over a whole clip compare different
work. compare_ms takes each run pair's per-frame times (ours: the track
call with the tracking thread's labels time, stats.json; the peer's:
peer.json) over the frames both tracked (state OK in both).
"""
from __future__ import annotations

import json
import pathlib
import statistics

import numpy as np

# Stamps of one frame in the two trajectories differ by the writers'
# rounding only; frames are >= 10 ms apart in every dataset here.
STAMP_TOLERANCE_S = 1e-3
# Fewer common poses than this: no common-frame ATE (a Sim3 fit on a
# handful of poses says nothing).
MIN_COMMON_POSES = 10


def _existing(path: str | None, out: pathlib.Path | None) -> pathlib.Path | None:
    """path as recorded, or the same file under the bench folder `out` (a results.json moved with its runs)."""
    if not path:
        return None
    p = pathlib.Path(path)
    if p.is_file():
        return p
    if out is not None and "runs" in p.parts:
        q = pathlib.Path(out, *p.parts[p.parts.index("runs"):])
        if q.is_file():
            return q
    return None


def _held(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mask over the stamps a: those that b also holds (within STAMP_TOLERANCE_S)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(len(a), dtype=bool)
    b = np.sort(b)
    i = np.searchsorted(b, a)
    after = np.abs(b[np.minimum(i, len(b) - 1)] - a)
    before = np.abs(b[np.maximum(i - 1, 0)] - a)
    return np.minimum(after, before) <= STAMP_TOLERANCE_S


def _cut(traj, keep: np.ndarray):
    """The poses of an evo trajectory where keep (a mask over its poses) is set."""
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(poses_se3=[p for p, k in zip(traj.poses_se3, keep) if k],
                            timestamps=np.asarray(traj.timestamps)[keep])


def run_pair(ours: dict, theirs: dict, out: pathlib.Path | None = None, align: str | None = None) -> dict | None:
    """{"frames", "ours", "theirs"}: both runs' ATE RMSE [m] over the frames both tracked, aligned as
    our run's full evaluation was (or with `align`: "se3", "sim3"); None when a trajectory, the ground
    truth or our run's ATE is missing or they share fewer than MIN_COMMON_POSES poses."""
    from evo.tools.file_interface import FileInterfaceException

    from dynaorb.evaluation import evaluate, load_trajectory

    ours_file, theirs_file = _existing(ours.get("trajectory"), out), _existing(theirs.get("trajectory"), out)
    gt_file = _existing(str(pathlib.Path(ours.get("out") or "", "groundtruth.tum")), out)
    evaluated = ours.get("align")  # the full evaluation's: sim3 monocular, se3 otherwise; none without an ATE
    if not (ours_file and theirs_file and gt_file and evaluated):
        return None
    align = align or evaluated
    try:
        a, b, gt = load_trajectory(ours_file), load_trajectory(theirs_file), load_trajectory(gt_file)
    except (ValueError, OSError, FileInterfaceException):  # unreadable or empty: no common-frame figure
        return None
    ta, tb = np.asarray(a.timestamps), np.asarray(b.timestamps)
    keep_a, keep_b = _held(ta, tb), _held(tb, ta)
    frames = int(np.count_nonzero(keep_a))
    if frames < MIN_COMMON_POSES:
        return None
    try:
        ate_a = evaluate(gt, _cut(a, keep_a), align=align, rpe_delta=None).ate["rmse"]
        ate_b = evaluate(gt, _cut(b, keep_b), align=align, rpe_delta=None).ate["rmse"]
    except ValueError:  # too few poses match the ground truth
        return None
    return {"frames": frames, "ours": float(ate_a), "theirs": float(ate_b)}


def compare(ours_runs: list[dict], theirs_runs: list[dict], out: pathlib.Path | None = None) -> dict | None:
    """Medians over the run pairs (run r with run r) of run_pair: {"pairs", "frames", "ours", "theirs",
    "ratio"}; None when no pair has a common-frame ATE."""
    return _over_pairs(ours_runs, theirs_runs, lambda r, t: run_pair(r, t, out))


def compare_sim3(ours_runs: list[dict], theirs_runs: list[dict], out: pathlib.Path | None = None) -> dict | None:
    """compare() with every cut aligned with scale (Sim3); None where our runs were evaluated with Sim3
    already (monocular: compare() is this) or no pair has a common-frame ATE."""
    if any(r.get("align") == "sim3" for r in ours_runs):
        return None
    return _over_pairs(ours_runs, theirs_runs, lambda r, t: run_pair(r, t, out, align="sim3"))


def _over_pairs(ours_runs: list[dict], theirs_runs: list[dict], one) -> dict | None:
    """Medians over the run pairs (run r of ours with the peer's run r, both finished) of one(r, t), a
    {"frames", "ours", "theirs"} or None; None when no pair has one."""
    theirs_by_run = {r.get("run"): r for r in theirs_runs if not r.get("error")}
    results = []
    for r in ours_runs:
        t = theirs_by_run.get(r.get("run"))
        if r.get("error") or t is None:
            continue
        c = one(r, t)
        if c is not None:
            results.append(c)
    if not results:
        return None
    ours_med = statistics.median(c["ours"] for c in results)
    theirs_med = statistics.median(c["theirs"] for c in results)
    return {"pairs": len(results), "frames": int(statistics.median(c["frames"] for c in results)),
            "ours": ours_med, "theirs": theirs_med, "ratio": ours_med / theirs_med if theirs_med > 0 else None}


def _frame_times(record: dict, name: str, out: pathlib.Path | None) -> dict[float, tuple[bool, float]] | None:
    """{stamp: (tracked, ms)} from the run's per-frame records in its folder's `name` (stats.json: ours,
    the track call plus the labels' time; peer.json: ORB-SLAM3's track call); None when unreadable."""
    path = _existing(str(pathlib.Path(record.get("out") or "", name)), out) if record.get("out") else None
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    frames = data.get("per_frame") if isinstance(data, dict) else None
    times = {}
    for f in frames if isinstance(frames, list) else []:
        if not isinstance(f, dict):
            continue
        ms = f.get("ms") if "ms" in f else f.get("track_call_ms")
        if ms is None or f.get("stamp") is None:
            continue  # a frame the core rejected: no track call
        times[float(f["stamp"])] = (f.get("state") == "OK", float(ms) + float(f.get("labels_ms") or 0.0))
    return times


def run_pair_ms(ours: dict, theirs: dict, out: pathlib.Path | None = None) -> dict | None:
    """{"frames", "ours", "theirs"}: both runs' median ms per frame over the frames both tracked; None
    when a run's per-frame records are missing or they share fewer than MIN_COMMON_POSES such frames."""
    a, b = _frame_times(ours, "stats.json", out), _frame_times(theirs, "peer.json", out)
    if not a or not b:
        return None
    ta = np.array([t for t, (ok, _) in a.items() if ok])
    tb = np.array([t for t, (ok, _) in b.items() if ok])
    keep_a, keep_b = _held(ta, tb), _held(tb, ta)
    if int(np.count_nonzero(keep_a)) < MIN_COMMON_POSES:
        return None
    mine = [a[t][1] for t in ta[keep_a]]
    peer = [b[t][1] for t in tb[keep_b]]
    return {"frames": len(mine), "ours": statistics.median(mine), "theirs": statistics.median(peer)}


def compare_ms(ours_runs: list[dict], theirs_runs: list[dict], out: pathlib.Path | None = None) -> dict | None:
    """Medians over the run pairs (run r with run r) of run_pair_ms: {"pairs", "frames", "ours",
    "theirs", "ratio"}; None when no pair has one."""
    return _over_pairs(ours_runs, theirs_runs, lambda r, t: run_pair_ms(r, t, out))
