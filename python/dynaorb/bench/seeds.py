"""`dynaorb bench --suite seeds`: the end-to-end accuracy targets over many synthetic seeds.

The end-to-end tests assert medians over seeds 0-2 (CI time). One seed's
ratio of two 2-5 mm ATEs moves by +-0.2 with small changes, and three seeds
miss whole failures: RGB-D seeds 6-10 once gave `full` 2-12x the static
error while seeds 0-2 gave 1.05-1.29. This suite renders, per sensor and
seed, the room without and with movers (what `dynaorb synth --movers 0|3
--frames 60 --seed S` writes) and runs each condition once, with
synchronous mapping (runs repeat, to rounding), or with `realtime` as a
camera delivers the frames: asynchronous mapping, paced at the recording's
rate (runs do not repeat; monocular tracking then makes fewer keyframes
than synchronously, where local mapping is idle at every frame: 24-39
against 39-53 of the 51-56 frames tracked):

  static  no movers, no filter: the reference;
  full    movers, the `full` preset with the label images;
  full_static
          no movers, the `full` preset with the label images: what the
          filter costs where nothing moves (not run unless asked for);
  masks   movers, the ground-truth dynamic masks kept out of tracking
          (SLAM core I's target: within 1.2x of static);
  off     movers, no filter: the problem (the filter's issue asks `off` to
          be at least 3x worse);
  peer_static, peer_movers
          ORB-SLAM3 on the rooms without and with movers (seeds_peer.py),
          not run unless asked for.

Each run is a child process (a crash is recorded, the sweep goes on).
Writes OUT/seeds.json (every run; rewritten after each, so a sweep stopped
part way keeps what it ran) and OUT/seeds.md: per sensor and seed the
ATEs and their ratios to static, and per sensor and condition the median
ratio, the worst seed and how many seeds meet the target.
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import datetime
import json
import os
import pathlib
import statistics

from dynaorb.bench import seeds_peer
from dynaorb.bench.build_info import build, core_fingerprint
from dynaorb.bench.suites import SYNTH_FRAMES, Sequence, ensure_rendered, synth_sequence

SENSORS = ("rgbd", "stereo", "mono")
MOVERS = 3
# condition: (movers, preset, label images, ground-truth masks)
CONDITIONS = {
    "static": (0, "off", False, False),
    "full": (MOVERS, "full", True, False),
    "full_static": (0, "full", True, False),
    "masks": (MOVERS, "off", False, True),
    "off": (MOVERS, "off", False, False),
}
# ratio to static each condition is held to: (comparison, bound); static is the reference.
TARGETS = {"full": ("<=", 1.2), "masks": ("<=", 1.2), "off": (">=", 3.0)}
FILTERED = ("full", "full_static")  # the conditions --preset runs
ALL_CONDITIONS = (*CONDITIONS, *seeds_peer.PEER_CONDITIONS)
TEST_SEEDS = (0, 1, 2)   # the seeds test/python/test_dynamic_e2e.py runs
RUN_TIMEOUT_S = 600.0


@dataclasses.dataclass
class SeedsOptions:
    out: str = "out/bench_seeds"
    seeds: tuple[int, ...] = tuple(range(12))
    sensors: tuple[str, ...] = SENSORS
    conditions: tuple[str, ...] = ("static", "full", "masks", "off")  # full_static and the peer when asked for
    # What the "full" and "full_static" conditions run: a preset name of config/dynamic/ or a preset YAML (a variant under test).
    preset: str = "full"
    jobs: int = 1                    # runs (and renders) at a time; the runs are synchronous, so repeatable
    # > 0: asynchronous mapping, the frames delivered at this many times the recording's rate by their
    # stamps (as users' runs; not repeatable); the peer conditions paced alike. 0: synchronous mapping.
    realtime: float = 0.0
    frames: int = SYNTH_FRAMES
    width: int = 640
    height: int = 480
    fx: float | None = None          # None: the renderer's default for the size
    synth_root: str | None = None    # cache of the rendered sequences (default OUT/synth)
    vocabulary: str = "default"
    timeout_s: float = RUN_TIMEOUT_S
    resume: bool = False             # reuse OUT/runs/... records written for the same spec
    peer_venv: str | None = None     # pyorbslam3's venv for the peer conditions (default: the peer's cache)
    # The core's options for every dynaorb run (not the peer's): RunOptions' tracker / mapping / loop
    # ({name: value}, dotted names for nested groups), e.g. a tracker value under test.
    tracker: dict | None = None
    mapping: dict | None = None
    loop: dict | None = None

    def validate(self) -> None:
        if not self.seeds:
            raise ValueError("seeds: at least one seed")
        bad = [s for s in self.sensors if s not in SENSORS]
        if bad or not self.sensors:
            raise ValueError(f"sensors: {bad or 'none given'}; choose from {', '.join(SENSORS)}")
        bad = [c for c in self.conditions if c not in ALL_CONDITIONS]
        if bad or "static" not in self.conditions:
            raise ValueError(f"conditions must include static and come from {', '.join(ALL_CONDITIONS)}"
                             + (f" (unknown: {', '.join(bad)})" if bad else ""))
        if self.jobs < 1:
            raise ValueError(f"jobs must be >= 1, got {self.jobs}")
        if self.realtime:
            from dynaorb.runner.pacing import Pacer

            Pacer(self.realtime)  # a rate that is not a finite positive number: ValueError
            if self.jobs > 1:
                raise ValueError(f"jobs must be 1 with realtime (paced runs side by side would take each "
                                 f"other's cores), got {self.jobs}")
        from dynaorb import core
        from dynaorb.runner.run import core_options

        for cls, values, what in ((core().TrackerOptions, self.tracker, "tracker"),
                                  (core().LocalMapperOptions, self.mapping, "local mapping"),
                                  (core().LoopCloserOptions, self.loop, "loop closing")):
            options = core_options(cls, values, what)  # an unknown name refused before any rendering
            if options is not None:
                options.validate()
        if any(c in FILTERED for c in self.conditions):
            from dynaorb.bench.suites import preset_applicability

            for sensor in self.sensors:  # an unknown preset (ValueError) or one the sensor cannot run
                why = preset_applicability(self.preset, sensor)
                if why is not None:
                    raise ValueError(f"--preset {self.preset}: {why}")


def parse_list(text: str) -> tuple[str, ...]:
    """'rgbd, stereo' -> ("rgbd", "stereo")."""
    return tuple(part.strip() for part in text.split(",") if part.strip())


def parse_seeds(text: str) -> tuple[int, ...]:
    """'12' -> 0..11; '3-5' -> 3, 4, 5; '0,4,9' -> those; ranges and lists combine ('0-2,7')."""
    text = text.strip()
    if text.isdigit():
        n = int(text)
        if n < 1:
            raise ValueError(f"--seeds {text}: a count must be >= 1 (one seed S alone: S-S)")
        return tuple(range(n))
    seeds: list[int] = []
    for part in text.split(","):
        lo, sep, hi = part.strip().partition("-")
        if not lo.isdigit() or (sep and not hi.isdigit()):
            raise ValueError(f"--seeds: {part!r} is not a seed, a range A-B or a count")
        first, last = int(lo), int(hi) if sep else int(lo)
        if last < first:
            raise ValueError(f"--seeds: empty range {part!r}")
        seeds += [s for s in range(first, last + 1) if s not in seeds]
    return tuple(seeds)


def movers(condition: str) -> int:
    """How many movers the condition's room has."""
    if condition in seeds_peer.PEER_CONDITIONS:
        return MOVERS if seeds_peer.PEER_CONDITIONS[condition] else 0
    return CONDITIONS[condition][0]


def _sequence(sensor: str, movers: int, seed: int, root: pathlib.Path, opts: SeedsOptions) -> Sequence:
    return synth_sequence(sensor, movers, root, frames=opts.frames, seed=seed, width=opts.width,
                          height=opts.height, fx=opts.fx)


def _thread_shares(opts: SeedsOptions) -> tuple[dict | None, dict | None]:
    """The mapping and loop options of a run: with several runs at a time
    (--jobs), each run's synchronous BAs get its share of the cores
    (ba_threads_synchronous / threads_synchronous, otherwise every core each)
    unless the options set them."""
    mapping, loop = opts.mapping, opts.loop
    if opts.jobs > 1:
        share = max(1, (os.cpu_count() or 1) // opts.jobs)
        mapping = {"ba_threads_synchronous": share, **(mapping or {})}
        loop = {"threads_synchronous": share, **(loop or {})}
    return mapping, loop


def _run(seq: Sequence, sensor: str, seed: int, condition: str, out: pathlib.Path, opts: SeedsOptions) -> dict:
    """One run of one condition (its record, also written to its folder)."""
    from dynaorb.bench.suite_runner import keep_record, reused_record, run_spec

    _, preset, labels, masks = CONDITIONS[condition]
    if condition in FILTERED:
        preset = opts.preset
    spec = {"kind": seq.kind, "path": seq.path, "sensor": sensor, "out": str(out), "dynamic": preset,
            "vocabulary": opts.vocabulary, "synchronous_mapping": not opts.realtime,
            "result": str(out / "result.json"), "core": core_fingerprint()}
    if opts.realtime:
        spec["realtime"] = opts.realtime
    if labels:
        spec["labels"] = seq.labels
    if masks:
        spec["masks"] = str(pathlib.Path(seq.path) / "dynamic_masks")
    mapping, loop = _thread_shares(opts)
    spec.update({k: v for k, v in (("tracker", opts.tracker), ("mapping", mapping), ("loop", loop)) if v})
    record = {"sensor": sensor, "seed": seed, "condition": condition, "out": str(out)}
    reused = reused_record(out, "spec.json", spec, opts.resume)
    if reused is not None:
        return reused
    child = run_spec(out, spec, opts.timeout_s)
    record["wall_s"] = child.wall_s
    result = out / "result.json"
    if child.ok and result.is_file():
        stats = json.loads(result.read_text())
        ate = stats.get("ate")
        record.update(ate_rmse=ate["rmse"] if ate else None, ate_reason=None if ate else stats.get("reason"),
                      align=stats.get("align"), tracked_fraction=stats.get("tracked_fraction"),
                      frames=stats.get("frames"), tracked_frames=stats.get("tracked_frames"),
                      # the track call with the labels' time, as the full suite's pair tables compare it
                      track_call_ms_median=stats.get("track_call_ms_median"),
                      track_call_plus_labels_ms_median=stats.get("track_call_plus_labels_ms_median"))
    else:
        record["error"] = (child.failure() or "no result written") + "\n" + child.log_tail()
    return keep_record(out, record)


def run_seeds(opts: SeedsOptions, progress=print) -> dict:
    """Renders what is missing, runs every sensor, seed and condition, writes seeds.json and seeds.md."""
    opts.validate()
    out = pathlib.Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    root = pathlib.Path(opts.synth_root) if opts.synth_root else out / "synth"
    rooms = sorted({movers(c) for c in opts.conditions})
    sequences = {(sensor, m, seed): _sequence(sensor, m, seed, root, opts)
                 for sensor in opts.sensors for seed in opts.seeds for m in rooms}
    missing = [s for s in sequences.values() if not (pathlib.Path(s.synthetic["out"]) / "synth.json").is_file()]
    if missing:
        progress(f"rendering {len(missing)} synthetic sequences (cached in {root})")
        with concurrent.futures.ProcessPoolExecutor(max_workers=opts.jobs) as pool:
            list(pool.map(ensure_rendered, missing))
    results = {"suite": "seeds", "started": datetime.datetime.now().isoformat(timespec="seconds"), "build": build(),
               "options": {k: v for k, v in dataclasses.asdict(opts).items() if k not in ("out", "resume")},
               "conditions": {c: dict(zip(("movers", "preset", "labels", "masks"),
                                          (CONDITIONS[c][0], opts.preset if c in FILTERED else CONDITIONS[c][1],
                                           *CONDITIONS[c][2:])))
                              if c in CONDITIONS else {"movers": movers(c), "system": "orbslam3"}
                              for c in opts.conditions},
               "targets": {c: TARGETS[c] for c in opts.conditions if c in TARGETS},
               "records": [], "finished": None}
    peer = seeds_peer.setup(opts.conditions, opts.peer_venv, opts.vocabulary, progress)
    results["peer"] = peer["status"] if peer else None
    jobs = [(sensor, seed, c) for sensor in opts.sensors for seed in opts.seeds for c in opts.conditions]

    def one(job):
        sensor, seed, condition = job
        seq = sequences[(sensor, movers(condition), seed)]
        run_out = out / "runs" / sensor / f"s{seed}" / condition
        if condition in seeds_peer.PEER_CONDITIONS:
            return seeds_peer.run(seq, sensor, seed, condition, run_out, peer, opts.timeout_s, opts.resume,
                                  opts.realtime)
        return _run(seq, sensor, seed, condition, run_out, opts)

    with concurrent.futures.ThreadPoolExecutor(max_workers=opts.jobs) as pool:
        for i, record in enumerate(pool.map(one, jobs), 1):
            progress(f"[{i}/{len(jobs)}] {record['sensor']} seed {record['seed']} {record['condition']}: "
                     + (f"ATE {record['ate_rmse'] * 1000:.2f} mm" if record.get("ate_rmse") is not None
                        else (record.get("error") or record.get("ate_reason") or "no ATE").splitlines()[0]))
            results["records"].append(record)
            _save(out, results)  # a sweep stopped part way keeps its runs ("finished" null; --resume goes on)
    results["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
    results["summary"] = summarize(results)
    _save(out, results)
    (out / "seeds.md").write_text(render(results, out))
    return results


def _save(out: pathlib.Path, results: dict) -> None:
    part = out / "seeds.json.part"
    part.write_text(json.dumps(results, indent=1))
    part.replace(out / "seeds.json")


def _meets(ratio: float, target: tuple[str, float]) -> bool:
    op, bound = target
    return ratio <= bound if op == "<=" else ratio >= bound


def _static_reference(condition: str) -> str | None:
    return None if condition == "static" or condition in seeds_peer.PEER_CONDITIONS else "static"


def ratios(results: dict, reference=_static_reference) -> dict:
    """{(sensor, condition): {seed: ATE / its reference run's ATE}} for the seeds where both have an ATE;
    reference(condition): the condition of that run on the same sensor and seed (None: no ratio). Default:
    our conditions over static."""
    ate = {(r["sensor"], r["seed"], r["condition"]): r.get("ate_rmse") for r in results["records"]}
    out: dict = {}
    for (sensor, seed, condition), value in ate.items():
        of = reference(condition)
        ref = ate.get((sensor, seed, of)) if of else None
        if value is not None and ref:
            out.setdefault((sensor, condition), {})[seed] = value / ref
    return out


def summarize(results: dict) -> list[dict]:
    """Per sensor and condition: seeds with a ratio, its median, the worst seed, seeds meeting the target,
    and the median over seeds 0-2 (what the end-to-end tests assert; None unless all three ran)."""
    rows = []
    by = ratios(results)
    targets = results["targets"]
    for (sensor, condition), per_seed in sorted(by.items(), key=lambda kv: (SENSORS.index(kv[0][0]), kv[0][1])):
        seeds = sorted(per_seed)
        values = [per_seed[s] for s in seeds]
        target = tuple(targets[condition]) if condition in targets else None
        worst_seed = (max if not target or target[0] == "<=" else min)(seeds, key=lambda s: per_seed[s])
        tested = [per_seed[s] for s in TEST_SEEDS if s in per_seed]
        rows.append({"sensor": sensor, "condition": condition, "seeds": len(seeds),
                     "median": statistics.median(values), "worst": per_seed[worst_seed], "worst_seed": worst_seed,
                     "test_seeds_median": statistics.median(tested) if len(tested) == len(TEST_SEEDS) else None,
                     "target": list(target) if target else None,
                     "meeting": sum(_meets(v, target) for v in values) if target else None,
                     "median_meets": _meets(statistics.median(values), target) if target else None})
    return rows


def _mapping_mode(realtime) -> str:
    if not realtime:
        return "synchronous mapping (repeatable)"
    return (f"asynchronous mapping with the frames delivered at {realtime:g}x the recording's rate "
            "(as a camera delivers them; runs do not repeat)")


def _mm(v) -> str:
    return "n/a" if v is None else f"{v * 1000:.2f}"


def render(results: dict, out_dir: pathlib.Path | None = None) -> str:
    """seeds.md; out_dir: the sweep's folder, where the speed table finds the runs' per-frame times when
    the recorded paths no longer lead there."""
    from dynaorb.bench.report import markdown_table

    opts = results["options"]
    n = len(opts["seeds"])
    preset = next((results["conditions"][c].get("preset") for c in FILTERED if c in results["conditions"]), None)
    preset = preset or "full"
    lines = [f"# Benchmark: seeds ({n} synthetic seed{'s' if n != 1 else ''} per sensor)", "",
             f"Started {results['started']}, finished {results['finished']}. Seeds "
             f"{', '.join(map(str, opts['seeds']))}; {opts['frames']} frames at {opts['width']}x{opts['height']}, "
             f"{MOVERS} movers against none; one run per condition, {_mapping_mode(opts.get('realtime'))}.", "",
             "Conditions: static = no movers, no filter (the reference); full = movers, the "
             f"`{preset}` preset with the label images; full_static = no movers, the same preset; masks = movers, "
             "the ground-truth dynamic masks kept out of tracking; off = movers, "
             "no filter" + ("; peer_static / peer_movers = ORB-SLAM3 on the room without / with the movers "
                            "(its own mapping threads)" if any(c in seeds_peer.PEER_CONDITIONS for c in
                                                                results["conditions"]) else "")
             + ". Ratios are ATE RMSE over the static run's on the same seed (each over the frames it "
             "tracked; monocular: Sim3 alignment); the seeds 0-2 median is what the end-to-end tests assert.", "", "## Summary", ""]
    rows = []
    for s in results.get("summary") or summarize(results):
        target = f"{s['target'][0]} {s['target'][1]:g}" if s["target"] else "-"
        rows.append([s["sensor"], s["condition"], target, s["seeds"], f"{s['median']:.2f}",
                     "-" if s["test_seeds_median"] is None else f"{s['test_seeds_median']:.2f}", f"{s['worst']:.2f} (seed {s['worst_seed']})",
                     "-" if s["meeting"] is None else f"{s['meeting']}/{s['seeds']}",
                     "-" if s["median_meets"] is None else ("met" if s["median_meets"] else "missed")])
    lines += markdown_table(["sensor", "condition", "target", "seeds", "median ratio", "seeds 0-2 median",
                             "worst", "seeds meeting", "median"], rows)
    by_run = {(r["sensor"], r["seed"], r["condition"]): r for r in results["records"]}
    conditions = [c for c in results["conditions"]]
    per = ratios(results)
    for sensor in [s for s in SENSORS if s in opts["sensors"]]:
        lines += ["", f"## {sensor}", ""]
        ours = [c for c in conditions if c != "static" and c in CONDITIONS]
        header = ["seed"] + [f"{c} [mm]" for c in conditions] + [f"{c} / static" for c in ours]
        header.append(f"frames tracked ({' / '.join(conditions)})")
        rows = []
        for seed in opts["seeds"]:
            row = [seed]
            for c in conditions:
                r = by_run.get((sensor, seed, c)) or {}
                row.append("failed" if r.get("error") else _mm(r.get("ate_rmse")))
            for c in ours:
                v = per.get((sensor, c), {}).get(seed)
                row.append("n/a" if v is None else f"{v:.2f}")
            runs = [by_run.get((sensor, seed, c)) or {} for c in conditions]
            frames = next((r["frames"] for r in runs if r.get("frames")), None)
            row.append(" / ".join("-" if r.get("tracked_frames") is None else str(r["tracked_frames"]) for r in runs)
                       + (f" of {frames}" if frames else ""))
            rows.append(row)
        lines += markdown_table(header, rows)
    lines += seeds_peer.render(results, SENSORS, TEST_SEEDS)
    lines += seeds_peer.render_speed(results, SENSORS, TEST_SEEDS, out_dir)
    failed = [r for r in results["records"] if r.get("error")]
    if failed:
        lines += ["", "## Failed runs", ""]
        lines += [f"- {r['sensor']} seed {r['seed']} {r['condition']}: {r['error'].splitlines()[0]}" for r in failed]
    return "\n".join(lines) + "\n"
