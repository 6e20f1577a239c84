"""`dynaorb run`: iterate a dataset through the core and write what came out.

Writes OUT/trajectory.tum (and trajectory.kitti for KITTI), OUT/groundtruth.tum
when the dataset has ground truth, OUT/map_points.ply (the sparse map) and
OUT/stats.json: frames, tracked frames, skipped and rejected frames with
reasons, per-stage median ms (per frame for the tracking thread, per keyframe
for local mapping), fps, map size, and ATE / RPE against the ground truth when
enough frames were tracked.
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
from dynaorb.runner.frames import readable_frames
from dynaorb.runner.masks import MaskFolder
from dynaorb.segmentation.labels import PASCAL_VOC_MOVABLE

log = logging.getLogger(__name__)

# Dynamic-object front-end presets. Only "off" exists until the front end lands;
# a mask folder (--masks) already keeps the keypoints it marks out of tracking.
DYNAMIC_MODES = ("off",)


@dataclasses.dataclass
class RunOptions:
    kind: str
    path: str
    sensor: str | None = None
    config: str | None = None
    out: str = "out/run"
    dynamic: str = "off"
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
    max_mask_age: int = 30
    progress: bool = True
    # Map each keyframe before tracking the next frame: repeatable runs. False
    # runs local mapping concurrently, as a live camera would.
    synchronous_mapping: bool = True
    save_map: str | None = None     # the map written here after the run
    load_map: str | None = None     # start from this saved map (needs a vocabulary)
    localization: bool = False      # localisation only: no new keyframes or map points
    # A provider object to run instead of opening kind/path (e.g. a
    # dynaorb.ros.bag.BagProvider); frames that carry `labels` (class ids)
    # get the mask of movable_ids when no other mask source is given.
    provider: object | None = None
    movable_ids: tuple = PASCAL_VOC_MOVABLE


# Stages of the tracking thread (summed into "frame_total"); the others are
# local mapping's, reported per keyframe.
FRAME_STAGES = ("preprocess", "extract", "stereo_matching", "tracking")


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
                                                                max_age_frames=opts.max_mask_age))


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


def run_dataset(opts: RunOptions) -> dict:
    """Runs a sequence; returns the stats also written to OUT/stats.json."""
    _core = core()
    if opts.dynamic not in DYNAMIC_MODES:
        raise ValueError(f"unknown dynamic mode {opts.dynamic!r} (available: {', '.join(DYNAMIC_MODES)})")
    segmenter, semantic = _semantic(opts)
    try:
        return _run(_core, opts, segmenter, semantic)
    finally:
        if semantic is not None:
            semantic.close()


def _track(_core, system, frame, mask):
    """A frame of a C++ provider goes in as it is; others (bag frames) by their images."""
    if isinstance(frame, _core.Frame):
        return system.track_frame(frame, mask)
    if system.sensor == "mono":
        return system.track_mono(frame.image, frame.stamp, mask)
    if system.sensor == "stereo":
        return system.track_stereo(frame.image, frame.right, frame.stamp, mask)
    return system.track_rgbd(frame.image, frame.depth, frame.stamp, mask)


def _label_mask(labels, movable: np.ndarray):
    """255 on the movable ids of a label image (what the runner does with a segmenter's labels)."""
    if labels is None:
        return None
    return np.where(movable[labels], np.uint8(255), np.uint8(0))


def _run(_core, opts: RunOptions, segmenter, semantic) -> dict:
    provider = opts.provider if opts.provider is not None else _core.open_dataset(opts.kind, opts.path, opts.sensor)
    for w in provider.warnings:
        log.warning("%s: %s", opts.path, w)
    settings = _settings(provider, opts.config)
    vocabulary = _vocabulary(opts.vocabulary)
    if opts.load_map and vocabulary is None:
        raise ValueError("--load-map needs a vocabulary (--vocabulary): frames are relocalised in the loaded map")
    system = _core.System(settings, provider.sensor, synchronous_mapping=opts.synchronous_mapping,
                          vocabulary=vocabulary)
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

    skipped = collections.Counter()
    states = collections.Counter()
    methods = collections.Counter()
    per_frame_ms = []
    ok_frames = []  # frame indices tracked (state OK)
    mask_ages = []
    start = time.perf_counter()
    for i, frame in readable_frames(provider, skipped, opts.progress, f"{opts.kind} {pathlib.Path(opts.path).name}"):
        mask = masks.for_image(frame.image_path, frame.image.shape[:2]) if masks else None
        if semantic is not None:
            labels = semantic.labels_for(i, frame.image)
            mask_ages.append(labels.age)
            mask = segmenter.movable_mask(labels.labels) if labels.labels is not None else None
        if mask is None and masks is None and semantic is None and getattr(frame, "labels", None) is not None:
            mask = _label_mask(frame.labels, movable)
            frames_with_labels += 1
        result = _track(_core, system, frame, mask)
        if result.rejected != "none":
            log.warning("frame %d (%s) rejected: %s", i, frame.image_path, result.message)
        states[result.state] += 1
        if result.state == "OK":
            ok_frames.append(i)
        methods[result.method or "rejected"] += 1
        per_frame_ms.append(dict(result.stage_ms))
    wall = time.perf_counter() - start
    if opts.save_map:
        t0 = time.perf_counter()
        system.save_map(opts.save_map)
        map_io["saved"] = {"path": str(opts.save_map), "save_s": time.perf_counter() - t0,
                           "bytes": pathlib.Path(opts.save_map).stat().st_size}

    stamps, poses = system.trajectory()
    _core.write_tum(str(out / "trajectory.tum"), stamps, poses)
    if opts.kind == "kitti":
        _core.write_kitti(str(out / "trajectory.kitti"), stamps, poses)
    write_ply(out / "map_points.ply", system.map_points())
    counters = system.counters()
    stats = {
        "dataset": {"kind": opts.kind, "path": str(opts.path), "sensor": provider.sensor,
                    "frames": len(provider), "warnings": list(provider.warnings)},
        "settings": settings.summary(),
        "dynamic": opts.dynamic,
        "frames": len(provider),
        "frames_skipped": dict(skipped),
        "frames_rejected": counters["rejected_by_reason"],
        "tracked_frames": int(counters["tracked"]),
        "tracked_fraction": counters["tracked"] / max(len(provider), 1),
        # The first frame tracked (for monocular: the initialisation frame) and
        # the share of the frames from there on that were tracked.
        "init_frame": ok_frames[0] if ok_frames else None,
        "tracked_fraction_after_init": (len(ok_frames) / (len(provider) - ok_frames[0])
                                        if ok_frames else 0.0),
        "states": dict(states),
        "tracking_methods": dict(methods),
        "lost_frames": int(counters["lost"]),
        "relocalizations": int(counters["relocalizations"]),
        "vocabulary": opts.vocabulary if isinstance(opts.vocabulary, (str, type(None))) else "given",
        "initializations": int(counters["initializations"]),
        "map": system.map_summary(),
        "synchronous_mapping": opts.synchronous_mapping,
        "localization": opts.localization,
        "map_file": map_io or None,
        "stage_ms_median": _median_stages(per_frame_ms),
        "wall_s": wall,
        "fps": len(per_frame_ms) / wall if wall > 0 else None,
        "masks": dict(masks.counts) if masks else None,
        "frames_with_labels": frames_with_labels,
        "masks_dropped_by_core": int(counters["masks_dropped"]),
    }
    if semantic is not None:
        # mask_age_per_frame: frames since the network saw the labels' image; -1: no labels.
        stats["segmentation"] = {"model": segmenter.card.name, **semantic.summary(),
                                 "mask_age_per_frame": mask_ages}
    stats.update(_evaluate(provider, stamps, poses, provider.sensor, out))
    (out / "stats.json").write_text(json.dumps(stats, indent=2))
    return stats
