"""`dynaorb run`: iterate a dataset through the core and write what came out.

Writes OUT/trajectory.tum (and trajectory.kitti for KITTI), OUT/groundtruth.tum
when the dataset has ground truth, OUT/map_points.ply (the sparse map) and
OUT/stats.json: frames, tracked frames, skipped and rejected frames with
reasons, per-stage median ms (per frame for the tracking thread, per keyframe
for local mapping), fps, map size, and ATE / RPE against the ground truth when
enough frames were tracked.

With a dynamic-object front-end preset (--dynamic, config/dynamic/*.yaml) the
stats also hold, per frame, the dynamic keypoint count, the dynamic share of
the image, each stage's ms and its report, with medians in a summary
(stats["dynamic_filter"]); --save-masks writes each frame's dynamic mask.
"""
from __future__ import annotations

import collections
import dataclasses
import json
import logging
import pathlib
import statistics
import time

import numpy as np

from dynaorb import core
from dynaorb.image_files import write_image
from dynaorb.runner.frames import frame_file_name, frame_range, readable_frames
from dynaorb.runner.interrupt import StopOnInterrupt
from dynaorb.runner.label_delay import DelayedLabels
from dynaorb.runner.masks import LabelFolder, MaskFolder
from dynaorb.runner.pacing import Pacer
from dynaorb.segmentation.labels import PASCAL_VOC_MOVABLE
from dynaorb.segmentation.priority import DEFAULT_NICE

log = logging.getLogger(__name__)

REPO = pathlib.Path(__file__).resolve().parents[3]
# Dynamic-object front-end presets: config/dynamic/<name>.yaml.
PRESET_DIR = REPO / "config" / "dynamic"


def dynamic_presets() -> tuple[str, ...]:
    """Names of the presets in config/dynamic/."""
    return tuple(sorted(p.stem for p in PRESET_DIR.glob("*.yaml")))


DYNAMIC_MODES = dynamic_presets()


def resolve_dynamic(spec: str | None) -> pathlib.Path | None:
    """The preset file for a preset name or a file path; None for off / None."""
    if spec is None:
        return None
    path = pathlib.Path(spec)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return path
    preset = PRESET_DIR / f"{spec}.yaml"
    if preset.is_file():
        return preset
    raise ValueError(f"unknown dynamic mode {spec!r} (presets: {', '.join(dynamic_presets())}; "
                     "or a preset YAML file)")


@dataclasses.dataclass
class RunOptions:
    kind: str
    path: str
    sensor: str | None = None
    config: str | None = None
    out: str = "out/run"
    # Dynamic-object front end: a preset name (config/dynamic/: off, stdyn, dm,
    # ddl, li, full) or a preset YAML file.
    dynamic: str = "off"
    # Label images (class ids) named like the frames, for the filter's semantic
    # stage: a `dynaorb segment` folder (labels.json) or e.g. a synthetic labels/.
    labels: str | None = None
    # Emulate a segmentation network this many frames behind the camera on the
    # label folder (runner/label_delay.py; 0: every frame its own labels). The
    # older labels (these, and --segment's asynchronous ones) are moved by
    # optical flow unless propagate_labels is False.
    labels_delay: int = 0
    propagate_labels: bool = True
    save_masks: str | None = None   # the filter's dynamic mask per frame, as PNG named like the frame
    # Exclusion masks named like the frames (ground-truth masks, a mask cache): kept out of tracking.
    masks: str | None = None
    # Bag-of-words vocabulary (relocalisation, loop closing, reference-keyframe
    # matching): "default" (dynaorb's own, built and cached on first use), "none",
    # a file (binary or ORBvoc.txt), or a dynaorb.core().Vocabulary object.
    vocabulary: object = "default"
    # In-process segmentation: a model file or catalog name (see `dynaorb models`);
    # its movable classes are masked. Exclusive with masks.
    segment: str | None = None
    segment_mode: str = "async"
    segment_threads: int = 1     # leaves the other core of a 2-core machine to tracking
    # async: the network thread's nice above the tracking thread's (0-19): on
    # a busy machine tracking gets the cores first, the network what is left.
    segment_nice: int = DEFAULT_NICE
    max_mask_age: int = 30
    progress: bool = True
    # Only these frames of the sequence: "START:END" (frame numbers from 0, END
    # not included; either may be left out, as "500:" or ":300"), or a
    # (start, end) pair. None: all.
    frames: object = None
    # Map each keyframe before tracking the next frame: repeatable runs. False
    # runs local mapping concurrently, as a live camera would.
    synchronous_mapping: bool = True
    # Deliver the frames at this multiple of the recording's rate (their
    # stamps), as a live camera or `rosbag play` would; 0: as fast as tracking
    # takes them. What a concurrent local mapping (synchronous_mapping False)
    # gets on a live camera: the time between frames (see runner/pacing.py).
    realtime: float = 0.0
    # Nice value of the local mapping, loop closing and global BA threads above
    # the process's (0-19): tracking gets the CPU first when the cores are
    # busy. None: the core's default (10).
    background_nice: int | None = None
    save_map: str | None = None     # the map written here after the run
    load_map: str | None = None     # start from this saved map (needs a vocabulary)
    localization: bool = False      # localisation only: no new keyframes or map points
    # Tracking options by name (_core.TrackerOptions fields, e.g.
    # {"mono_init_feature_factor": 5, "mono_init_feature_frames": 40}); the rest keep their defaults.
    tracker: dict | None = None
    # Local mapping's and loop closing's options the same way
    # (_core.LocalMapperOptions, _core.LoopCloserOptions fields, e.g.
    # {"neighbors_stereo": 15}, {"ransac.chi2": 7.8}).
    mapping: dict | None = None
    loop: dict | None = None
    # A provider object to run instead of opening kind/path (e.g. a
    # dynaorb.ros.bag.BagProvider); frames that carry `labels` (class ids)
    # get the mask of movable_ids when no other mask source is given.
    provider: object | None = None
    movable_ids: tuple = PASCAL_VOC_MOVABLE


# Stages of the tracking thread (summed into "frame_total"; "dynamic" is the
# whole dynamic filter, its parts are "dynamic.<stage>"); the others are local
# mapping's, reported per keyframe.
FRAME_STAGES = ("preprocess", "dynamic", "extract", "stereo_matching", "tracking")


# Synchronous mapping maps each keyframe in full before the next frame: on a
# long sequence local mapping can take most of the run (the 1500-frame
# synthetic stereo walk of `dynaorb bench --suite long`: 2.6-2.8 min, 9-10
# fps on 2 cores; 63 fps with --async-mapping).
SYNC_HINT_MIN_WALL_S = 30.0   # runs shorter than this are not worth a hint
SYNC_HINT_SHARE = 0.5         # local mapping's share of the run's wall time above which it is given


def _hint_async_mapping(opts: RunOptions, frame_records: list, wall: float) -> None:
    if not opts.synchronous_mapping or wall < SYNC_HINT_MIN_WALL_S:
        return
    mapping_s = sum(r["stage_ms"].get("local_mapping", 0.0) for r in frame_records) / 1000.0
    if mapping_s > SYNC_HINT_SHARE * wall:
        log.info("local mapping took %.0f s of the run's %.0f s: with synchronous mapping (the default, repeatable) "
                 "each keyframe is mapped before the next frame; --async-mapping (RunOptions."
                 "synchronous_mapping=False) maps beside tracking, as a live camera runs", mapping_s, wall)


def _settings(provider, config: str | None):
    if config:
        return core().Settings.load(config)
    return provider.default_settings()


def _median_stages(per_frame: list[dict]) -> dict:
    stages = collections.defaultdict(list)
    for ms in per_frame:
        for k, v in ms.items():
            stages[k].append(v)
        stages["frame_total"].append(sum(v for k, v in ms.items() if k in FRAME_STAGES))
    return {k: statistics.median(v) for k, v in stages.items()}


def write_ply(path: pathlib.Path, points) -> None:
    """ASCII PLY of an (N, 3) array of points."""
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\n")
        f.write(f"element vertex {len(points)}\nproperty float x\nproperty float y\nproperty float z\n")
        f.write("end_header\n")
        for x, y, z in points:
            f.write(f"{x:.6f} {y:.6f} {z:.6f}\n")


def _write_segments(system, out: pathlib.Path, main_stamps) -> list[dict]:
    """One entry per map the frames were tracked in (main_stamps: those of
    system.trajectory(), in trajectory.tum); with more than one map, each
    map's poses go to OUT/trajectory_map<K>.tum as well."""
    segments = system.trajectory_segments()
    maps = []
    for index, stamps, poses in segments:
        entry = {"map": int(index), "frames": len(stamps), "first_stamp": float(stamps[0]),
                 "last_stamp": float(stamps[-1]),
                 "in_trajectory_tum": len(stamps) == len(main_stamps) and bool(np.all(stamps == main_stamps))}
        if len(segments) > 1:
            name = f"trajectory_map{index}.tum"
            core().write_tum(str(out / name), stamps, poses)
            entry["file"] = name
        maps.append(entry)
    return maps


def _evaluate(provider, stamps, poses, sensor: str, out: pathlib.Path) -> dict:
    gt_stamps, gt_poses = provider.ground_truth()
    if len(gt_stamps) == 0:
        return {"ate": None, "reason": "dataset has no ground truth"}
    core().write_tum(str(out / "groundtruth.tum"), gt_stamps, gt_poses)
    if len(stamps) < 3:
        return {"ate": None, "reason": f"only {len(stamps)} frames tracked"}
    from evo.core.trajectory import PoseTrajectory3D

    from dynaorb.evaluation import evaluate

    align = "sim3" if sensor == "mono" else "se3"
    try:
        result = evaluate(PoseTrajectory3D(poses_se3=list(gt_poses), timestamps=gt_stamps),
                          PoseTrajectory3D(poses_se3=list(poses), timestamps=stamps),
                          align=align, rpe_delta=1.0, rpe_unit="frames")
    except ValueError as exc:
        return {"ate": None, "reason": str(exc)}
    stats = {"ate": result.ate, "rpe_trans": result.rpe_trans, "rpe_rot": result.rpe_rot,
             "align": align, "matched_poses": result.matched_poses}
    # Drift per distance travelled, in %, over segments of a tenth of the path:
    # the short clips here are far below KITTI's 100-800 m segments.
    length = float(np.sum(np.linalg.norm(np.diff(gt_poses[:, :3, 3], axis=0), axis=1)))
    delta = float(f"{length / 10.0:.2g}") if length > 0 else 0.0
    if delta <= 0:
        return stats
    try:
        per_m = evaluate(PoseTrajectory3D(poses_se3=list(gt_poses), timestamps=gt_stamps),
                         PoseTrajectory3D(poses_se3=list(poses), timestamps=stamps),
                         align=align, rpe_delta=delta, rpe_unit="m")
        stats["rpe_percent"] = per_m.rpe_percent
        stats["rpe_delta_m"] = delta
    except ValueError as exc:
        stats["rpe_percent"] = None
        stats["rpe_percent_reason"] = str(exc)
    return stats


def _semantic(opts: RunOptions):
    """(Segmenter, SemanticMasks) for in-process segmentation, or (None, None)."""
    if not opts.segment:
        return None, None
    if opts.masks:
        raise ValueError("give either a mask folder (--masks) or a segmentation model (--segment), not both")
    from dynaorb.segmentation import SemanticMasks, SemanticOptions, Segmenter, resolve_model

    segmenter = Segmenter(resolve_model(opts.segment), threads=opts.segment_threads)
    return segmenter, SemanticMasks(segmenter, SemanticOptions(mode=opts.segment_mode,
                                                                max_age_frames=opts.max_mask_age,
                                                                propagate=opts.propagate_labels,
                                                                classes=tuple(int(i) for i in segmenter.card.movable),
                                                                nice=opts.segment_nice))


def _vocabulary(spec):
    """A Vocabulary object, or None for spec None / "none"."""
    if spec is None or (isinstance(spec, str) and spec == "none"):
        return None
    if not isinstance(spec, (str, pathlib.Path)):
        return spec  # already a Vocabulary
    if spec == "default":
        from dynaorb.vocab import build_default, default_vocabulary_path

        if not default_vocabulary_path().is_file():
            log.info("building the default vocabulary (once, about a minute): dynaorb vocab default")
        spec = str(build_default())
    if not pathlib.Path(spec).is_file():
        raise FileNotFoundError(f"{spec}: vocabulary file does not exist")
    return core().Vocabulary.load(spec)


def _dynamic_options(_core, opts: RunOptions):
    """(preset path, DynamicFilterOptions) or (None, None) when off."""
    path = resolve_dynamic(opts.dynamic)
    options = _core.DynamicFilterOptions.load(str(path)) if path else None
    return path, options


def _median(values):
    return statistics.median(values) if values else None


def _spread(values):
    """Median, mean and maximum of per-frame values (None without any)."""
    if not values:
        return None
    return {"median": statistics.median(values), "mean": statistics.fmean(values), "max": max(values)}


# Per-frame values of work done for the filter on a worker thread, beside the
# stages (not inside their times): the motion cues' corners of the next
# frame, detected ahead with their sub-pixel refinement, and their stereo
# depth; the candidate regions cut beside the motion cues.
# "motion_cues.<part>_ahead_ms" -> "<part>_ahead".
_WORKER_PREFIX, _WORKER_SUFFIX = "motion_cues.", "_ahead_ms"


def _dynamic_summary(per_frame: list[dict]) -> dict:
    """Medians over the frames the filter ran on (the worker's over the
    frames that used its work)."""
    stage_ms = collections.defaultdict(list)
    worker_ms = collections.defaultdict(list)
    for f in per_frame:
        for k, v in f["stage_ms"].items():
            stage_ms[k].append(v)
        for k, v in f.get("values", {}).items():
            if k.startswith(_WORKER_PREFIX) and k.endswith(_WORKER_SUFFIX):
                worker_ms[k[len(_WORKER_PREFIX):-len("_ms")]].append(v)
    return {
        "frames": len(per_frame),
        "dynamic_keypoints_median": _median([f["dynamic_keypoints"] for f in per_frame]),
        "dynamic_keypoints_total": sum(f["dynamic_keypoints"] for f in per_frame),
        "dynamic_fraction_median": _median([f["dynamic_fraction"] for f in per_frame]),
        "dynamic_fraction_mean": (sum(f["dynamic_fraction"] for f in per_frame) / len(per_frame)
                                  if per_frame else None),
        "stage_ms_median": {k: statistics.median(v) for k, v in sorted(stage_ms.items())},
        "worker_ms_median": {k: statistics.median(v) for k, v in sorted(worker_ms.items())},
    }


def _mask_name(frame) -> str:
    return pathlib.Path(frame_file_name(frame)).with_suffix(".png").name


def core_options(cls, values: dict | None, what: str):
    """A `cls()` (a _core option class: TrackerOptions, LocalMapperOptions,
    LoopCloserOptions) with `values` set (field name -> number, or true / false
    for a switch; a dotted name, e.g. "ransac.chi2", reaches a nested one), or
    None for the defaults.
    ValueError names an unknown field or a bad value ("unknown {what} option
    ..."); the ranges are checked where the System is made."""
    if not values:
        return None
    o = cls()
    for key, value in values.items():
        *groups, field = key.split(".")
        target = o  # the struct that holds the field: o, or a nested one (o.ransac)
        for depth, name in enumerate(groups + [field]):
            fields = [k for k in dir(target) if not k.startswith("_") and not callable(getattr(target, k))]
            if name not in fields:
                where = f" in {'.'.join(groups[:depth])}" if depth else ""
                raise ValueError(f"unknown {what} option '{key}' (known{where}: {', '.join(fields)})")
            if depth < len(groups):
                target = getattr(target, name)
        current = getattr(target, field)
        if not isinstance(current, (bool, int, float)):
            raise ValueError(f"{what} option '{key}' is a group of options: name one of its fields ('{key}.NAME')")
        if isinstance(current, bool):
            # A switch: true / false (1 / 0); 0.5 or 2 is refused, not rounded.
            text = str(value).strip().lower()
            if text in ("true", "1", "1.0"):
                cast = True
            elif text in ("false", "0", "0.0"):
                cast = False
            else:
                raise ValueError(f"{what} option '{key}': {value!r} is not true / false (1 / 0)")
        else:
            try:
                cast = type(current)(value)
            except (TypeError, ValueError):
                raise ValueError(f"{what} option '{key}': {value!r} is not a {type(current).__name__}") from None
        if isinstance(current, int) and not isinstance(current, bool) and float(value) != cast:
            raise ValueError(f"{what} option '{key}': {value!r} is not a whole number")
        try:
            setattr(target, field, cast)
        except TypeError:  # an unsigned field (a seed) given a negative number
            raise ValueError(f"{what} option '{key}': {value!r} is not an integer >= 0") from None
    return o


def run_dataset(opts: RunOptions) -> dict:
    """Runs a sequence; returns the stats also written to OUT/stats.json."""
    _core = core()
    resolve_dynamic(opts.dynamic)  # an unknown preset fails before anything is loaded
    # And so does an unknown tracking, mapping or loop closing option.
    options = {"tracker": core_options(_core.TrackerOptions, opts.tracker, "tracker"),
               "mapping": core_options(_core.LocalMapperOptions, opts.mapping, "local mapping"),
               "loop": core_options(_core.LoopCloserOptions, opts.loop, "loop closing")}
    if opts.labels and opts.segment:
        raise ValueError("give either a label folder (--labels) or a segmentation model (--segment), not both")
    segmenter, semantic = _semantic(opts)
    stop = StopOnInterrupt()
    try:
        return _run(_core, opts, segmenter, semantic, options, stop)
    finally:
        stop.restore()  # the loop left by an exception
        if semantic is not None:
            semantic.close()


def _track(_core, system, frame, mask, labels):
    """A frame of a C++ provider goes in as it is; others (bag frames) by their images."""
    if isinstance(frame, _core.Frame):
        return system.track_frame(frame, mask, labels)
    if system.sensor == "mono":
        return system.track_mono(frame.image, frame.stamp, mask, labels)
    if system.sensor == "stereo":
        return system.track_stereo(frame.image, frame.right, frame.stamp, mask, labels)
    return system.track_rgbd(frame.image, frame.depth, frame.stamp, mask, labels)


def _label_mask(labels, movable: np.ndarray):
    """255 on the movable ids of a label image (what the runner does with a segmenter's labels)."""
    if labels is None:
        return None
    return np.where(movable[labels], np.uint8(255), np.uint8(0))


def _run(_core, opts: RunOptions, segmenter, semantic, options: dict, stop: StopOnInterrupt) -> dict:
    pacer = Pacer(opts.realtime) if opts.realtime else None  # a bad rate refused before any work
    provider = opts.provider if opts.provider is not None else _core.open_dataset(opts.kind, opts.path, opts.sensor)
    for w in provider.warnings:
        log.warning("%s: %s", opts.path, w)
    selected = frame_range(opts.frames, len(provider))
    settings = _settings(provider, opts.config)
    vocabulary = _vocabulary(opts.vocabulary)
    if opts.load_map and vocabulary is None:
        raise ValueError("--load-map needs a vocabulary (--vocabulary): frames are relocalised in the loaded map")
    preset, dynamic = _dynamic_options(_core, opts)
    if dynamic is not None:
        dynamic.validate(provider.sensor)  # a stage this sensor cannot run: refused, naming both
    dynamic_on = dynamic is not None and dynamic.enabled(provider.sensor)
    if opts.labels and not dynamic_on:
        raise ValueError("--labels feeds the dynamic filter's semantic stage: give a --dynamic preset with stages "
                         "for this sensor (--masks takes an exclusion mask folder)")
    if opts.save_masks and not dynamic_on:
        raise ValueError("--save-masks writes the dynamic filter's masks: give a --dynamic preset with stages "
                         "for this sensor")
    labels_folder = LabelFolder(opts.labels) if opts.labels else None
    if opts.labels_delay and not labels_folder:
        raise ValueError("--labels-delay emulates a network on a label folder: give --labels")
    delayed = (DelayedLabels(opts.labels_delay, opts.propagate_labels, opts.max_mask_age,
                             classes=(labels_folder.movable or ()) if labels_folder else ())
               if opts.labels_delay else None)
    if dynamic_on:
        # Label ids only mean something in the network's own label set.
        if labels_folder is not None and labels_folder.movable is not None:
            dynamic.movable_classes = labels_folder.movable
        elif segmenter is not None:
            dynamic.movable_classes = [int(i) for i in segmenter.card.movable]
    system = _core.System(settings, provider.sensor, synchronous_mapping=opts.synchronous_mapping,
                          vocabulary=vocabulary, dynamic=dynamic if dynamic_on else None,
                          background_nice=opts.background_nice, **options)
    map_io = {}
    if opts.load_map:
        t0 = time.perf_counter()
        system.load_map(opts.load_map)
        map_io["loaded"] = {"path": str(opts.load_map), "load_s": time.perf_counter() - t0,
                            **system.map_summary()}
    if opts.localization:
        system.set_localization_mode(True)
    masks = MaskFolder(opts.masks) if opts.masks else None
    movable = np.zeros(65536, bool)
    movable[list(opts.movable_ids)] = True
    frames_with_labels = 0
    out = pathlib.Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    save_masks = pathlib.Path(opts.save_masks) if opts.save_masks else None
    if save_masks is not None:
        save_masks.mkdir(parents=True, exist_ok=True)
    dynamic_frames = []
    masks_saved = 0

    skipped = collections.Counter()
    states = collections.Counter()
    methods = collections.Counter()
    track_call_ms = []  # wall time around each track call (what a caller of the System waits)
    live_labels = delayed is not None or semantic is not None
    labels_ms = []  # with a network (or its emulation): the time taken for each frame's labels
    ok_frames = []  # frame indices tracked (state OK)
    frame_records = []  # one per frame read: what tracking made of it
    mask_ages = []
    start = time.perf_counter()
    stop.install()  # Ctrl-C from here: the loop ends after the frame it is on
    for i, frame in readable_frames(provider, skipped, opts.progress, f"{opts.kind} {pathlib.Path(opts.path).name}",
                                    indices=selected):
        if stop.requested:
            break
        name = frame_file_name(frame)
        mask = masks.for_image(name, frame.image.shape[:2]) if masks else None
        labels = labels_folder.for_image(name, frame.image.shape[:2]) if labels_folder else None
        t_labels = time.perf_counter()
        if delayed is not None:
            labels = delayed.labels_for(i, labels, frame.image)
        if semantic is not None:
            seg = semantic.labels_for(i, frame.image)
            mask_ages.append(seg.age)
            if dynamic_on:
                labels = seg.labels  # the filter decides what of the movable classes to drop
            else:
                mask = segmenter.movable_mask(seg.labels) if seg.labels is not None else None
        elif labels is None and masks is None and getattr(frame, "labels", None) is not None:
            # Labels carried by the frame (a bag's label topic).
            frames_with_labels += 1
            if dynamic_on:
                labels = frame.labels
            else:
                mask = _label_mask(frame.labels, movable)
        if live_labels:
            # The tracking thread's own time for this frame's labels (the
            # network's result taken, reduced to its movable classes, moved onto
            # the frame): spent before the track call, on the same thread.
            labels_ms.append(1000.0 * (time.perf_counter() - t_labels))
        if pacer is not None:
            pacer.wait(frame.stamp)
        t0 = time.perf_counter()
        result = _track(_core, system, frame, mask, labels)
        track_call_ms.append(1000.0 * (time.perf_counter() - t0))
        if result.rejected != "none":
            log.warning("frame %d (%s) rejected: %s", i, frame.image_path, result.message)
        states[result.state] += 1
        if result.state == "OK":
            ok_frames.append(i)
        methods[result.method or "rejected"] += 1
        frame_records.append({
            "index": i, "stamp": frame.stamp, "state": result.state, "method": result.method or None,
            "rejected": None if result.rejected == "none" else result.rejected, "map": result.map,
            "map_dropped": result.map_dropped, "keypoints": result.keypoints,
            "tracked_points": result.tracked_points, "new_keyframe": result.new_keyframe,
            "track_call_ms": track_call_ms[-1],
            "labels_ms": labels_ms[-1] if live_labels else None,
            # Part of the tracking stage spent waiting for the map lock (local
            # mapping, loop closing or global BA changing the map meanwhile).
            "map_wait_ms": result.stage_ms.get("tracking.map_wait"),
            # This frame's stage times (the medians are in stage_ms_median).
            "stage_ms": dict(result.stage_ms),
            # Why a frame was not tracked (the initialisation's or tracking's own words).
            "message": None if result.state == "OK" else (result.message or None)})
        if dynamic_on and result.rejected == "none":
            dynamic_frames.append({
                "index": i, "stamp": frame.stamp, "labels_used": result.labels_used,
                "dynamic_keypoints": result.dynamic_keypoints, "dynamic_fraction": result.dynamic_fraction,
                "stage_ms": {k: v for k, v in result.stage_ms.items() if k == "dynamic" or k.startswith("dynamic.")},
                "values": dict(result.dynamic_values)})
            if save_masks is not None:
                dyn = system.last_dynamic_mask()
                if dyn is not None:
                    target = save_masks / _mask_name(frame)
                    write_image(target, dyn, "dynamic mask")
                    masks_saved += 1
    stop.restore()
    wall = time.perf_counter() - start
    _hint_async_mapping(opts, frame_records, wall)
    # Concurrent mapping: the keyframes still queued mapped and loop closing
    # done (ORB-SLAM2 saves after its Shutdown likewise), so the outputs are final.
    t0 = time.perf_counter()
    system.wait_for_mapping()
    final_mapping_wait_s = time.perf_counter() - t0
    if final_mapping_wait_s > 1.0:  # a global BA after a late loop, on a long sequence
        log.info("waited %.1f s after the last frame for local mapping and loop closing to finish",
                 final_mapping_wait_s)
    if opts.save_map:
        t0 = time.perf_counter()
        system.save_map(opts.save_map)
        map_io["saved"] = {"path": str(opts.save_map), "save_s": time.perf_counter() - t0,
                           "bytes": pathlib.Path(opts.save_map).stat().st_size}

    stamps, poses = system.trajectory()
    _core.write_tum(str(out / "trajectory.tum"), stamps, poses)
    if opts.kind == "kitti":
        _core.write_kitti(str(out / "trajectory.kitti"), stamps, poses)
    maps = _write_segments(system, out, stamps)
    write_ply(out / "map_points.ply", system.map_points())
    counters = system.counters()
    # An interrupted run's fractions are over the frames it came to.
    frames_run = (len(selected) if not stop.requested else
                  (frame_records[-1]["index"] + 1 - selected.start if frame_records else 0))
    stats = {
        "dataset": {"kind": opts.kind, "path": str(opts.path), "sensor": provider.sensor,
                    "frames": len(provider), "warnings": list(provider.warnings)},
        "settings": settings.summary(),
        "dynamic": opts.dynamic,
        "dynamic_filter": None if not dynamic_on else {
            "preset": opts.dynamic, "file": str(preset), "stages": list(dynamic.stages_for(provider.sensor)),
            "movable_classes": list(dynamic.movable_classes) or None,
            "labels": (dict(labels_folder.counts) if labels_folder else
                       "segmentation" if semantic is not None else None),
            "all_dynamic_frames": int(counters["dynamic_all_frames"]),
            "stage_failures": int(counters["dynamic_stage_failures"]),
            "unchecked_kept": int(counters["unchecked_kept"]),
            "labels_dropped_by_core": int(counters["labels_dropped"]),
            "masks_saved": masks_saved if save_masks is not None else None,
            "summary": _dynamic_summary(dynamic_frames),
            "per_frame": dynamic_frames,
        },
        "frames": len(selected),
        # The frames run (--frames), [start, end) of the sequence's; None: all of them.
        "frame_range": [selected.start, selected.stop] if len(selected) < len(provider) else None,
        # Ctrl-C: the run stopped after this many of the frames (its outputs are theirs); None: it ran to the end.
        "interrupted": {"frames_run": frames_run} if stop.requested else None,
        "frames_skipped": dict(skipped),
        "frames_rejected": counters["rejected_by_reason"],
        "tracked_frames": int(counters["tracked"]),
        "tracked_fraction": counters["tracked"] / max(frames_run, 1),
        # The first frame tracked (for monocular: the initialisation frame) and
        # the share of the frames from there on that were tracked.
        "init_frame": ok_frames[0] if ok_frames else None,
        "tracked_fraction_after_init": (len(ok_frames) / (selected.start + frames_run - ok_frames[0])
                                        if ok_frames else 0.0),
        "states": dict(states),
        "tracking_methods": dict(methods),
        "lost_frames": int(counters["lost"]),
        "relocalizations": int(counters["relocalizations"]),
        "vocabulary": opts.vocabulary if isinstance(opts.vocabulary, (str, type(None))) else "given",
        "initializations": int(counters["initializations"]),
        "maps_dropped": int(counters["maps_dropped"]),
        "maps": maps,
        "map": system.map_summary(),
        "synchronous_mapping": opts.synchronous_mapping,
        # After the last frame: until the queued keyframes were mapped and loop closing was done.
        "final_mapping_wait_s": final_mapping_wait_s,
        "realtime": pacer.summary() if pacer is not None else None,
        "background_nice": opts.background_nice,
        "tracker_options": dict(opts.tracker or {}),
        "mapping_options": dict(opts.mapping or {}),
        "loop_options": dict(opts.loop or {}),
        "localization": opts.localization,
        "map_file": map_io or None,
        "stage_ms_median": _median_stages([f["stage_ms"] for f in frame_records]),
        # Wall time around the track call, frame loading excluded: the number a
        # benchmark can take the same way for another SLAM system.
        "track_call_ms_median": _median(track_call_ms),
        "track_call_ms": track_call_ms,
        # With a network behind the camera (--segment, --labels-delay): the
        # tracking thread's time per frame for the labels, before the track
        # call, and the median of both together (what the thread spends on a frame).
        "labels_ms": labels_ms if live_labels else None,
        "labels_ms_median": _median(labels_ms),
        "track_call_plus_labels_ms_median": (_median([a + b for a, b in zip(track_call_ms, labels_ms)])
                                             if live_labels else None),
        "map_wait_ms": _spread([f["map_wait_ms"] for f in frame_records if f["map_wait_ms"] is not None]),
        # Per frame read: index, stamp, state, method, rejection, map index (one more
        # after each map given up), keypoints, tracked points, keyframe, track call ms,
        # map wait ms, stage ms.
        "per_frame": frame_records,
        "wall_s": wall,
        "fps": len(frame_records) / wall if wall > 0 else None,
        "masks": dict(masks.counts) if masks else None,
        "frames_with_labels": frames_with_labels,
        "masks_dropped_by_core": int(counters["masks_dropped"]),
    }
    if delayed is not None:
        stats["labels_delay"] = delayed.summary()
    if semantic is not None:
        # mask_age_per_frame: frames since the network saw the labels' image; -1: no labels.
        stats["segmentation"] = {"model": segmenter.card.name, **semantic.summary(),
                                 "mask_age_per_frame": mask_ages}
    stats.update(_evaluate(provider, stamps, poses, provider.sensor, out))
    (out / "stats.json").write_text(json.dumps(stats, indent=2))
    return stats
