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
"""
from __future__ import annotations

import pathlib
import statistics

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
    from dynaorb.bench.report import markdown_table

    rows = summarize(results, sensors, test_seeds)
    if not rows:
        return []
    lines = ["", "## Against ORB-SLAM3", "",
             "ATE ours / ORB-SLAM3's on the same seed's room (ORB-SLAM3 in its plain mode: no filter, no masks; "
             "each over the frames it tracked, monocular with Sim3 alignment); no worse is a ratio <= 1.", ""]
    table = [[r["sensor"], r["condition"], r["peer"], r["seeds"], f"{r['median']:.2f}",
              "-" if r["test_seeds_median"] is None else f"{r['test_seeds_median']:.2f}",
              f"{r['no_worse']}/{r['seeds']}"] for r in rows]
    return lines + markdown_table(["sensor", "ours", "ORB-SLAM3", "seeds", "median ours / theirs",
                                   "seeds 0-2 median", "seeds no worse"], table)
