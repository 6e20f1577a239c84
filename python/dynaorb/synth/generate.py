"""`dynaorb synth`: render a synthetic dynamic sequence with exact ground truth.

RGB-D sequences are written in the TUM layout, stereo and mono in the KITTI
layout. Beside the images: per-frame ground-truth dynamic masks (255 on moving
objects), label images with PASCAL VOC ids (person 15, car 7: what a
segmentation network outputs, the parked car included), settings.yaml in the
ORB-SLAM2 format and synth.json describing the scene. Deterministic per seed.
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import json
import os
import pathlib

import numpy as np

from dynaorb.image_files import write_image
from dynaorb.synth.scene import Renderer, build_loop_scene, build_scene
from dynaorb.synth.textures import TextureBank, default_texture_dir

SENSORS = ("rgbd", "stereo", "mono")
PATHS = ("forward", "loop")


@dataclasses.dataclass
class SynthConfig:
    sensor: str = "rgbd"
    movers: int = 3
    frames: int = 90
    seed: int = 0
    width: int = 640
    height: int = 480
    fx: float = 525.0
    fps: float | None = None        # default: 30 (rgbd), 20 (stereo, mono)
    baseline: float = 0.12          # stereo baseline [m]
    depth_factor: float = 5000.0    # TUM's 16-bit depth scale
    max_depth: float = 12.0         # farther depth is written as 0 (no measurement)
    noise_sigma: float = 1.5        # image noise, grey levels
    textures: str | None = None     # folder of real images; default ../shared/data
    # "forward": down a long room (CameraPath); "loop": laps of a closed circuit in a closed
    # room (LoopPath, one lap every lap_period seconds; no movers), for loop closing.
    path: str = "forward"
    lap_period: float = 12.0
    features: int = 1000            # ORBextractor.nFeatures written to settings.yaml

    def rate(self) -> float:
        return self.fps or (30.0 if self.sensor == "rgbd" else 20.0)


def _intrinsics(c: SynthConfig) -> np.ndarray:
    return np.array([[c.fx, 0, (c.width - 1) / 2], [0, c.fx, (c.height - 1) / 2], [0, 0, 1]])


def _settings_yaml(c: SynthConfig, K: np.ndarray) -> str:
    lines = ["%YAML:1.0", f"# dynaorb synth: {c.sensor}, {c.movers} movers, seed {c.seed}",
             f"Camera.fx: {K[0, 0]}", f"Camera.fy: {K[1, 1]}", f"Camera.cx: {K[0, 2]}", f"Camera.cy: {K[1, 2]}",
             "Camera.k1: 0.0", "Camera.k2: 0.0", "Camera.p1: 0.0", "Camera.p2: 0.0",
             f"Camera.width: {c.width}", f"Camera.height: {c.height}", f"Camera.fps: {c.rate()}",
             "Camera.RGB: 0"]  # images are written as BGR PNGs
    if c.sensor == "rgbd":
        lines += [f"Camera.bf: {K[0, 0] * 0.08}", "ThDepth: 40.0", f"DepthMapFactor: {c.depth_factor}"]
    elif c.sensor == "stereo":
        lines += [f"Camera.bf: {K[0, 0] * c.baseline}", "ThDepth: 40.0"]
    lines += [f"ORBextractor.nFeatures: {c.features}", "ORBextractor.scaleFactor: 1.2", "ORBextractor.nLevels: 8",
              "ORBextractor.iniThFAST: 20", "ORBextractor.minThFAST: 7"]
    return "\n".join(lines) + "\n"


def _quaternion(R: np.ndarray) -> np.ndarray:
    """(qx, qy, qz, qw) of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_quat()


class _Layout:
    """Where files go: TUM (rgbd) or KITTI (stereo, mono) layout."""

    def __init__(self, out: pathlib.Path, c: SynthConfig):
        self.out, self.c = out, c
        self.tum = c.sensor == "rgbd"
        self.seq = out if self.tum else out / "sequences" / "00"
        dirs = ["rgb", "depth"] if self.tum else ["image_0"] + (["image_1"] if c.sensor == "stereo" else [])
        for d in dirs + ["labels", "dynamic_masks"]:
            (self.seq / d).mkdir(parents=True, exist_ok=True)
        if not self.tum:
            (out / "poses").mkdir(parents=True, exist_ok=True)

    def name(self, i: int, stamp: float) -> str:
        return f"{stamp:.6f}.png" if self.tum else f"{i:06d}.png"


def _scene(c: SynthConfig):
    """The room, path and movers of a configuration, and the texture bank they took their
    textures from (deterministic per seed)."""
    rng = np.random.default_rng(c.seed)
    source = pathlib.Path(c.textures) if c.textures else default_texture_dir()
    bank = TextureBank(rng, source)
    duration = (c.frames - 1) / c.rate()
    if c.path == "loop":
        return build_loop_scene(bank, rng, duration=duration, colour=c.sensor == "rgbd", period=c.lap_period), bank
    return build_scene(bank, rng, movers=c.movers, duration=duration, colour=c.sensor == "rgbd",
                       long_room_bank=TextureBank(np.random.default_rng([c.seed, 1]), source)), bank


def generate(out: str | pathlib.Path, config: SynthConfig, progress=None, threads: int | None = None) -> dict:
    """Renders the sequence into `out`; returns the summary written to synth.json.
    threads: frames rendered at once (None or 0: one per core); the files are the same."""
    c = config
    if c.sensor not in SENSORS:
        raise ValueError(f"sensor must be one of {SENSORS}, not {c.sensor!r}")
    if c.frames < 2 or c.movers < 0:
        raise ValueError("need frames >= 2 and movers >= 0")
    if c.path not in PATHS:
        raise ValueError(f"path must be one of {PATHS}, not {c.path!r}")
    if c.path == "loop" and c.movers:
        raise ValueError("the loop path has no movers (movers=0)")
    out = pathlib.Path(out)
    scene, bank = _scene(c)
    duration = scene.duration
    K = _intrinsics(c)
    renderer = Renderer(K, c.width, c.height)
    layout = _Layout(out, c)
    T0_inv = np.linalg.inv(scene.path.pose(0.0))
    T_right = np.eye(4)
    T_right[0, 3] = c.baseline

    labels_of_box = np.array([b.label for b in scene.boxes] + [0], np.uint8)  # index -1 -> 0
    t0 = 1_000_000.0 if layout.tum else 0.0  # TUM-like epoch stamps

    def render_frame(i: int) -> tuple:
        """Frame i's images written; (pose, stamp, dynamic pixel fraction). Reads the scene
        only, and its noise comes from its own generator: frames render independently."""
        t = i / c.rate()
        stamp = t0 + t
        T_room_cam = scene.path.pose(t)
        image, depth, box = renderer.render(scene, T_room_cam, t)
        moving = np.array([b.moving_at(t) for b in scene.boxes] + [False])
        dyn = np.where(moving[box], 255, 0).astype(np.uint8)
        labels = labels_of_box[box]
        frame_rng = np.random.default_rng([c.seed, i])
        name = layout.name(i, stamp)

        def finish(img):
            img = img + frame_rng.normal(0.0, c.noise_sigma, img.shape).astype(np.float32)
            return np.clip(img + 0.5, 0, 255).astype(np.uint8)

        if layout.tum:
            write_image(layout.seq / "rgb" / name, finish(image))
            d16 = np.where(depth <= c.max_depth, np.round(depth * c.depth_factor), 0).astype(np.uint16)
            write_image(layout.seq / "depth" / name, d16)
        else:
            write_image(layout.seq / "image_0" / name, finish(image))
            if c.sensor == "stereo":
                right, _, _ = renderer.render(scene, T_room_cam @ T_right, t)
                write_image(layout.seq / "image_1" / name, finish(right))
        write_image(layout.seq / "labels" / name, labels)
        write_image(layout.seq / "dynamic_masks" / name, dyn)
        return T0_inv @ T_room_cam, stamp, float(np.count_nonzero(dyn)) / dyn.size

    # Frames on a thread per core (NumPy's array operations and OpenCV's remap and PNG
    # encoding release the GIL): the same files as one at a time, in about half the time
    # on two cores.
    # A failure or Ctrl-C cancels the frames not started: only those being rendered finish.
    poses, stamps, dynamic_fraction = [], [], []
    workers = max(1, min(threads or os.cpu_count() or 1, c.frames))
    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        futures = [pool.submit(render_frame, i) for i in range(c.frames)]
        try:
            for i in range(c.frames) if progress is None else progress(range(c.frames)):
                pose, stamp, fraction = futures[i].result()
                poses.append(pose)
                stamps.append(stamp)
                dynamic_fraction.append(fraction)
        except BaseException:
            for f in futures:
                f.cancel()
            raise

    _write_index(layout, stamps, poses)
    (layout.seq / "settings.yaml").write_text(_settings_yaml(c, K))
    summary = {
        "config": dataclasses.asdict(c),
        "layout": "tum" if layout.tum else "kitti",
        "sequence": str(layout.seq),
        "texture_source": str(bank.source) if bank.source else "procedural",
        "duration_s": duration,
        "objects": [{"name": b.name, "label": b.label, "moving": b.moving,
                     "velocity": b.velocity.tolist(), "lo": b.lo.tolist(), "hi": b.hi.tolist()}
                    for b in scene.boxes],
        "dynamic_pixel_fraction": {"mean": float(np.mean(dynamic_fraction)),
                                   "max": float(np.max(dynamic_fraction))},
        "path_length_m": float(sum(np.linalg.norm(poses[k + 1][:3, 3] - poses[k][:3, 3])
                                   for k in range(len(poses) - 1))),
    }
    (out / "synth.json").write_text(json.dumps(summary, indent=2))
    return summary


def _write_index(layout: _Layout, stamps: list, poses: list) -> None:
    seq = layout.seq
    if layout.tum:
        for kind in ("rgb", "depth"):
            with open(seq / f"{kind}.txt", "w") as f:
                f.write(f"# {kind} images (dynaorb synth)\n# timestamp filename\n")
                for i, s in enumerate(stamps):
                    f.write(f"{s:.6f} {kind}/{layout.name(i, s)}\n")
        with open(seq / "groundtruth.txt", "w") as f:
            f.write("# ground truth trajectory (dynaorb synth, exact)\n# timestamp tx ty tz qx qy qz qw\n")
            for s, T in zip(stamps, poses):
                q = _quaternion(T[:3, :3])
                f.write(f"{s:.6f} " + " ".join(f"{v:.9f}" for v in (*T[:3, 3], *q)) + "\n")
        return
    with open(seq / "times.txt", "w") as f:
        f.writelines(f"{s:.6e}\n" for s in stamps)
    K = _intrinsics(layout.c)
    with open(seq / "calib.txt", "w") as f:
        for n, tx in enumerate([0.0, -K[0, 0] * layout.c.baseline, 0.0, 0.0]):
            P = np.hstack([K, np.array([[tx], [0.0], [0.0]])])
            f.write(f"P{n}: " + " ".join(f"{v:.12e}" for v in P.ravel()) + "\n")
    with open(layout.out / "poses" / "00.txt", "w") as f:
        for T in poses:
            f.write(" ".join(f"{v:.9e}" for v in T[:3, :].ravel()) + "\n")
