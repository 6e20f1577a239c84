"""ORB-SLAM3 (pyorbslam3) on one sequence, for the benchmark's comparison.

Runs with the python of the peer's own virtual environment
(~/.cache/dynaorb/peer/orbslam3-venv): it never imports dynaorb, and dynaorb
never imports pyorbslam3 (GPL: a measuring stick, run as a separate program).

    orbslam3_worker.py MANIFEST.json

MANIFEST.json (written by dynaorb.peer.orbslam3): sensor, settings (ORB-SLAM3
settings file), vocabulary (ORBvoc.txt), frames [{stamp, image, right?,
depth?}], trajectory (TUM file to write), result (JSON to write), and
optionally realtime (a rate: each frame is handed over once its stamp, scaled
by 1 / rate, has passed since the first frame, as ORB-SLAM3's own example
runners and dynaorb's `--realtime` deliver frames; the pacing is dynaorb's
runner/pacing.py, a file without imports of dynaorb, loaded by its path).

Each track call is timed with a wall clock, image loading outside the timed
window (ORB-SLAM3 rectifies stereo pairs inside the call, as dynaorb does).
The result holds per frame: ms, tracking state and tracked map points; the
trajectory ORB-SLAM3 saves at shutdown (its keyframe-relative poses),
converted from its EuRoC file (nanoseconds) to TUM (seconds); and how many
keyframes its map holds then (from its keyframe trajectory file).
"""
from __future__ import annotations

import collections
import importlib.util
import json
import os
import pathlib
import statistics
import sys
import time

import cv2
import numpy as np


def _read(path: str, flags=cv2.IMREAD_UNCHANGED):
    image = cv2.imread(path, flags)
    if image is None:
        raise FileNotFoundError(f"{path}: cannot read the image")
    return image


def _euroc_to_tum(src: str, dst: str) -> tuple[int, int]:
    """ORB-SLAM3's EuRoC trajectory (stamp in ns, t, q xyzw) as a TUM file: (poses written, repeats dropped).

    ORB-SLAM3 (pyorbslam3 0.1.1) sometimes writes one frame's line twice: on the synthetic monocular
    room with movers, frame 1.10 s, tracked, then "recently lost" with 1.15 s, is saved twice with the
    same stamp and pose and 1.15 s not at all. A line whose stamp repeats the line before it is
    dropped (the first is kept), so the file has the increasing stamps a TUM trajectory needs."""
    rows, repeats = [], 0
    if os.path.isfile(src):
        for line in open(src):
            fields = line.replace(",", " ").split()
            if len(fields) == 8 and not line.startswith("#"):
                row = [float(fields[0]) * 1e-9] + [float(x) for x in fields[1:]]
                if rows and row[0] == rows[-1][0]:
                    repeats += 1
                    continue
                rows.append(row)
    with open(dst, "w") as f:
        for r in rows:
            f.write(f"{r[0]:.9f} " + " ".join(f"{x:.9f}" for x in r[1:]) + "\n")
    return len(rows), repeats


def _keyframes(slam, path: str) -> int | None:
    """The keyframes of ORB-SLAM3's map at shutdown (the poses it saves for them), None where it cannot say."""
    try:
        slam.save_keyframe_trajectory_tum(path)
        with open(path) as f:
            return sum(1 for line in f if line.strip() and not line.startswith("#"))
    except (AttributeError, OSError, RuntimeError):  # an older pyorbslam3, or nothing written
        return None


def _vm_hwm_mb() -> float | None:
    """Peak resident memory of this process since its exec (ru_maxrss would include the parent's at fork)."""
    try:
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError):
        pass
    return None


def _version(package: str) -> str | None:
    try:
        from importlib.metadata import version

        return version(package)
    except Exception:  # metadata missing: the version is unknown, not an error
        return None


def _pacer(rate):
    """dynaorb.runner.pacing.Pacer for `rate`, loaded from its file (this program never imports dynaorb)."""
    path = pathlib.Path(__file__).resolve().parents[1] / "runner" / "pacing.py"
    spec = importlib.util.spec_from_file_location("dynaorb_pacing", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.Pacer(float(rate))


def main(manifest_path: str) -> int:
    manifest = json.load(open(manifest_path))
    import pyorbslam3 as pos

    sensor = {"mono": pos.Sensor.MONOCULAR, "stereo": pos.Sensor.STEREO, "rgbd": pos.Sensor.RGBD}[manifest["sensor"]]
    t0 = time.perf_counter()
    slam = pos.Slam(manifest["vocabulary"], manifest["settings"], sensor, use_viewer=False)
    init_s = time.perf_counter() - t0
    per_frame = []
    states = collections.Counter()
    pacer = _pacer(manifest["realtime"]) if manifest.get("realtime") else None
    loop_start = time.perf_counter()
    for frame in manifest["frames"]:
        # Every image of the frame is read before the frame is due, as dynaorb's runner loads its frames.
        image = _read(frame["image"])
        stamp = float(frame["stamp"])
        if manifest["sensor"] == "stereo":
            right = _read(frame["right"])
        elif manifest["sensor"] == "rgbd":
            depth = _read(frame["depth"]).astype(np.float32)  # raw units: RGBD.DepthMapFactor scales them
        if pacer:
            pacer.wait(stamp)
        t = time.perf_counter()
        if manifest["sensor"] == "stereo":
            r = slam.track_stereo(image, right, stamp)
        elif manifest["sensor"] == "rgbd":
            r = slam.track_rgbd(image, depth, stamp)
        else:
            r = slam.track_monocular(image, stamp)
        ms = 1000.0 * (time.perf_counter() - t)
        state = str(r.state).split(".")[-1]
        states[state] += 1
        per_frame.append({"stamp": stamp, "ms": ms, "state": state, "tracked_points": int(r.num_tracked_points)})
    loop_s = time.perf_counter() - loop_start
    slam.shutdown()
    euroc = manifest["trajectory"] + ".euroc"
    slam.save_trajectory_euroc(euroc)
    poses, repeats = _euroc_to_tum(euroc, manifest["trajectory"])
    keyframes = _keyframes(slam, manifest["trajectory"] + ".keyframes")
    ms = [f["ms"] for f in per_frame]
    result = {
        "pyorbslam3": _version("pyorbslam3"),
        "frames": len(per_frame),
        "states": dict(states),
        "tracked_frames": states.get("OK", 0),
        "trajectory_poses": poses,
        "trajectory_repeats_dropped": repeats,
        "keyframes": keyframes,
        "init_s": init_s,
        "loop_s": loop_s,
        "track_call_ms_median": statistics.median(ms) if ms else None,
        "track_call_ms": ms,
        "peak_rss_mb_self": _vm_hwm_mb(),
        "realtime": pacer.summary() if pacer else None,
        "per_frame": per_frame,
    }
    with open(manifest["result"], "w") as f:
        json.dump(result, f)
    sys.stdout.flush()
    sys.stderr.flush()
    # ORB-SLAM3's destructors can crash after a clean shutdown; the results are written.
    os._exit(0)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: orbslam3_worker.py MANIFEST.json", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
