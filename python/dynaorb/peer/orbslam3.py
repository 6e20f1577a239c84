"""ORB-SLAM3 as the benchmark's measuring stick, through the PyPI package pyorbslam3.

ORB-SLAM3 is GPL: dynaorb never links, imports or vendors it. This module
installs pyorbslam3 into a virtual environment of its own, writes what the
peer needs (ORB-SLAM3 settings, our vocabulary as ORBvoc.txt text, a JSON
manifest of the frames) and runs orbslam3_worker.py with that environment's
python as a separate program; the trajectory it writes is evaluated here with
dynaorb's own evaluation (evo), against the same ground truth.

Fairness: the same image files, the same calibration (from dynaorb's settings
for the sequence), the same ORB extractor settings (features, scale factor,
levels, FAST thresholds), the same vocabulary. Stereo pairs are rectified
by ORB-SLAM3 itself inside its track call (see orbslam3_settings), as
dynaorb's track call rectifies inside its own.
"""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import subprocess
import sys

import numpy as np

PYORBSLAM3 = "pyorbslam3==0.1.1"
PACKAGES = (PYORBSLAM3, "numpy", "opencv-python-headless")
WORKER = pathlib.Path(__file__).with_name("orbslam3_worker.py")
# pyorbslam3's wheel needs these runtime libraries of the host (its README);
# Debian packages: libgl1 libegl1 libopengl0 libglx0 libsm6 libice6 libx11-6 libxext6.
RUNTIME_LIBS = ("libOpenGL.so.0", "libGLX.so.0", "libEGL.so.1", "libX11.so.6", "libXext.so.6",
                "libSM.so.6", "libICE.so.6")


class PeerUnavailable(RuntimeError):
    """pyorbslam3 cannot be installed or loaded here; the message says why."""


def cache_root() -> pathlib.Path:
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "dynaorb" / "peer"


def default_venv() -> pathlib.Path:
    return cache_root() / "orbslam3-venv"


def missing_runtime_libs() -> list[str]:
    """The libraries of RUNTIME_LIBS that the dynamic loader cannot open."""
    import ctypes

    missing = []
    for lib in RUNTIME_LIBS:
        try:
            ctypes.CDLL(lib)
        except OSError:
            missing.append(lib)
    return missing


def _venv_python(venv: pathlib.Path) -> pathlib.Path:
    return venv / "bin" / "python"


def _check(python: pathlib.Path) -> str | None:
    """None when pyorbslam3 imports with that python, else the error."""
    proc = subprocess.run([str(python), "-c", "import pyorbslam3, cv2, numpy"], capture_output=True, text=True,
                          timeout=120)
    return None if proc.returncode == 0 else (proc.stderr.strip().splitlines() or ["import failed"])[-1]


def ensure_venv(venv: pathlib.Path | None = None, log=print) -> pathlib.Path:
    """The python of a virtual environment holding PACKAGES, created and installed on first use."""
    venv = pathlib.Path(venv) if venv else default_venv()
    python = _venv_python(venv)
    marker = venv / "dynaorb-peer.json"
    if python.is_file() and marker.is_file() and json.loads(marker.read_text()).get("packages") == list(PACKAGES):
        error = _check(python)
        if error is None:
            return python
        log(f"peer venv {venv}: {error}; installing again")
    missing = missing_runtime_libs()
    if missing:
        raise PeerUnavailable(f"runtime libraries missing: {', '.join(missing)} (Debian: apt-get install "
                              "libgl1 libegl1 libopengl0 libglx0 libsm6 libice6 libx11-6 libxext6)")
    base = getattr(sys, "_base_executable", None) or sys.executable
    try:
        if not python.is_file():
            log(f"creating the peer's virtual environment {venv}")
            subprocess.run([base, "-m", "venv", str(venv)], check=True, capture_output=True, text=True, timeout=300)
        log(f"installing {', '.join(PACKAGES)} into {venv}")
        subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *PACKAGES],
                       check=True, capture_output=True, text=True, timeout=900)
    except subprocess.CalledProcessError as exc:
        tail = "\n".join((exc.stderr or exc.stdout or "").strip().splitlines()[-5:])
        raise PeerUnavailable(f"cannot install {PYORBSLAM3} into {venv}: {tail}") from None
    except subprocess.TimeoutExpired as exc:
        raise PeerUnavailable(f"installing {PYORBSLAM3} timed out ({exc.timeout:.0f} s)") from None
    error = _check(python)
    if error is not None:
        raise PeerUnavailable(f"{PYORBSLAM3} installed in {venv} but does not load: {error}")
    marker.write_text(json.dumps({"packages": list(PACKAGES)}))
    return python


def vocabulary_text(spec: str = "default") -> pathlib.Path:
    """Our vocabulary (`default`: dynaorb's own, or a binary file) written once in ORBvoc.txt text."""
    from dynaorb import core

    if spec == "default":
        from dynaorb.vocab import build_default

        source = pathlib.Path(build_default())
    else:
        source = pathlib.Path(spec)
    if source.suffix == ".txt":
        return source
    target = cache_root() / "vocab" / f"{source.stem}.txt"
    if not target.is_file() or target.stat().st_mtime < source.stat().st_mtime:
        target.parent.mkdir(parents=True, exist_ok=True)
        part = target.with_name(f"{target.name}.{os.getpid()}.part")
        core().Vocabulary.load(str(source)).save_text(str(part))
        part.replace(target)
    return target


# --- settings ---------------------------------------------------------------------------------------------

def read_settings(path: pathlib.Path) -> dict:
    """The fields of an ORB-SLAM2 settings YAML (what dynaorb runs with) that the peer needs."""
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    if not fs.isOpened():
        raise FileNotFoundError(f"{path}: cannot read the settings")
    out = {}
    for key in ("Camera.fx", "Camera.fy", "Camera.cx", "Camera.cy", "Camera.k1", "Camera.k2", "Camera.p1",
                "Camera.p2", "Camera.k3", "Camera.width", "Camera.height", "Camera.fps", "Camera.RGB", "Camera.bf",
                "ThDepth", "DepthMapFactor", "ORBextractor.nFeatures", "ORBextractor.scaleFactor",
                "ORBextractor.nLevels", "ORBextractor.iniThFAST", "ORBextractor.minThFAST"):
        node = fs.getNode(key)
        if not node.empty():
            out[key] = node.real()
    for side in ("LEFT", "RIGHT"):
        mats = {m: fs.getNode(f"{side}.{m}") for m in ("K", "D", "R", "P")}
        if all(not n.empty() for n in mats.values()):
            out[side] = {m: n.mat().reshape(-1).tolist() for m, n in mats.items()}
    fs.release()
    return out


VIEWER = {  # read by pyorbslam3's ORB-SLAM3 settings parser even without a viewer; unused
    "Viewer.KeyFrameSize": 0.05, "Viewer.KeyFrameLineWidth": 1.0, "Viewer.GraphLineWidth": 0.9,
    "Viewer.PointSize": 2.0, "Viewer.CameraSize": 0.08, "Viewer.CameraLineWidth": 3.0, "Viewer.ViewpointX": 0.0,
    "Viewer.ViewpointY": -0.7, "Viewer.ViewpointZ": -1.8, "Viewer.ViewpointF": 500.0,
}


def _real(v: float) -> str:
    """A number ORB-SLAM3's parser reads as real: it refuses 35 where it wants a float."""
    text = f"{float(v):.10g}"
    return text if any(c in text for c in ".en") else text + ".0"


def orbslam3_settings(ours: dict, sensor: str) -> str:
    """ORB-SLAM3 File.version 1.0 settings text for dynaorb's settings of a sequence.

    Stereo is always given as a PinHole pair with Stereo.T_c1_c2 (pose of the
    right camera in the left), so ORB-SLAM3 rectifies inside its track call:
    - pairs dynaorb rectifies (EuRoC: LEFT/RIGHT K, D, R, P): the raw cameras
      and T_c1_c2 = [R_l^T R_r | R_l^T (b, 0, 0)], b = bf / fx; ORB-SLAM3
      computes its own rectification (cv::stereoRectify, alpha -1), whose
      rectified camera differs a little from dynaorb's;
    - rectified pairs (KITTI, synthetic): both cameras the rectified one, no
      distortion, T_c1_c2 = [I | (b, 0, 0)]: the maps ORB-SLAM3 computes are
      the identity (to 2e-5 px), so it tracks the same images, plus a remap
      of each image inside its call. pyorbslam3 0.1.1 cannot take
      Camera.type "Rectified": ORB-SLAM3 prints the settings through a null
      second camera and crashes.
    ThDepth keeps ORB-SLAM's meaning (times the baseline) in both systems;
    RGB-D depth is raw, scaled by RGBD.DepthMapFactor.
    """
    need = ("Camera.fx", "Camera.fy", "Camera.cx", "Camera.cy", "Camera.width", "Camera.height")
    missing = [k for k in need if k not in ours]
    if missing:
        raise ValueError(f"settings lack {', '.join(missing)}")
    lines = ['%YAML:1.0', 'File.version: "1.0"', 'Camera.type: "PinHole"']
    dist = [ours.get(f"Camera.{k}", 0.0) for k in ("k1", "k2", "p1", "p2")]
    if sensor == "stereo" and "LEFT" in ours and "RIGHT" in ours:
        for cam, side in (("Camera1", "LEFT"), ("Camera2", "RIGHT")):
            K, D = ours[side]["K"], ours[side]["D"]
            lines += [f"{cam}.fx: {_real(K[0])}", f"{cam}.fy: {_real(K[4])}", f"{cam}.cx: {_real(K[2])}",
                      f"{cam}.cy: {_real(K[5])}"]
            lines += [f"{cam}.{k}: {_real(v)}" for k, v in zip(("k1", "k2", "p1", "p2", "k3"), D)]
        R_l = np.asarray(ours["LEFT"]["R"], float).reshape(3, 3)
        R_r = np.asarray(ours["RIGHT"]["R"], float).reshape(3, 3)
        T = np.eye(4)
        T[:3, :3] = R_l.T @ R_r
        T[:3, 3] = R_l.T @ np.array([ours["Camera.bf"] / ours["Camera.fx"], 0.0, 0.0])
    else:
        cams = ("Camera1", "Camera2") if sensor == "stereo" else ("Camera1",)
        for cam in cams:
            lines += [f"{cam}.{k}: {_real(ours['Camera.' + k])}" for k in ("fx", "fy", "cx", "cy")]
        if sensor != "stereo" and any(d != 0.0 for d in dist + [ours.get("Camera.k3", 0.0)]):
            lines += [f"Camera1.{k}: {_real(v)}" for k, v in zip(("k1", "k2", "p1", "p2"), dist)]
            if ours.get("Camera.k3", 0.0) != 0.0:
                lines.append(f"Camera1.k3: {_real(ours['Camera.k3'])}")
        T = np.eye(4)
        if sensor == "stereo":
            T[0, 3] = ours["Camera.bf"] / ours["Camera.fx"]
    lines += [f"Camera.width: {int(ours['Camera.width'])}", f"Camera.height: {int(ours['Camera.height'])}",
              f"Camera.fps: {int(round(ours.get('Camera.fps', 30.0)))}",
              f"Camera.RGB: {int(ours.get('Camera.RGB', 1))}"]
    if sensor in ("stereo", "rgbd"):
        if "Camera.bf" not in ours or "ThDepth" not in ours:
            raise ValueError(f"{sensor} settings need Camera.bf and ThDepth")
        lines.append(f"Stereo.ThDepth: {_real(ours['ThDepth'])}")
    if sensor == "stereo":
        lines += ["Stereo.T_c1_c2: !!opencv-matrix", "   rows: 4", "   cols: 4", "   dt: f",
                  "   data: [" + ", ".join(_real(v) for v in T.reshape(-1)) + "]"]
    if sensor == "rgbd":
        lines += [f"Stereo.b: {_real(ours['Camera.bf'] / ours['Camera.fx'])}",
                  f"RGBD.DepthMapFactor: {_real(ours.get('DepthMapFactor', 1.0))}"]
    for k in ("nFeatures", "scaleFactor", "nLevels", "iniThFAST", "minThFAST"):
        v = ours[f"ORBextractor.{k}"]
        lines.append(f"ORBextractor.{k}: {_real(v)}" if k == "scaleFactor" else f"ORBextractor.{k}: {int(v)}")
    lines += [f"{k}: {_real(v)}" for k, v in VIEWER.items()]
    return "\n".join(lines) + "\n"


# --- frames ---------------------------------------------------------------------------------------------

def _tum_depth_list(root: pathlib.Path) -> tuple[np.ndarray, list[str]]:
    stamps, names = [], []
    for line in (root / "depth.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            s, name = line.split()[:2]
            stamps.append(float(s))
            names.append(str(root / name))
    return np.asarray(stamps), names


def frame_list(kind: str, path: str, sensor: str, max_diff: float = 0.02) -> list[dict]:
    """[{stamp, image, right?, depth?}] of the frames dynaorb's reader yields for this sequence
    (its stamps and left/colour image paths); the right image and depth files beside them.

    TUM depth: the depth.txt entry nearest in time, within max_diff s (TUM's associate.py default)."""
    from dynaorb import core

    provider = core().open_dataset(kind, path, sensor)
    depth = _tum_depth_list(pathlib.Path(path)) if sensor == "rgbd" and kind == "tum" else None
    frames = []
    for i in range(len(provider)):
        try:
            image = provider.load(i).image_path
        except core().InputError:
            continue  # unreadable for us: left out for the peer too
        entry = {"stamp": provider.stamp(i), "image": image}
        p = pathlib.Path(image)
        if sensor == "stereo":
            if kind == "euroc":
                right = p.parents[2] / "cam1" / "data" / p.name
            elif kind == "kitti":
                right = p.parents[1] / "image_1" / p.name
            else:
                raise ValueError(f"stereo {kind}: no right image layout known")
            entry["right"] = str(right)
        elif sensor == "rgbd":
            if depth is None:
                raise ValueError(f"rgbd {kind}: no depth layout known")
            j = int(np.argmin(np.abs(depth[0] - entry["stamp"])))
            if abs(depth[0][j] - entry["stamp"]) > max_diff:
                continue
            entry["depth"] = depth[1][j]
        frames.append(entry)
    return frames


@dataclasses.dataclass
class PeerCase:
    kind: str
    path: str
    sensor: str
    out: pathlib.Path
    realtime: float = 0.0  # > 0: frames paced at this multiple of the recording's rate (the worker's manifest)


def prepare(case: PeerCase, vocabulary: pathlib.Path) -> pathlib.Path:
    """Writes settings.yaml, manifest.json (and our settings as ours.yaml) into case.out; the manifest path."""
    from dynaorb import core

    out = case.out
    out.mkdir(parents=True, exist_ok=True)
    provider = core().open_dataset(case.kind, case.path, case.sensor)
    provider.default_settings().save(str(out / "ours.yaml"))
    (out / "settings.yaml").write_text(orbslam3_settings(read_settings(out / "ours.yaml"), case.sensor))
    manifest = {"sensor": case.sensor, "settings": str(out / "settings.yaml"), "vocabulary": str(vocabulary),
                "frames": frame_list(case.kind, case.path, case.sensor),
                "trajectory": str(out / "trajectory.tum"), "result": str(out / "peer.json")}
    if case.realtime:
        manifest["realtime"] = case.realtime
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return out / "manifest.json"


def run(case: PeerCase, python: pathlib.Path, vocabulary: pathlib.Path, timeout_s: float = 900.0) -> dict:
    """Runs the worker on one sequence and evaluates its trajectory; a dict like our runs' stats."""
    from dynaorb.bench.process import run_child

    manifest = prepare(case, vocabulary)
    child = run_child([str(python), str(WORKER), str(manifest)], case.out / "worker.log", timeout_s,
                      env={k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")})
    stats = {"peak_rss_mb": child.peak_rss_mb, "wall_s": child.wall_s, "log": child.log}
    result_file = case.out / "peer.json"
    if not result_file.is_file():
        stats["error"] = (child.failure() or "no result written") + "\n" + child.log_tail()
        return stats
    peer = json.loads(result_file.read_text())
    stats["peak_rss_mb"] = max(v for v in (child.peak_rss_mb, peer.get("peak_rss_mb_self"), 0.0) if v is not None)
    stats.update({k: peer[k] for k in ("pyorbslam3", "frames", "states", "tracked_frames", "init_s",
                                       "track_call_ms_median", "track_call_ms", "trajectory_poses")})
    stats["trajectory_repeats_dropped"] = peer.get("trajectory_repeats_dropped")
    stats["keyframes"] = peer.get("keyframes")  # in its map at shutdown
    stats["realtime"] = peer.get("realtime")
    stats["tracked_fraction"] = peer["tracked_frames"] / max(peer["frames"], 1)
    # Frames over the loop's wall time (image loading included), as dynaorb's runner counts fps.
    stats["fps"] = peer["frames"] / peer["loop_s"] if peer["loop_s"] > 0 else None
    if child.failure():
        stats["exit"] = child.failure()  # e.g. a crash at exit after the results were written
    stats.update(evaluate(case, case.out / "trajectory.tum"))
    return stats


def evaluate(case: PeerCase, trajectory: pathlib.Path) -> dict:
    """ATE / RPE of the peer's trajectory as dynaorb's runs are evaluated (SE3, Sim3 for mono)."""
    from dynaorb import core
    from dynaorb.runner.run import _evaluate

    provider = core().open_dataset(case.kind, case.path, case.sensor)
    stamps, poses = [], []
    for line in trajectory.read_text().splitlines() if trajectory.is_file() else []:
        f = [float(x) for x in line.split()]
        if len(f) != 8:
            continue
        stamps.append(f[0])
        poses.append(_pose(f[1:4], f[4:8]))
    return _evaluate(provider, np.asarray(stamps), np.asarray(poses).reshape(-1, 4, 4), case.sensor, case.out)


def _pose(t, q_xyzw) -> np.ndarray:
    x, y, z, w = q_xyzw
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    T[:3, 3] = t
    return T
