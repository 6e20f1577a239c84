"""ORB-SLAM2 settings from a bag's sensor_msgs/CameraInfo, for bags recorded
on a robot that carry no settings file.

The camera's own calibration fills the Camera.* keys by the node's rules
(`~use_camera_info`, ros/node_config.cc apply_camera_info): stereo images are
rectified and take their intrinsics from P, the baseline from the right
camera's P[3] = -fx * baseline; mono and RGB-D take K and the plumb_bob
distortion D. What a CameraInfo does not hold comes from ORB-SLAM2's own
settings files: the ORB extractor of its TUM / EuRoC files (1000 features,
scale 1.2, 8 levels, FAST 20 / 7), ThDepth 40 (RGB-D) or 35 (stereo), and for
RGB-D the virtual baseline of its TUM files (Camera.bf = fx * 0.08 m). Depth
units: 16UC1 depth is millimetres (REP-118: DepthMapFactor 1000), 32FC1 is
metres (written as 16-bit PNG at TUM's 5000 per metre by `bag to-dataset`).
Camera.RGB is 0: colour reaches the System in OpenCV's BGR order, from a bag
(converted whatever its encoding) as from the PNGs `bag to-dataset` writes.
"""
from __future__ import annotations

import math

# ORB-SLAM2's values for what CameraInfo does not carry.
N_FEATURES = 1000
SCALE_FACTOR = 1.2
N_LEVELS = 8
INI_TH_FAST = 20
MIN_TH_FAST = 7
TH_DEPTH = {"rgbd": 40.0, "stereo": 35.0}
RGBD_VIRTUAL_BASELINE_M = 0.08      # TUM1-3.yaml: Camera.bf 40 for fx ~ 520
DEPTH_MAP_FACTOR = {"16UC1": 1000.0, "mono16": 1000.0, "32FC1": 5000.0}
_RADTAN = ("", "plumb_bob", "rational_polynomial")


def _positive(value: float, what: str) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"camera_info: {what} must be a positive number, got {value}")
    return value


def settings_yaml(sensor: str, left, right=None, *, fps: float, depth_encoding: str | None = None) -> str:
    """The settings YAML text for `sensor` from the image's CameraInfo `left`
    (and, stereo, the right image's `right`). ValueError naming what is missing
    or wrong (no size, no focal length, a distortion model other than
    plumb_bob, a right P[3] that is not -fx * baseline, an unknown depth encoding)."""
    if not left.width or not left.height:
        raise ValueError("camera_info: width and height must be set")
    lines = ["%YAML:1.0", "# From the bag's sensor_msgs/CameraInfo (dynaorb.ros.bag.camera_info); the ORB",
             "# extractor, ThDepth and the RGB-D virtual baseline are ORB-SLAM2's own values."]
    dist = [0.0, 0.0, 0.0, 0.0, 0.0]
    if sensor == "stereo":
        P = [float(v) for v in left.P]
        fx, fy, cx, cy = _positive(P[0], "P[0] (fx)"), _positive(P[5], "P[5] (fy)"), P[2], P[6]
        if right is None:
            raise ValueError("camera_info: stereo needs the right image's camera_info (its P holds the baseline)")
        bf = -float(right.P[3])
        if not (math.isfinite(bf) and bf > 0):
            raise ValueError(f"right camera_info: P[3] must be -fx * baseline < 0, got {right.P[3]}")
    else:
        K = [float(v) for v in left.K]
        fx, fy, cx, cy = _positive(K[0], "K[0] (fx)"), _positive(K[4], "K[4] (fy)"), K[2], K[5]
        if left.distortion_model not in _RADTAN:
            raise ValueError(f"camera_info: distortion model {left.distortion_model!r} is not plumb_bob")
        for i, v in enumerate(list(left.D)[:5]):
            dist[i] = float(v)
        bf = fx * RGBD_VIRTUAL_BASELINE_M if sensor == "rgbd" else None
    lines += [f"Camera.fx: {fx!r}", f"Camera.fy: {fy!r}", f"Camera.cx: {cx!r}", f"Camera.cy: {cy!r}",
              f"Camera.k1: {dist[0]!r}", f"Camera.k2: {dist[1]!r}", f"Camera.p1: {dist[2]!r}",
              f"Camera.p2: {dist[3]!r}", f"Camera.k3: {dist[4]!r}",
              f"Camera.width: {int(left.width)}", f"Camera.height: {int(left.height)}",
              f"Camera.fps: {_positive(fps, 'the image rate (fps)')!r}", "Camera.RGB: 0"]
    if bf is not None:
        lines += [f"Camera.bf: {bf!r}", f"ThDepth: {TH_DEPTH[sensor]!r}"]
    if sensor == "rgbd":
        if depth_encoding not in DEPTH_MAP_FACTOR:
            raise ValueError(f"depth encoding {depth_encoding!r} is not one of {', '.join(DEPTH_MAP_FACTOR)}")
        lines.append(f"DepthMapFactor: {DEPTH_MAP_FACTOR[depth_encoding]!r}")
    lines += [f"ORBextractor.nFeatures: {N_FEATURES}", f"ORBextractor.scaleFactor: {SCALE_FACTOR!r}",
              f"ORBextractor.nLevels: {N_LEVELS}", f"ORBextractor.iniThFAST: {INI_TH_FAST}",
              f"ORBextractor.minThFAST: {MIN_TH_FAST}"]
    return "\n".join(lines) + "\n"
