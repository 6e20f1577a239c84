"""Poses in a bag (a motion-capture or reference topic, or TF between two
frames) as a trajectory, and a trajectory sampled at other stamps.

The topic's poses are taken as they are, stamped with their headers: a
motion-capture system's body or marker pose, not necessarily the camera's
(an SE3-aligned ATE against the camera's trajectory then includes the lever
arm between the two).
"""
from __future__ import annotations


import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from dynaorb.ros.bag import messages as m

POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
              "geometry_msgs/msg/TransformStamped", "nav_msgs/msg/Odometry")


def _position_orientation(msg, msgtype: str):
    if msgtype == "geometry_msgs/msg/TransformStamped":
        return msg.transform.translation, msg.transform.rotation
    pose = msg.pose if msgtype == "geometry_msgs/msg/PoseStamped" else msg.pose.pose
    return pose.position, pose.orientation


def read_pose_topic(bag, topic: str) -> tuple[np.ndarray, np.ndarray]:
    """(stamps [s], 4x4 poses) of `topic`, in header-stamp order; repeated
    stamps keep the first. ValueError for a topic that is not in the bag, of a
    type that is not a stamped pose, or with a quaternion that is not one."""
    with m.open_bags(bag) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            raise ValueError(f"{bag}: topic {topic} is not in the bag (topics: "
                             f"{', '.join(sorted({c.topic for c in reader.connections}))})")
        msgtype = conns[0].msgtype
        if msgtype not in POSE_TYPES:
            raise ValueError(f"{bag}: topic {topic} carries {msgtype}, not a stamped pose "
                             f"({', '.join(POSE_TYPES)})")
        rows = {}
        for conn, _, raw in reader.messages(connections=conns):
            msg = m.deserialize(raw, conn.msgtype)
            stamp = _seconds(msg.header.stamp)
            key = m.stamp_ns(stamp)
            if key not in rows:  # a repeated stamp keeps the first
                p, q = _position_orientation(msg, conn.msgtype)
                rows[key] = (stamp, _matrix(p, q, f"{bag}: {topic} at {stamp:.6f}"))
    return _ordered(rows)


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _matrix(t, q, where: str) -> np.ndarray:
    """The 4x4 pose of translation t and quaternion q (message fields); ValueError
    naming `where` for a quaternion that is not a unit one."""
    xyzw = np.array([q.x, q.y, q.z, q.w], dtype=float)
    norm = float(np.linalg.norm(xyzw))
    if not (np.isfinite(norm) and abs(norm - 1.0) < 1e-3):
        raise ValueError(f"{where}: orientation {xyzw.tolist()} is not a unit quaternion")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(xyzw / norm).as_matrix()
    T[:3, 3] = [t.x, t.y, t.z]
    return T


def _ordered(rows: dict) -> tuple[np.ndarray, np.ndarray]:
    """{stamp ns: (stamp, pose)} as (stamps, N x 4 x 4 poses) in stamp order."""
    ordered = [rows[k] for k in sorted(rows)]
    return np.array([r[0] for r in ordered], dtype=float), np.array([r[1] for r in ordered]).reshape(-1, 4, 4)


def _frame(name: str) -> str:
    return name.strip().lstrip("/")


def read_tf(bag, parent: str, child: str) -> tuple[np.ndarray, np.ndarray]:
    """(stamps [s], 4x4 poses) of frame `child` in frame `parent` from the bag's
    TF topics (tf2_msgs/TFMessage or tf/tfMessage on any topic, /tf as TUM's
    bags carry the motion-capture pose), from the transforms that join the two
    directly (parent -> child, or child -> parent inverted); frame names
    without their leading slash. ValueError naming the pairs there are when
    none joins them."""
    parent, child = _frame(parent), _frame(child)
    if not parent or not child or parent == child:
        raise ValueError(f"ground truth from TF needs two different frames, got {parent!r} and {child!r}")
    rows, pairs = {}, set()
    with m.open_bags(bag) as reader:
        conns = [c for c in reader.connections if c.msgtype in m.TF_TYPES]
        if not conns:
            raise ValueError(f"{bag}: no TF topic ({' or '.join(m.TF_TYPES)})")
        for conn, _, raw in reader.messages(connections=conns):
            for tf in m.deserialize(raw, conn.msgtype).transforms:
                a, b = _frame(tf.header.frame_id), _frame(tf.child_frame_id)
                pairs.add((a, b))
                if (a, b) not in ((parent, child), (child, parent)):
                    continue
                stamp = _seconds(tf.header.stamp)
                key = m.stamp_ns(stamp)
                if key not in rows:  # a repeated stamp keeps the first
                    T = _matrix(tf.transform.translation, tf.transform.rotation, f"{bag}: TF {a} -> {b} at {stamp:.6f}")
                    rows[key] = (stamp, T if a == parent else np.linalg.inv(T))
    if not rows:
        raise ValueError(f"{bag}: no transform joins {parent} and {child} in its TF messages (frame pairs: "
                         f"{', '.join(f'{a} -> {b}' for a, b in sorted(pairs)) or 'none'})")
    return _ordered(rows)


def sample(stamps: np.ndarray, poses: np.ndarray, at: np.ndarray, max_gap: float) -> np.ndarray:
    """The trajectory at the stamps `at` (N x 4 x 4), NaN where it has none:
    a stamp within 1 us of a pose takes it; one between two poses at most
    max_gap s apart is interpolated (position linearly, rotation by slerp);
    anything else (outside the trajectory, or in a longer gap) has none."""
    out = np.full((len(at), 4, 4), np.nan)
    if len(stamps) == 0:
        return out
    stamps = np.asarray(stamps, float)
    rot = Rotation.from_matrix(poses[:, :3, :3])
    for k, t in enumerate(np.asarray(at, float)):
        j = int(np.searchsorted(stamps, t))
        for near in (j - 1, j):
            if 0 <= near < len(stamps) and abs(stamps[near] - t) <= 1e-6:
                out[k] = poses[near]
                break
        else:
            if 0 < j < len(stamps) and stamps[j] - stamps[j - 1] <= max_gap:
                a, b = stamps[j - 1], stamps[j]
                w = (t - a) / (b - a)
                out[k] = np.eye(4)
                out[k, :3, :3] = Slerp([a, b], rot[[j - 1, j]])([t]).as_matrix()[0]
                out[k, :3, 3] = (1 - w) * poses[j - 1, :3, 3] + w * poses[j, :3, 3]
    return out
