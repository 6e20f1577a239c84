"""The subcommands behind `dynaorb`; each a thin layer over a library module."""
from __future__ import annotations

import dataclasses
import json
import pathlib
import sys


def cmd_run(args) -> int:
    from dynaorb.runner import RunOptions, run_dataset

    stats = run_dataset(RunOptions(kind=args.kind, path=args.path, sensor=args.sensor, config=args.config,
                                   **_runner_fields(args)))
    print(summary_line(args.out, stats))
    return _exit_status(stats)


def _exit_status(stats: dict) -> int:
    """0, or 130 (as a shell reports Ctrl-C) for a run stopped by Ctrl-C: its outputs are written, but partial."""
    return 130 if stats.get("interrupted") else 0


def _runner_fields(args) -> dict:
    """What main._runner_args reads, by RunOptions' field names (`run` and `bag run`)."""
    return dict(out=args.out, frames=args.frames, dynamic=args.dynamic, masks=args.masks, labels=args.labels,
                save_masks=args.save_masks, labels_delay=args.labels_delay,
                propagate_labels=not args.no_label_propagation, vocabulary=args.vocabulary,
                segment=args.segment, segment_mode=args.segment_mode, segment_threads=args.segment_threads,
                segment_nice=args.segment_nice, max_mask_age=args.max_mask_age, progress=not args.quiet,
                synchronous_mapping=not args.async_mapping, realtime=args.realtime,
                background_nice=args.background_nice, save_map=args.save_map, load_map=args.load_map,
                localization=args.localization, tracker=key_values(args.tracker, "--tracker"),
                mapping=key_values(args.mapping, "--mapping"), loop=key_values(args.loop, "--loop"))


def key_values(items: list[str], flag: str) -> dict:
    """KEY=VALUE strings -> {KEY: float VALUE, or True / False for `true` /
    `false` (a switch such as --tracker motion_vo_points=false)}; ValueError
    names a malformed one."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        switch = value.strip().lower()
        if switch in ("true", "false"):
            out[key.strip()] = switch == "true"
        else:
            try:
                out[key.strip()] = float(value)
            except ValueError:
                sep = ""
        if not sep or not key.strip():
            raise ValueError(f"{flag} {item!r}: expected KEY=NUMBER or KEY=true / false")
    return out


def summary_line(out, stats: dict) -> str:
    ate = stats.get("ate")
    ate_text = f"ATE RMSE {ate['rmse']:.4f} m" if ate else f"ATE n/a ({stats.get('reason', '')})"
    total = stats["stage_ms_median"].get("frame_total")
    ms = f"{total:.1f} ms/frame median (tracking thread)" if total is not None else "no frame processed"
    dyn = stats.get("dynamic_filter")
    dyn_text = ""
    if dyn and dyn["summary"]["frames"]:
        d = dyn["summary"]
        dyn_text = (f"; dynamic filter ({', '.join(dyn['stages'])}): {d['stage_ms_median'].get('dynamic', 0):.1f} ms, "
                    f"{d['dynamic_keypoints_median']:.0f} dynamic keypoints, "
                    f"{100 * d['dynamic_fraction_median']:.1f} % of the image (medians)")
    stopped = stats.get("interrupted")
    run = stopped["frames_run"] if stopped else stats["frames"]
    frames = f"{stats['tracked_frames']}/{run} frames tracked"
    if stopped:
        frames += f" (interrupted: {run} of {stats['frames']} frames run)"
    return f"{frames}, {ate_text}, {ms}{dyn_text}; written to {out}"


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


def cmd_models_list(args) -> int:
    from dynaorb.segmentation import CATALOG, DEFAULT_MODEL, resolve_model

    for name, entry in CATALOG.items():
        try:
            where = str(resolve_model(name, args.cache))
        except FileNotFoundError:
            where = "not installed"
        default = " (default)" if name == DEFAULT_MODEL else ""
        print(f"{name}{default}: {entry.note}\n    {where}")
    return 0


def cmd_models_fetch(args) -> int:
    from dynaorb.segmentation import fetch

    for m in fetch(args.names, from_dir=args.from_dir, cache=args.cache, force=args.force,
                   progress=not args.quiet):
        print(f"{m.name}: {m.model} ({m.backend}; {m.how})")
    return 0


def cmd_segment(args) -> int:
    from dynaorb.segmentation import Segmenter, resolve_model
    from dynaorb.segmentation.offline import segment_sequence

    summary = segment_sequence(args.kind, args.path, Segmenter(resolve_model(args.model), threads=args.threads),
                               args.out, overwrite=args.overwrite, progress=not args.quiet)
    ms = summary["ms_median"]
    print(f"{summary.get('segmented', 0)} frames segmented, {summary.get('cached', 0)} already cached, "
          f"{summary.get('unreadable', 0)} unreadable"
          + (f"; {ms:.0f} ms/frame median" if ms else "") + f"; labels in {summary['out']}")
    return 0


def cmd_bench(args) -> int:
    out = pathlib.Path(args.out)
    if args.report_only or (args.readme and args.suite is None):
        from dynaorb.bench import report

        if args.report_only:
            print(f"report: {report.write(report.load(out), out)}")
        if args.readme:
            _write_readme(out)
        return 0
    if args.realtime and args.suite not in ("quick", "full", "long", "seeds"):
        print("dynaorb bench: --realtime paces the quick, full, long and seeds suites' runs; the segmentation "
              "suite times the network", file=sys.stderr)
        return 2
    if (args.only or args.presets) and args.suite not in ("quick", "full", "long"):
        print("dynaorb bench: --only and --presets pick clips and presets of the quick, full and long suites "
              "(the seeds suite has --sensors, --conditions and --preset)", file=sys.stderr)
        return 2
    if args.suite in ("quick", "full", "long"):
        from dynaorb.bench.suite_runner import BenchOptions, run_suite
        from dynaorb.bench.seeds import parse_list
        from dynaorb.bench.suites import SelectionError
        from dynaorb.runner.pacing import Pacer

        if args.realtime:
            try:
                Pacer(args.realtime)  # a bad rate refused before any run
            except ValueError as exc:
                print(f"dynaorb bench: {exc}", file=sys.stderr)
                return 2
        try:
            run_suite(BenchOptions(suite=args.suite, out=args.out, runs=args.runs or 3, peer=not args.no_peer,
                                   peer_venv=args.peer_venv, segment_model=_bench_network(args),
                                   resume=args.resume, realtime=args.realtime, synth_root=args.synth_root,
                                   only=parse_list(args.only or "") or None,
                                   presets=parse_list(args.presets or "") or None))
        except SelectionError as exc:  # --only / --presets naming what the suite does not have
            print(f"dynaorb bench: {exc}", file=sys.stderr)
            return 2
        print((out / "report.md").read_text())
        if args.readme:
            _write_readme(out)
        return 0
    if args.suite == "seeds":
        from dynaorb.bench.seeds import SeedsOptions, parse_list, parse_seeds, run_seeds

        try:
            opts = SeedsOptions(out=args.out, seeds=parse_seeds(args.seeds), jobs=args.jobs, resume=args.resume,
                                realtime=args.realtime,
                                sensors=parse_list(args.sensors), conditions=parse_list(args.conditions),
                                preset=args.preset, synth_root=args.synth_root, peer_venv=args.peer_venv,
                                tracker=key_values(args.tracker, "--tracker") or None,
                                mapping=key_values(args.mapping, "--mapping") or None,
                                loop=key_values(args.loop, "--loop") or None)
            opts.validate()
        except ValueError as exc:
            print(f"dynaorb bench: {exc}", file=sys.stderr)
            return 2
        run_seeds(opts)
        print((out / "seeds.md").read_text())
        return 0
    return _bench_segmentation(args)


def _model_folders(args) -> list[pathlib.Path]:
    """Where the bench looks for segmentation models: --models, else ../shared/models/segmentation (when
    the shared folder is found), then the cache of `dynaorb models fetch`."""
    from dynaorb.segmentation import cache_dir
    from dynaorb.synth.textures import default_texture_dir

    if args.models:
        return [pathlib.Path(args.models)]
    data = default_texture_dir()
    return ([data.parent / "models" / "segmentation"] if data is not None else []) + [cache_dir()]


def _bench_network(args) -> str | None:
    """The segmentation model the quick/full suites run on sequences without label images: --model, else
    the dm05 PASCAL model of --models (default ../shared/models/segmentation, else the cache); None with
    --no-network or when there is none (the report then says the semantic stage saw no labels)."""
    if args.no_network:
        return None
    if args.model:
        return args.model
    for folder in _model_folders(args):
        for name in ("deeplabv3_mnv2_dm05_pascal_quant.onnx", "deeplabv3_mnv2_dm05_pascal_quant.tflite"):
            if (folder / name).is_file():
                return str(folder / name)
    return None


def _write_readme(out: pathlib.Path) -> None:
    from dynaorb.bench.readme import update_readme

    readme = pathlib.Path(__file__).resolve().parents[3] / "README.md"
    update_readme(readme, out)
    print(f"README Results section written from {out / 'results.json'} into {readme}")


def _bench_segmentation(args) -> int:
    from dynaorb.bench import segmentation
    from dynaorb.segmentation import cache_dir
    from dynaorb.synth.textures import default_texture_dir

    data = default_texture_dir()
    if data is None:
        raise FileNotFoundError("the shared data folder was not found (set DYNAORB_SHARED)")
    models = next((f for f in _model_folders(args) if f.is_dir()), cache_dir())
    segmentation.run(args.out, str(models), str(data), runs=args.runs or 10,
                     sequence=tuple(args.sequence) if args.sequence else None, model=args.model)
    print((pathlib.Path(args.out) / "segmentation.md").read_text())
    return 0


def cmd_vocab_train(args) -> int:
    import time

    from dynaorb import vocab

    start = time.perf_counter()
    vocabulary = vocab.train(args.images, k=args.k, L=args.L, seed=args.seed, config=args.config,
                             max_images=args.max_images, progress=not args.quiet)
    out = vocab.save(vocabulary, args.output)
    print(f"{vocabulary.size} words (k={vocabulary.k}, L={vocabulary.L}) in "
          f"{time.perf_counter() - start:.1f} s -> {out}")
    return 0


def cmd_vocab_default(args) -> int:
    from dynaorb.vocab import build_default

    print(build_default(force=args.force))
    return 0


def cmd_bag_from_dataset(args) -> int:
    from dynaorb.ros.bag import BagWriteOptions, write_dataset_bag

    summary = write_dataset_bag(BagWriteOptions(kind=args.kind, path=args.path, out=args.output, sensor=args.sensor,
                                                depth_encoding=args.depth_encoding, labels=args.labels,
                                                stamp_offset=args.stamp_offset, max_frames=args.max_frames,
                                                image_transport=args.image_transport, image_format=args.image_format,
                                                progress=not args.quiet))
    topics = ", ".join(f"{role} {topic}" for role, topic in summary["topics"].items())
    print(f"{summary['frames']} frames ({summary['sensor']}) written to {args.output}: {topics}"
          + (f"; {summary['labels']} label images" if args.labels else "")
          + f"; sidecars: {', '.join(v for k, v in summary['files'].items() if k != 'bag')}")
    return 0


def _topics(args) -> dict | None:
    topics = {}
    for item in args.topic:
        role, sep, topic = item.partition("=")
        if not sep or not topic:
            raise ValueError(f"--topic {item!r}: expected ROLE=TOPIC")
        topics[role] = topic
    return topics or None


def _ground_truth_tf(args) -> tuple[str, str] | None:
    if not args.ground_truth_tf:
        return None
    parent, sep, child = args.ground_truth_tf.partition(":")
    if not sep or not parent or not child:
        raise ValueError(f"--ground-truth-tf {args.ground_truth_tf!r}: expected PARENT:CHILD")
    return parent, child


def _bag_inputs(args) -> dict:
    """What main._bag_input_args reads, by the names BagRunOptions, BagToDatasetOptions and bag_info take."""
    return dict(config=args.config, sensor=args.sensor, topics=_topics(args), max_diff=args.max_diff,
                ground_truth=args.ground_truth, ground_truth_topic=args.ground_truth_topic,
                ground_truth_tf=_ground_truth_tf(args), use_labels=not args.no_labels)


def cmd_bag_run(args) -> int:
    from dynaorb.ros.bag import BagRunOptions, run_bag

    runner = _runner_fields(args)
    # BagRunOptions' own fields, the rest as its runner options.
    own = {f.name for f in dataclasses.fields(BagRunOptions)}
    stats = run_bag(BagRunOptions(bag=args.bag, **_bag_inputs(args), **{k: v for k, v in runner.items() if k in own},
                                  runner={k: v for k, v in runner.items() if k not in own}))
    print(summary_line(args.out, stats))
    return _exit_status(stats)


def cmd_bag_info(args) -> int:
    import json

    from dynaorb.ros.bag.info import bag_info, format_info

    info = bag_info(args.bag, **_bag_inputs(args))
    print(json.dumps(info, indent=2) if args.json else format_info(info))
    return 0


def cmd_bag_to_dataset(args) -> int:
    from dynaorb.ros.bag import BagToDatasetOptions, bag_to_dataset

    s = bag_to_dataset(BagToDatasetOptions(bag=args.bag, out=args.output, **_bag_inputs(args),
                                           ground_truth_max_gap=args.ground_truth_max_gap, overwrite=args.overwrite,
                                           progress=not args.quiet))
    gt = s["ground_truth"]
    extra = [f"{s['labels']} label images"] if s["labels"] else []
    if s["unreadable"]:
        extra.append(f"{s['unreadable']} unreadable frames skipped")
    if gt["poses"]:
        extra.append(f"ground truth {gt['poses']} poses"
                     + (f" (KITTI poses for {gt['kitti_poses']} frames)" if "kitti_poses" in gt else ""))
    if s["settings_from_camera_info"]:
        extra.append("settings from the bag's camera_info")
    print(f"{s['frames']} frames ({s['sensor']}) written to {s['files']['sequence']} in {s['layout'].upper()}'s "
          f"layout" + "".join(f"; {e}" for e in extra))
    print(f"run it: {s['run']}")
    return 0
