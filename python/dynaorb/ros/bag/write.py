"""`dynaorb bag from-dataset`: a TUM, KITTI or EuRoC sequence as a ROS 1 bag.

Topics (messages stamped with the frame's stamp, bag time = header stamp):
- TUM (RGB-D): /camera/rgb/image_color (rgb8), /camera/depth/image (32FC1
  metres, NaN without depth, as TUM's own bags; or 16UC1 as in the PNGs with
  --depth-encoding 16UC1), camera_info for both;
- KITTI (stereo): /camera/left/image_rect, /camera/right/image_rect (mono8)
  and their camera_info (P of the right camera carries -fx * baseline);
- EuRoC: /cam0/image_raw, /cam1/image_raw (mono8, distorted: the settings'
  LEFT./RIGHT. blocks rectify them);
- with --labels DIR: the label image of each frame (DIR/<image file name>,
  e.g. `dynaorb synth`'s labels/ or a `dynaorb segment` cache) as mono8 on
  the labels topic, stamped like the image.
With --image-transport compressed, the images go as image_transport records
them: sensor_msgs/CompressedImage on TOPIC/compressed (png, lossless, or
--image-format jpeg; labels always png) and depth on TOPIC/compressedDepth
(png; 32FC1 as compressed_depth_image_transport's quantised inverse depth,
up to 10 m; 16UC1 as it is).
Beside BAG: BAG-stem.settings.yaml (the dataset's settings) and, when the
dataset has ground truth, BAG-stem.groundtruth.tum (the camera's poses, with
the bag's stamps). KITTI's stamps start at 0, which ROS reads as "no time":
they are shifted by --stamp-offset (default: 1 s for sequences starting
below 1 s, else 0), and so is the ground truth written beside the bag.
"""
from __future__ import annotations

import dataclasses
import logging
import pathlib

import cv2
import numpy as np
from rosbags.rosbag1 import Writer

from dynaorb import core
from dynaorb.ros.bag import messages as m

log = logging.getLogger(__name__)


@dataclasses.dataclass
class BagWriteOptions:
    kind: str                     # tum | kitti | euroc
    path: str
    out: str
    sensor: str | None = None     # default: the richest the dataset has
    depth_encoding: str = "32FC1"  # or 16UC1 (TUM's PNG units: DepthMapFactor)
    labels: str | None = None     # folder of per-frame label images
    stamp_offset: float | None = None
    max_frames: int | None = None
    progress: bool = False
    image_transport: str = "raw"  # or compressed (TOPIC/compressed, TOPIC/compressedDepth)
    image_format: str = "png"     # compressed: png (lossless) or jpeg


def sidecar(bag: str | pathlib.Path, what: str) -> pathlib.Path:
    """BAG-stem.<what> beside the bag (settings.yaml, groundtruth.tum)."""
    bag = pathlib.Path(bag)
    return bag.with_name(f"{bag.stem}.{what}")


def topics_for(kind: str, sensor: str) -> m.Topics:
    if kind == "tum":
        t = m.TUM_TOPICS
        return t if sensor == "rgbd" else dataclasses.replace(t, depth=None, depth_info=None)
    t = m.EUROC_TOPICS if kind == "euroc" else m.STEREO_TOPICS
    return t if sensor == "stereo" else dataclasses.replace(t, right=None, right_info=None)


def _camera_infos(settings, kind: str, sensor: str, width: int, height: int):
    """(left/colour info kwargs, right info kwargs or None); None when the
    images are raw and only the settings' rectification blocks describe them."""
    if kind == "euroc":
        return None, None
    K = np.array([[settings.fx, 0, settings.cx], [0, settings.fy, settings.cy], [0, 0, 1]])
    P = np.hstack([K, np.zeros((3, 1))])
    D = np.zeros(5)
    dist = np.asarray(settings.dist, float).ravel()
    D[:min(5, dist.size)] = dist[:5]
    left = dict(width=width, height=height, K=K, D=D, P=P)
    right = None
    if sensor == "stereo" and settings.bf:
        Pr = P.copy()
        Pr[0, 3] = -settings.bf
        right = dict(width=width, height=height, K=K, D=D, P=Pr)
    return left, right


def write_dataset_bag(opts: BagWriteOptions) -> dict:
    """Writes the bag and its sidecars; returns a summary (frames, topics, files)."""
    _core = core()
    if opts.depth_encoding not in ("32FC1", "16UC1"):
        raise ValueError(f"depth encoding must be 32FC1 or 16UC1, not {opts.depth_encoding!r}")
    if opts.image_transport not in ("raw", "compressed"):
        raise ValueError(f"image transport must be raw or compressed, not {opts.image_transport!r}")
    if opts.image_format not in ("png", "jpeg"):
        raise ValueError(f"image format must be png or jpeg, not {opts.image_format!r}")
    provider = _core.open_dataset(opts.kind, opts.path, opts.sensor)
    for w in provider.warnings:
        log.warning("%s: %s", opts.path, w)
    sensor = provider.sensor
    settings = provider.default_settings()
    n = len(provider) if opts.max_frames is None else min(len(provider), opts.max_frames)
    if n == 0:
        raise ValueError(f"{opts.path}: the sequence has no frames")
    first = provider.stamp(0)
    offset = opts.stamp_offset if opts.stamp_offset is not None else (1.0 if first < 1.0 else 0.0)
    topics = topics_for(opts.kind, sensor)
    labels_dir = pathlib.Path(opts.labels) if opts.labels else None
    if labels_dir is not None and not labels_dir.is_dir():
        raise FileNotFoundError(f"{labels_dir}: label folder does not exist")
    factor = settings.depth_map_factor or 1.0

    out = pathlib.Path(opts.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()  # rosbags refuses to overwrite
    counts = {"frames": 0, "labels": 0, "labels_missing": 0, "unreadable": 0}
    indices = range(n)
    if opts.progress:
        from tqdm import tqdm

        indices = tqdm(indices, desc=f"bag {pathlib.Path(opts.path).name}", unit="frame")
    with Writer(out) as writer:
        conn = {}

        compressed = opts.image_transport == "compressed"

        def add(topic, msgtype):
            if topic and topic not in conn:
                conn[topic] = writer.add_connection(topic, msgtype, typestore=m.TYPESTORE)

        def add_image(topic, depth=False):
            if topic:
                add(topic + ("/compressedDepth" if depth else "/compressed") if compressed else topic,
                    m.COMPRESSED_IMAGE if compressed else m.IMAGE)

        add_image(topics.image)
        add_image(topics.right)
        add_image(topics.depth, depth=True)
        if labels_dir is not None:
            add_image(topics.labels)
        infos = None
        for i in indices:
            try:
                frame = provider.load(i)
            except _core.InputError as exc:
                counts["unreadable"] += 1
                log.warning("frame %d skipped: %s", i, exc)
                continue
            stamp = frame.stamp + offset
            t_ns = m.stamp_ns(stamp)
            seq = counts["frames"]

            def put(topic, msg):
                if msg.__msgtype__ == m.IMAGE and compressed:
                    depth = topic == topics.depth
                    fmt = "png" if depth or topic == topics.labels else opts.image_format
                    topic += "/compressedDepth" if depth else "/compressed"
                    msg = m.compress(msg, fmt)
                writer.write(conn[topic], t_ns, m.serialize(msg))

            image = frame.image
            if image.ndim == 3:
                put(topics.image, m.image_msg(cv2.cvtColor(image, cv2.COLOR_BGR2RGB), "rgb8", stamp,
                                              topics.frame_id, seq))
            else:
                put(topics.image, m.image_msg(image, "mono8", stamp, topics.frame_id, seq))
            if topics.right:
                right = frame.right if frame.right.ndim == 2 else cv2.cvtColor(frame.right, cv2.COLOR_BGR2GRAY)
                put(topics.right, m.image_msg(right, "mono8", stamp, topics.right_frame_id or topics.frame_id, seq))
            if topics.depth:
                depth = frame.depth
                if opts.depth_encoding == "32FC1":
                    metres = depth.astype(np.float32) / np.float32(factor)
                    metres[~(metres > 0)] = np.nan
                    put(topics.depth, m.image_msg(metres, "32FC1", stamp, topics.frame_id, seq))
                else:
                    if depth.dtype != np.uint16:
                        depth = np.nan_to_num(depth.astype(np.float32) * np.float32(factor)).astype(np.uint16)
                    put(topics.depth, m.image_msg(depth, "16UC1", stamp, topics.frame_id, seq))
            if labels_dir is not None:
                path = labels_dir / pathlib.Path(frame.image_path).name
                labels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED) if path.is_file() else None
                if labels is None or labels.ndim != 2 or labels.shape != frame.image.shape[:2]:
                    counts["labels_missing"] += 1
                else:
                    put(topics.labels, m.image_msg(labels.astype(np.uint8), "mono8", stamp, topics.frame_id, seq))
                    counts["labels"] += 1
            if infos is None:
                h, w = frame.image.shape[:2]
                infos = _camera_infos(settings, opts.kind, sensor, w, h)
                if infos[0] is not None:
                    add(topics.image_info, m.CAMERA_INFO)
                    add(topics.depth_info, m.CAMERA_INFO)
                if infos[1] is not None:
                    add(topics.right_info, m.CAMERA_INFO)
            left_info, right_info = infos
            if left_info is not None:
                put(topics.image_info, m.camera_info_msg(stamp, topics.frame_id, seq=seq, **left_info))
                if topics.depth_info:
                    put(topics.depth_info, m.camera_info_msg(stamp, topics.frame_id, seq=seq, **left_info))
            if right_info is not None and topics.right_info:
                put(topics.right_info, m.camera_info_msg(stamp, topics.right_frame_id or topics.frame_id, seq=seq,
                                                         **right_info))
            counts["frames"] += 1

    settings_file = sidecar(out, "settings.yaml")
    settings.save(str(settings_file))
    files = {"bag": str(out), "settings": str(settings_file)}
    gt_stamps, gt_poses = provider.ground_truth()
    if len(gt_stamps):
        gt_file = sidecar(out, "groundtruth.tum")
        _core.write_tum(str(gt_file), np.asarray(gt_stamps) + offset, gt_poses)
        files["groundtruth"] = str(gt_file)
    return {"kind": opts.kind, "path": str(opts.path), "sensor": sensor, "stamp_offset": offset,
            "topics": {role: name for role, topic in dataclasses.asdict(topics).items() if isinstance(topic, str)
                       for name in (topic, topic + "/compressed", topic + "/compressedDepth") if name in conn},
            "depth_encoding": opts.depth_encoding if topics.depth else None,
            "image_transport": opts.image_transport, **counts, "files": files}
