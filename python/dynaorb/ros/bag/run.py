"""`dynaorb bag run`: a ROS 1 bag through the core, serially and repeatably.

Every frame of the bag is tracked in stamp order (no frame dropped, no wall
clock: local mapping finishes each keyframe before the next frame unless
async_mapping, and frames go as fast as tracking takes them unless the
runner's realtime paces them by their stamps), by the runner `dynaorb run`
uses, with its options (BagRunOptions.runner), so the outputs are the same:
OUT/trajectory.tum, OUT/map_points.ply, OUT/stats.json (ATE / RPE against
the bag's ground truth when there is one), and the map file with save_map.
"""
from __future__ import annotations

import dataclasses
import json
import pathlib

from dynaorb.ros.bag.read import BagProvider
from dynaorb.runner import RunOptions, run_dataset


@dataclasses.dataclass
class BagRunOptions:
    bag: object                        # a bag path, or the parts of a split recording (a list, read as one)
    config: str | None = None          # settings YAML (default: BAG-stem.settings.yaml)
    sensor: str | None = None          # default: the richest the bag's topics allow
    topics: dict | None = None         # role -> topic (image, right, depth, labels)
    out: str = "out/bag"
    ground_truth: str | None = None    # TUM file (default: BAG-stem.groundtruth.tum)
    ground_truth_topic: str | None = None  # or a stamped pose topic of the bag
    ground_truth_tf: tuple[str, str] | None = None  # or (parent, child) frames of the bag's TF
    use_labels: bool = True            # a labels topic masks the movable classes
    max_diff: float = 0.02             # s: RGB-D colour/depth association
    vocabulary: object = "default"
    dynamic: str = "off"
    synchronous_mapping: bool = True
    save_map: str | None = None
    progress: bool = True
    # In-process segmentation (a model file or `dynaorb models` name) for a bag
    # without labels, as `dynaorb run --segment`: its labels feed the `dynamic`
    # preset's semantic stage, or mask the movable classes; a labels topic in
    # the bag is then not read.
    segment: str | None = None
    segment_mode: str = "async"
    # The rest of the runner's options, by RunOptions field name, as `dynaorb
    # run` takes them: e.g. {"tracker": {"max_frames": 10}, "realtime": 1.0,
    # "load_map": "a.map", "localization": True, "save_masks": "masks",
    # "background_nice": 0}. Per-frame folders (masks, labels, save_masks)
    # name a bag's frames by stamp: <stamp>.png with 6 decimals.
    runner: dict | None = None


def _runner_fields(runner: dict | None) -> dict:
    """BagRunOptions.runner checked: RunOptions fields the bag does not set itself."""
    runner = dict(runner or {})
    fields = {f.name for f in dataclasses.fields(RunOptions)}
    own = {f.name for f in dataclasses.fields(BagRunOptions)} | {"kind", "path", "provider"}
    for key in runner:
        if key not in fields:
            raise ValueError(f"bag run: {key!r} is not a runner option (RunOptions has: "
                             f"{', '.join(sorted(fields - own))})")
        if key in own:
            raise ValueError(f"bag run: {key!r} is the bag's own (a BagRunOptions field), not a runner option")
    return runner


def run_bag(opts: BagRunOptions) -> dict:
    """Runs the bag; returns the stats also written to OUT/stats.json."""
    runner = _runner_fields(opts.runner)
    provider = BagProvider(opts.bag, settings=opts.config, sensor=opts.sensor, topics=opts.topics,
                           max_diff=opts.max_diff, ground_truth=opts.ground_truth,
                           use_labels=opts.use_labels and not opts.segment,
                           ground_truth_topic=opts.ground_truth_topic, ground_truth_tf=opts.ground_truth_tf)
    try:
        stats = run_dataset(RunOptions(kind="bag", path=str(provider.path), sensor=provider.sensor, out=opts.out,
                                       dynamic=opts.dynamic, vocabulary=opts.vocabulary, progress=opts.progress,
                                       synchronous_mapping=opts.synchronous_mapping, save_map=opts.save_map,
                                       segment=opts.segment, segment_mode=opts.segment_mode, provider=provider,
                                       **runner))
    finally:
        provider.close()
    stats["bag"] = {"files": [str(p) for p in provider.paths], "topics": provider.topics, "frames": len(provider)}
    if provider.settings_from_camera_info:
        # The settings the run used, for a rerun with --config.
        (pathlib.Path(opts.out) / "settings.camera_info.yaml").write_text(provider.settings_yaml)
        stats["bag"]["settings_from_camera_info"] = str(pathlib.Path(opts.out) / "settings.camera_info.yaml")
    (pathlib.Path(opts.out) / "stats.json").write_text(json.dumps(stats, indent=2))
    return stats
