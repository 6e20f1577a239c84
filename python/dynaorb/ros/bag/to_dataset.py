"""`dynaorb bag to-dataset`: a ROS 1 bag written as a dataset folder that
`dynaorb run`, `segment`, `eval` and other tools read.

The frames are the ones `dynaorb bag run` tracks (stereo pairs of the same
stamp, RGB-D colour and depth paired as TUM's associate.py does), in the
layout of the sensor's usual dataset:
- RGB-D: TUM (OUT/rgb/<stamp>.png, OUT/depth/<stamp>.png, rgb.txt,
  depth.txt, groundtruth.txt). Depth PNGs are 16-bit: 16UC1 as the bag holds
  it (the settings' DepthMapFactor), 32FC1 metres at the settings'
  DepthMapFactor per metre (TUM's 5000 from a bag's camera_info), 0 where
  there is none (NaN, zero, negative) or where the value does not fit 16
  bits (counted).
- stereo and mono: KITTI odometry (OUT/sequences/00/image_0[, image_1],
  times.txt with the bag's stamps, calib.txt with P0 / P1 from the settings;
  OUT/poses/00.txt, the left camera's pose at each frame in the first
  frame's, from the ground truth sampled at the frame stamps, for as many
  leading frames as it covers).
Colour images keep their colour (PNG in OpenCV's BGR order), grey ones stay
grey (16-bit grey as 16-bit PNG). With labels on the bag's labels topic they
go to labels/ beside the images, named like them (`--labels` / `--masks` of
`dynaorb run`). The sequence folder gets settings.yaml (the bag's settings,
or those from its camera_info), which the dataset readers load first, and
groundtruth.tum (the ground truth as it is, for `dynaorb eval`).
"""
from __future__ import annotations

import dataclasses
import logging
import pathlib
import shutil

import numpy as np

from dynaorb import core
from dynaorb.image_files import write_image
from dynaorb.ros.bag import messages as m
from dynaorb.ros.bag.poses import sample
from dynaorb.ros.bag.read import BagProvider

log = logging.getLogger(__name__)

TUM_MAX_DT = 0.02  # s: how far apart the TUM reader (io/tum_dataset.cc) pairs colour and depth


@dataclasses.dataclass
class BagToDatasetOptions:
    bag: object                            # a bag path, or the parts of a split recording (a list, read as one)
    out: str
    config: str | None = None              # settings YAML (default: BAG-stem.settings.yaml, else camera_info)
    sensor: str | None = None              # default: the richest the bag's topics allow
    topics: dict | None = None             # role -> topic (image, right, depth, labels)
    max_diff: float = 0.02                 # s: RGB-D colour/depth association
    ground_truth: str | None = None        # TUM file (default: BAG-stem.groundtruth.tum)
    ground_truth_topic: str | None = None  # or a stamped pose topic of the bag
    ground_truth_tf: tuple[str, str] | None = None  # or (parent, child) frames of the bag's TF
    ground_truth_max_gap: float = 0.1      # s: ground truth interpolated across gaps up to this
    use_labels: bool = True
    overwrite: bool = False
    progress: bool = False


def depth_for_file(msg, depth_map_factor: float) -> tuple[np.ndarray, int]:
    """16-bit depth in the settings' units, and how many pixels did not fit."""
    a = m.image_array(msg)
    if msg.encoding in ("16UC1", "mono16"):
        return a, 0
    if msg.encoding != "32FC1":
        raise ValueError(f"depth encoding {msg.encoding!r} is neither 16UC1 nor 32FC1")
    scaled = a.astype(np.float64) * depth_map_factor
    valid = np.isfinite(scaled) & (scaled > 0)
    over = valid & (np.rint(scaled) > 65535)
    out = np.zeros(a.shape, np.uint16)
    keep = valid & ~over
    out[keep] = np.rint(scaled[keep]).astype(np.uint16)
    return out, int(over.sum())


def _prepare(out: pathlib.Path, overwrite: bool) -> None:
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            raise FileExistsError(f"{out}: exists and is not empty (--overwrite replaces it)")
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)


def _kitti_calib(settings, sensor: str) -> str:
    P0 = np.array([[settings.fx, 0, settings.cx, 0], [0, settings.fy, settings.cy, 0], [0, 0, 1, 0]])
    rows = [P0]
    if sensor == "stereo":
        P1 = P0.copy()
        P1[0, 3] = -float(settings.bf)
        rows.append(P1)
    return "".join(f"P{k}: " + " ".join(f"{v:.12e}" for v in P.ravel()) + "\n" for k, P in enumerate(rows))


def bag_to_dataset(opts: BagToDatasetOptions) -> dict:
    """Writes the dataset folder; returns a summary (layout, frames, files, counts,
    and the `dynaorb run` command line that reads it)."""
    _core = core()
    if not (np.isfinite(opts.ground_truth_max_gap) and opts.ground_truth_max_gap > 0):
        raise ValueError(f"the ground truth's largest gap to interpolate across must be a positive number of "
                         f"seconds, got {opts.ground_truth_max_gap}")
    provider = BagProvider(opts.bag, settings=opts.config, sensor=opts.sensor, topics=opts.topics,
                           max_diff=opts.max_diff, ground_truth=opts.ground_truth, use_labels=opts.use_labels,
                           ground_truth_topic=opts.ground_truth_topic, ground_truth_tf=opts.ground_truth_tf)
    try:
        return _convert(opts, provider, _core)
    finally:
        provider.close()


def _convert(opts: BagToDatasetOptions, provider: BagProvider, _core) -> dict:
    names = ", ".join(p.name for p in provider.paths)
    for w in provider.warnings:
        log.warning("%s: %s", provider.path, w)
    if len(provider) == 0:
        raise ValueError(f"{names}: no frames to write")
    sensor, settings = provider.sensor, provider.default_settings()
    root = pathlib.Path(opts.out)
    _prepare(root, opts.overwrite)
    tum = sensor == "rgbd"
    seq = root if tum else root / "sequences" / "00"
    image_dirs = {"image": seq / ("rgb" if tum else "image_0")}
    if tum:
        image_dirs["depth"] = seq / "depth"
    elif sensor == "stereo":
        image_dirs["right"] = seq / "image_1"
    for d in image_dirs.values():
        d.mkdir(parents=True, exist_ok=True)
    factor = float(settings.depth_map_factor or 1.0)
    counts = {"frames": 0, "labels": 0, "unreadable": 0, "depth_too_far": 0}
    lists = {"image": [], "depth": []}  # (stamp, relative file name)
    stamps = []
    indices = range(len(provider))
    if opts.progress:
        from tqdm import tqdm

        indices = tqdm(indices, desc=f"dataset {names}", unit="frame")
    for i in indices:
        try:
            stamp, msgs = provider.load_messages(i)
            name = f"{stamp:.6f}.png" if tum else f"{counts['frames']:06d}.png"
            files = {"image": m.image_for_file(msgs["image"])}
            if "right" in msgs:
                files["right"] = m.image_for_file(msgs["right"])
            if "depth" in msgs:
                files["depth"], too_far = depth_for_file(msgs["depth"], factor)
            labels = m.image_array(msgs["labels"]) if "labels" in msgs else None
        except (ValueError, _core.InputError) as exc:
            counts["unreadable"] += 1
            log.warning("frame %d skipped: %s", i, exc)
            continue
        for role, image in files.items():
            if role == "depth":
                depth_stamp = provider.part_stamps(i)["depth"]
                write_image(image_dirs[role] / f"{depth_stamp:.6f}.png", image)
                lists["depth"].append((depth_stamp, f"depth/{depth_stamp:.6f}.png"))
                counts["depth_too_far"] += too_far
            else:
                write_image(image_dirs[role] / name, image)
        lists["image"].append((stamp, f"rgb/{name}" if tum else name))
        if labels is not None:
            (seq / "labels").mkdir(exist_ok=True)
            write_image(seq / "labels" / name, labels.astype(np.uint8) if labels.dtype != np.uint8 else labels)
            counts["labels"] += 1
        stamps.append(stamp)
        counts["frames"] += 1
    if counts["frames"] == 0:
        raise ValueError(f"{names}: none of its {len(provider)} frames could be read")
    if counts["depth_too_far"]:
        log.warning("%d depth pixels beyond %.2f m (16 bits at DepthMapFactor %g) written as no depth",
                    counts["depth_too_far"], 65535 / factor, factor)
    if tum:
        far = sum(abs(s - d) > TUM_MAX_DT + 1e-9 for (s, _), (d, _) in zip(lists["image"], lists["depth"]))
        counts["depth_pairs_beyond_tum"] = int(far)
        if far:
            log.warning("%d colour / depth pairs are more than %.2f s apart (--max-diff %.3f): the TUM reader "
                        "associates within %.2f s and will skip those frames", far, TUM_MAX_DT, opts.max_diff,
                        TUM_MAX_DT)

    files = {"sequence": str(seq)}
    settings.save(str(seq / "settings.yaml"))
    files["settings"] = str(seq / "settings.yaml")
    source = f"# file: '{names}' (dynaorb bag to-dataset)\n# timestamp filename\n"
    if tum:
        for role, list_name in (("image", "rgb.txt"), ("depth", "depth.txt")):
            kind = "color" if role == "image" else "depth"
            text = f"# {kind} images\n" + source + "".join(f"{s:.6f} {f}\n" for s, f in lists[role])
            (seq / list_name).write_text(text)
    else:
        (seq / "times.txt").write_text("".join(f"{s:.6f}\n" for s in stamps))
        (seq / "calib.txt").write_text(_kitti_calib(settings, sensor))

    gt_stamps, gt_poses = provider.ground_truth()
    gt = {"poses": int(len(gt_stamps))}
    if len(gt_stamps):
        gt_file = seq / ("groundtruth.txt" if tum else "groundtruth.tum")
        _core.write_tum(str(gt_file), np.asarray(gt_stamps, float), np.asarray(gt_poses))
        files["groundtruth"] = str(gt_file)
        if not tum:
            at = sample(np.asarray(gt_stamps, float), np.asarray(gt_poses), np.asarray(stamps),
                        opts.ground_truth_max_gap)
            covered = ~np.isnan(at[:, 0, 0])
            leading = int(np.argmin(covered)) if not covered.all() else len(stamps)
            gt["frames_covered"] = int(covered.sum())
            gt["kitti_poses"] = leading
            if leading:
                first_inv = np.linalg.inv(at[0])
                rows = [(first_inv @ at[k])[:3].ravel() for k in range(leading)]
                (root / "poses").mkdir(exist_ok=True)
                (root / "poses" / "00.txt").write_text("".join(" ".join(f"{v:.9e}" for v in r) + "\n"
                                                              for r in rows))
                files["kitti_poses"] = str(root / "poses" / "00.txt")
            if leading < len(stamps):
                what = (f"KITTI poses for the first {leading} only" if leading else
                        "no KITTI poses (they are relative to the first frame, which it does not cover)")
                log.warning("ground truth covers %d of %d frames: %s; %s holds all of it for `dynaorb eval`",
                            int(covered.sum()), len(stamps), what, gt_file.name)
    kind = "tum" if tum else "kitti"
    command = ["dynaorb", "run", kind, str(seq)] + ([] if sensor in ("rgbd", "stereo") else ["--sensor", sensor])
    if counts["labels"]:
        command += ["--labels", str(seq / "labels")]
    return {"bag": [str(p) for p in provider.paths], "layout": kind, "sensor": sensor, "topics": dict(provider.topics),
            "settings_from_camera_info": provider.settings_from_camera_info, **counts,
            "ground_truth": gt, "files": files, "run": " ".join(command)}
