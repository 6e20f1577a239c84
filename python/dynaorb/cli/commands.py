"""The subcommands behind `dynaorb`; each a thin layer over a library module."""
from __future__ import annotations

import json
import pathlib


def cmd_run(args) -> int:
    from dynaorb.runner import RunOptions, run_dataset

    stats = run_dataset(RunOptions(kind=args.kind, path=args.path, sensor=args.sensor, config=args.config,
                                   out=args.out, dynamic=args.dynamic, masks=args.masks,
                                   progress=not args.quiet,
                                   synchronous_mapping=not args.async_mapping))
    print(summary_line(args.out, stats))
    return 0


def summary_line(out, stats: dict) -> str:
    ate = stats.get("ate")
    ate_text = f"ATE RMSE {ate['rmse']:.4f} m" if ate else f"ATE n/a ({stats.get('reason', '')})"
    total = stats["stage_ms_median"].get("frame_total")
    ms = f"{total:.1f} ms/frame median (tracking thread)" if total is not None else "no frame processed"
    return (f"{stats['tracked_frames']}/{stats['frames']} frames tracked, {ate_text}, {ms}; "
            f"written to {out}")


def cmd_eval(args) -> int:
    from dynaorb.evaluation import evaluate

    result = evaluate(args.gt, args.est, align=args.align, rpe_delta=args.rpe, rpe_unit=args.rpe_unit,
                      max_diff=args.max_diff, plot_dir=args.plot)
    if args.json:
        print(json.dumps(result.to_dict(), indent=2))
    else:
        print(result.table())
        for p in result.plots:
            print(f"plot: {p}")
    return 0


def cmd_synth(args) -> int:
    from dynaorb.synth import SynthConfig, generate

    progress = None
    if not args.quiet:
        from tqdm import tqdm

        progress = lambda it: tqdm(it, desc="rendering", unit="frame")  # noqa: E731
    summary = generate(args.out, SynthConfig(sensor=args.sensor, movers=args.movers, frames=args.frames,
                                             seed=args.seed, width=args.width, height=args.height,
                                             textures=args.textures), progress=progress)
    frac = summary["dynamic_pixel_fraction"]
    print(f"{args.frames} {args.sensor} frames in {summary['sequence']} ({summary['layout']} layout); "
          f"moving objects cover {100 * frac['mean']:.1f} % of the image on average "
          f"(max {100 * frac['max']:.1f} %); path {summary['path_length_m']:.2f} m")
    return 0


def cmd_demo(args) -> int:
    from dynaorb.cli.demo import run_demo

    print(run_demo(pathlib.Path(args.out), frames=args.frames, seed=args.seed))
    return 0


def cmd_config(args) -> int:
    from dynaorb import core

    provider = core().open_dataset(args.kind, args.path, args.sensor)
    settings = provider.default_settings()
    settings.save(args.output)
    print(settings.summary())
    return 0
