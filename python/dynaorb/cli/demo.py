"""`make demo`: the built-in default job.

Renders two synthetic RGB-D sequences from one seed (the same room and camera
path, once without and once with moving people and a vehicle), runs SLAM on
each; on the dynamic one also with the `full` dynamic-object front end (fed
the sequence's label images, as a segmentation network would: it decides
itself which labelled objects move) and with the ground-truth dynamic masks;
then prints a table of tracked frames, ATE, time per frame and the share of
the image the front end marked moving, side by side.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import pathlib

from dynaorb.runner import RunOptions, run_dataset
from dynaorb.synth import SynthConfig, generate

log = logging.getLogger(__name__)


def _sequence(out: pathlib.Path, config: SynthConfig) -> pathlib.Path:
    """Renders once; reuses the folder while its synth.json matches the config."""
    meta = out / "synth.json"
    try:
        if json.loads(meta.read_text())["config"] == dataclasses.asdict(config):
            return out
    except (OSError, KeyError, TypeError, ValueError):
        pass
    log.info("rendering %s", out)
    from tqdm import tqdm

    generate(out, config, progress=lambda it: tqdm(it, desc=f"rendering {out.name}", unit="frame"))
    return out


@dataclasses.dataclass
class DemoRun:
    name: str
    tracked: int
    frames: int
    ate_m: float | None       # ATE RMSE (SE3), None when it could not be computed
    ms_per_frame: float       # median frame_total
    marked_moving: float | None  # the front end's median share of the image marked moving
    note: str = ""


def demo_runs(out: pathlib.Path, frames: int = 60, seed: int = 0) -> list[DemoRun]:
    """Renders the two sequences (or reuses them) and runs the four cases."""
    static = _sequence(out / "static", SynthConfig(sensor="rgbd", movers=0, frames=frames, seed=seed))
    dynamic = _sequence(out / "dynamic", SynthConfig(sensor="rgbd", movers=3, frames=frames, seed=seed))
    cases = [  # name, sequence, RunOptions' own fields
        ("static scene", static, {}),
        ("dynamic scene, no filter", dynamic, {}),
        ("dynamic scene, `full` front end", dynamic, {"dynamic": "full", "labels": str(dynamic / "labels")}),
        ("dynamic scene, ground-truth masks", dynamic, {"masks": str(dynamic / "dynamic_masks")}),
    ]
    runs = []
    for name, seq, extra in cases:
        folder = name.replace(" ", "_").replace(",", "").replace("`", "")
        stats = run_dataset(RunOptions(kind="tum", path=str(seq), out=str(out / "runs" / folder), progress=False,
                                       **extra))
        ate = stats.get("ate")
        summary = (stats.get("dynamic_filter") or {}).get("summary") or {}
        runs.append(DemoRun(name, stats["tracked_frames"], stats["frames"], ate["rmse"] if ate else None,
                            stats["stage_ms_median"].get("frame_total", float("nan")),
                            summary.get("dynamic_fraction_median"), "" if ate else stats.get("reason", "")))
    return runs


def format_demo(runs: list[DemoRun], header: str) -> str:
    head = ("run", "tracked", "ATE RMSE [m]", "ms/frame", "marked moving (median)", "note")
    rows = [(r.name, f"{r.tracked}/{r.frames}", f"{r.ate_m:.4f}" if r.ate_m is not None else "n/a",
             f"{r.ms_per_frame:.1f}", f"{100 * r.marked_moving:.0f} % of the image" if r.marked_moving is not None
             else "", r.note) for r in runs]
    widths = [max(len(str(r[k])) for r in rows + [head]) for k in range(len(head))]
    line = lambda r: "  ".join(str(v).ljust(w) for v, w in zip(r, widths)).rstrip()  # noqa: E731
    return "\n".join([header, line(head), line(["-" * w for w in widths])] + [line(r) for r in rows])


def run_demo(out: pathlib.Path, frames: int = 60, seed: int = 0) -> str:
    return format_demo(demo_runs(out, frames, seed),
                       f"dynaorb demo: synthetic RGB-D, {frames} frames, seed {seed} (outputs in {out})")
