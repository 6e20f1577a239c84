"""ORB-SLAM3 in the seeds suite: its ATE on the same rendered rooms, seed by seed.

The quick and full suites compare dynaorb with ORB-SLAM3 on one synthetic
seed, where one run's ATE of a few millimetres moves by a third from run to
run and seed to seed. Here the peer (dynaorb.peer.orbslam3: pyorbslam3 in a
venv of its own, a separate process, the same images, calibration, ORB
settings and vocabulary) runs on every seed's room:

  peer_static  no movers: compared with our `static` and `full_static`;
  peer_movers  movers (ORB-SLAM3 has no filter and takes no masks):
               compared with our `full`, `masks` and `off`.

Ratios are ours / ORB-SLAM3 on the same seed (issue 8: `full` no worse
than ORB-SLAM3's plain mode). ORB-SLAM3 maps in its own threads, so its
runs do not repeat as ours (synchronous, equal to rounding) do.

Paced sweeps (`--realtime`: ours with asynchronous mapping, both fed at
the recording's rate) compare speed as well, seed by seed: ms per frame
ours / ORB-SLAM3's, over the whole clip (the full suite's pair tables'
medians: ours the track call with the labels' time) and over the frames
both tracked (common_frames.run_pair_ms: before its map a system does other
work). Synchronous sweeps do not: there our track call waits for each
keyframe's mapping.
"""
from __future__ import annotations

import pathlib
import statistics

from dynaorb.bench import common_frames, report

# peer condition -> whether its room has the movers
PEER_CONDITIONS = {"peer_static": False, "peer_movers": True}
# our condition -> the peer run it is compared with
PEER_OF = {"static": "peer_static", "full_static": "peer_static", "full": "peer_movers", "masks": "peer_movers",
           "off": "peer_movers"}
TARGET = ("<=", 1.0)  # ours no worse


def setup(conditions, venv: str | None, vocabulary: str, progress) -> dict | None:
    """The peer's python and vocabulary when a peer condition is asked for (None otherwise); "python" None with
    the reason in "status" when pyorbslam3 cannot run here."""
    if not any(c in PEER_CONDITIONS for c in conditions):
        return None
    from dynaorb.bench.suite_runner import peer_setup

    return peer_setup(venv, vocabulary, progress)


def run(seq, sensor: str, seed: int, condition: str, out: pathlib.Path, peer: dict, timeout_s: float,
        resume: bool, realtime: float = 0.0) -> dict:
    """One peer run (a seeds-suite record: sensor, seed, condition, ate_rmse, frames, tracked_frames); realtime
    > 0: the frames paced at that rate, as ours."""
    from dynaorb.bench.suite_runner import peer_record

    fields = {"seed": seed, "condition": condition}
    if peer.get("python") is None:
        return {"sensor": sensor, **fields, "out": str(out), "error": f"ORB-SLAM3 {peer['status']['status']}"}
    return peer_record(seq, out, peer["python"], peer["vocabulary"], timeout_s, resume, realtime, fields=fields)


def ratios(results: dict) -> dict:
    """{(sensor, our condition): {seed: our ATE / ORB-SLAM3's}} where both have an ATE."""
    from dynaorb.bench import seeds

    return seeds.ratios(results, PEER_OF.get)


def summarize(results: dict, sensors, test_seeds) -> list[dict]:
    """Per sensor and our condition: seeds compared, median ratio, seeds 0-2 median, seeds where ours <= theirs."""
    rows = []
    by = ratios(results)
    order = list(PEER_OF)
    for (sensor, condition), per_seed in sorted(by.items(), key=lambda kv: (sensors.index(kv[0][0]),
                                                                           order.index(kv[0][1]))):
        values = [per_seed[s] for s in sorted(per_seed)]
        tested = [per_seed[s] for s in test_seeds if s in per_seed]
        rows.append({"sensor": sensor, "condition": condition, "peer": PEER_OF[condition], "seeds": len(values),
                     "median": statistics.median(values),
                     "test_seeds_median": statistics.median(tested) if len(tested) == len(test_seeds) else None,
                     "no_worse": sum(v <= TARGET[1] for v in values)})
    return rows


def render(results: dict, sensors, test_seeds) -> list[str]:
    """The report's "Against ORB-SLAM3" section (no lines when no peer run has an ATE)."""
    rows = summarize(results, sensors, test_seeds)
    if not rows:
        return []
    lines = ["", "## Against ORB-SLAM3", "",
             "ATE ours / ORB-SLAM3's on the same seed's room (ORB-SLAM3 in its plain mode: no filter, no masks; "
             "each over the frames it tracked, monocular with Sim3 alignment); no worse is a ratio <= 1.", ""]
    table = [[r["sensor"], r["condition"], r["peer"], r["seeds"], f"{r['median']:.2f}",
              "-" if r["test_seeds_median"] is None else f"{r['test_seeds_median']:.2f}",
              f"{r['no_worse']}/{r['seeds']}"] for r in rows]
    return lines + report.markdown_table(["sensor", "ours", "ORB-SLAM3", "seeds", "median ours / theirs",
                                   "seeds 0-2 median", "seeds no worse"], table)


def speed_ratios(results: dict, out_dir: pathlib.Path | None = None) -> dict:
    """{(sensor, our condition): {seed: (whole-clip ms ratio or None, common-frames ms ratio or None)}},
    ours / ORB-SLAM3's on the same seed's room, for the seeds where both runs finished."""
    runs = {(r["sensor"], r["seed"], r["condition"]): r for r in results["records"] if not r.get("error")}
    out: dict = {}
    for (sensor, seed, condition), ours in runs.items():
        theirs = runs.get((sensor, seed, PEER_OF.get(condition))) if condition in PEER_OF else None
        if theirs is None:
            continue
        # As the full suite's pair tables: ours the track call with the labels' time, the peer's its track call.
        a, b = report._thread_ms(ours), report._thread_ms(theirs)
        whole = a / b if a and b else None
        pair = common_frames.run_pair_ms(ours, theirs, out_dir)
        common = pair["ours"] / pair["theirs"] if pair and pair["theirs"] > 0 else None
        if whole is not None or common is not None:
            out.setdefault((sensor, condition), {})[seed] = (whole, common)
    return out


def speed_summary(results: dict, sensors, test_seeds, out_dir: pathlib.Path | None = None,
                  by: dict | None = None) -> list[dict]:
    """Per sensor and our condition: seeds compared, median of each ratio, seeds 0-2 median (whole clip), seeds
    where ours is at most ORB-SLAM3's (whole clip). by: speed_ratios' answer, when the caller has it."""
    rows = []
    order = list(PEER_OF)
    by = speed_ratios(results, out_dir) if by is None else by
    for (sensor, condition), per_seed in sorted(by.items(), key=lambda kv: (sensors.index(kv[0][0]),
                                                                           order.index(kv[0][1]))):
        whole = [per_seed[s][0] for s in sorted(per_seed) if per_seed[s][0] is not None]
        common = [per_seed[s][1] for s in sorted(per_seed) if per_seed[s][1] is not None]
        tested = [per_seed[s][0] for s in test_seeds if s in per_seed and per_seed[s][0] is not None]
        rows.append({"sensor": sensor, "condition": condition, "peer": PEER_OF[condition], "seeds": len(per_seed),
                     "median": statistics.median(whole) if whole else None,
                     "common_median": statistics.median(common) if common else None, "common_seeds": len(common),
                     "test_seeds_median": statistics.median(tested) if len(tested) == len(test_seeds) else None,
                     "no_slower": sum(v <= TARGET[1] for v in whole), "compared": len(whole)})
    return rows


def render_speed(results: dict, sensors, test_seeds, out_dir: pathlib.Path | None = None) -> list[str]:
    """The report's speed section against ORB-SLAM3: paced sweeps only (none without a peer run)."""
    if not any(r.get("condition") in PEER_CONDITIONS for r in results["records"]):
        return []
    if not results["options"].get("realtime"):
        return ["", "Speed against ORB-SLAM3: not compared in a synchronous sweep (our track call waits for each "
                "keyframe's mapping there); `--realtime` runs both as a camera feeds them and compares it."]
    by = speed_ratios(results, out_dir)
    rows = speed_summary(results, sensors, test_seeds, by=by)
    if not rows:
        return []

    def f(v):
        return report._f(v, "{:.2f}", "-")

    lines = ["", "## Speed against ORB-SLAM3", "",
             "ms per frame ours / ORB-SLAM3's on the same seed's room, both fed at the sweep's rate (above): medians of "
             "each run's frames over "
             "the whole clip (ours the track call with the labels' time, theirs the track call) and over the "
             "frames both tracked; at most ORB-SLAM3's is a ratio <= 1.", ""]
    lines += report.markdown_table(
        ["sensor", "ours", "ORB-SLAM3", "seeds", "median ours / theirs", "seeds 0-2 median", "seeds no slower",
         "median over the frames both tracked"],
        [[r["sensor"], r["condition"], r["peer"], r["seeds"], f(r["median"]), f(r["test_seeds_median"]),
          f"{r['no_slower']}/{r['compared']}", f"{f(r['common_median'])} ({r['common_seeds']} seeds)"] for r in rows])
    for sensor in [s for s in sensors if any(k[0] == s for k in by)]:
        conditions = [c for c in PEER_OF if (sensor, c) in by]
        seeds = sorted({s for c in conditions for s in by[(sensor, c)]})
        lines += ["", f"{sensor}, seed by seed (whole clip / over the frames both tracked):", ""]
        lines += report.markdown_table(["seed"] + [f"{c} / {PEER_OF[c]}" for c in conditions],
                                [[s] + [" / ".join(f(v) for v in by[(sensor, c)][s]) if s in by[(sensor, c)] else "-"
                                        for c in conditions] for s in seeds])
    return lines
