"""A ROS 1 bag as a dataset provider: frames in stamp order, none dropped.

The bag is indexed once (header stamps read from the first bytes of each
message), images are paired (stereo: the same stamp; RGB-D: the nearest depth
within max_diff, each used once, as TUM's associate.py), and frames are then
read serially: load(i) advances one pass through the bag, keeping only the
messages later frames need. The provider has the interface of the C++
DataProvider the runner uses (len, load, stamp, default_settings,
ground_truth, sensor, warnings), so `dynaorb bag run` goes through the same
runner and core as `dynaorb run`.

Settings: a settings YAML given, or BAG-stem.settings.yaml beside the bag, or
the TUM benchmark's camera for a bag named like TUM's own
(rgbd_dataset_freiburgN_*.bag; their camera_info is the driver's default), or,
for a bag recorded on a robot with none of these, the camera's own CameraInfo
topics (the image topic's sibling camera_info; dynaorb.ros.bag.camera_info).
Ground truth: a TUM file given, or BAG-stem.groundtruth.tum, or a stamped
pose topic in the bag (ground_truth_topic; dynaorb.ros.bag.poses).
"""
from __future__ import annotations

import bisect
import collections
import dataclasses
import pathlib
import tempfile

import numpy as np

from dynaorb import core
from dynaorb.ros.bag import camera_info as ci
from dynaorb.ros.bag import messages as m
from dynaorb.ros.bag.poses import read_pose_topic, read_tf
from dynaorb.ros.bag.write import sidecar

ROLES = ("image", "right", "depth", "labels")
_LAYOUTS = (m.TUM_TOPICS, m.STEREO_TOPICS, m.EUROC_TOPICS)
_SAME_STAMP = 1e-6  # s: "the same stamp" for stereo pairs and labels


@dataclasses.dataclass
class BagFrame:
    index: int
    stamp: float
    image: np.ndarray
    right: np.ndarray | None = None
    depth: np.ndarray | None = None   # in the System's units (DepthMapFactor): uint16 as stored, or float32
    labels: np.ndarray | None = None  # class ids, when the bag carries them
    image_path: str = ""              # "topic@stamp", for messages
    file_name: str = ""               # "<stamp>.png" (6 decimals): its masks' and labels' name in a folder


def _ns(stamp: float) -> int:
    return int(round(stamp * 1e9))


class BagProvider:
    kind = "bag"

    def __init__(self, path, *, settings=None, sensor: str | None = None,
                 topics: dict | None = None, max_diff: float = 0.02, ground_truth: str | None = None,
                 use_labels: bool = True, ground_truth_topic: str | None = None,
                 ground_truth_tf: tuple[str, str] | None = None):
        """path: a bag, or the parts of a split recording in order (read as one;
        sidecars are the first part's); settings: a Settings object or YAML path
        (default: BAG-stem.settings.yaml, else TUM's camera for a bag named
        rgbd_dataset_freiburgN_*, else the bag's camera_info); topics: role ->
        topic overrides (image, right, depth, labels); ground_truth: a TUM file (default: BAG-stem.groundtruth.tum
        when present); ground_truth_topic: a stamped pose topic of the bag instead;
        ground_truth_tf: (parent, child) frames of the bag's TF instead."""
        _core = core()
        self.paths = m.bag_paths(path)
        self.path = self.paths[0]  # sidecars are the first bag's
        self.warnings: list[str] = []
        with m.open_bags(self.paths) as reader:
            available = {c.topic: c.msgtype for c in reader.connections}
        if sum(bool(g) for g in (ground_truth, ground_truth_topic, ground_truth_tf)) > 1:
            raise ValueError("give the ground truth one way: a file, a pose topic or TF frames, not several")
        self._ground_truth_file = pathlib.Path(ground_truth) if ground_truth else sidecar(self.path, "groundtruth.tum")
        if ground_truth and not self._ground_truth_file.is_file():
            raise FileNotFoundError(f"{ground_truth}: ground truth file does not exist")
        # What the bag lacks to be a sequence is named before what is missing beside it.
        self.topics = self._choose_topics(available, topics or {}, sensor, use_labels)
        self.sensor = sensor or ("rgbd" if self.topics.get("depth") else "stereo" if self.topics.get("right")
                                 else "mono")
        self.sensor = _core.parse_sensor(self.sensor)
        need = {"mono": ("image",), "stereo": ("image", "right"), "rgbd": ("image", "depth")}[self.sensor]
        missing = [r for r in need if not self.topics.get(r)]
        if missing:
            raise ValueError(f"{self.path}: no {' / '.join(missing)} topic for a {self.sensor} run (topics in the "
                             f"bag: {', '.join(sorted(available)) or 'none'}; give them with --topic ROLE=TOPIC)")
        for role in ROLES:
            if role not in need and role != "labels":
                self.topics.pop(role, None)
        self._settings = self._load_settings(settings, available)
        self.settings_from_camera_info = self._settings is None
        self._ground_truth_topic = (read_pose_topic(self.paths, ground_truth_topic) if ground_truth_topic else
                                    read_tf(self.paths, *ground_truth_tf) if ground_truth_tf else None)
        self.max_diff = max_diff
        self._index()
        if self._settings is None:
            self._settings = self._settings_from_camera_info(available)
        self._reader = None
        self._messages = None
        self._next = 0

    # ------------------------------------------------------------- set-up
    def _load_settings(self, settings, available: dict):
        """The settings given or beside the bag; None when they are to come from
        the bag's camera_info (read once the topics are chosen)."""
        _core = core()
        if settings is None:
            default = sidecar(self.path, "settings.yaml")
            if not default.is_file():
                tum = _core.tum_settings_for_name(self.path.name) if self.sensor != "stereo" else None
                if tum is not None:
                    # TUM's own bags (rgbd_dataset_freiburgN_*.bag) carry the
                    # driver's default camera_info, not the benchmark's calibration.
                    self.warnings.append(f"settings: {tum.source}, the TUM benchmark's calibration (ORB-SLAM2's "
                                         f"TUM1/2/3.yaml), chosen by the bag's name; give --config to choose others")
                    tum.source = f"{tum.source} (named by {self.path.name})"
                    return tum
                if m.CAMERA_INFO in available.values():
                    return None
                raise ValueError(f"{self.path}: no settings (give --config, or keep {default.name} beside the bag; "
                                 f"the bag has no {m.CAMERA_INFO} topic to take the camera from)")
            settings = str(default)
        if isinstance(settings, (str, pathlib.Path)):
            return _core.Settings.load(str(settings))
        return settings

    def camera_info_topic(self, role: str) -> str:
        """The CameraInfo topic beside an image topic (image_transport's rule:
        the image topic's namespace + camera_info; a compressed transport's
        topic is under its image topic)."""
        return m.base_topic(self.topics[role]).rsplit("/", 1)[0] + "/camera_info"

    def _first_message(self, topic: str, msgtype: str):
        """The first message of the topic, an Image for a (compressed) image topic."""
        with m.open_bags(self.paths) as reader:
            conns = [c for c in reader.connections if c.topic == topic and c.msgtype == msgtype]
            for conn, _, raw in reader.messages(connections=conns):
                return m.as_image(raw, msgtype) if msgtype in m.IMAGE_TYPES else m.deserialize(raw, msgtype)
        return None

    def _settings_from_camera_info(self, available: dict):
        _core = core()
        infos = {}
        for role in ("image", "right") if self.sensor == "stereo" else ("image",):
            topic = self.camera_info_topic(role)
            if available.get(topic) != m.CAMERA_INFO:
                raise ValueError(f"{self.path}: no settings (give --config, or keep "
                                 f"{sidecar(self.path, 'settings.yaml').name} beside the bag), and no "
                                 f"{m.CAMERA_INFO} on {topic} beside {self.topics[role]} to take the camera from")
            infos[role] = self._first_message(topic, m.CAMERA_INFO)
        depth = self._first_message(self.topics["depth"], self._msgtypes["depth"]) if self.sensor == "rgbd" else None
        stamps = np.array([s for s, _ in self._frames])
        gaps = np.diff(stamps)
        fps = 1.0 / float(np.median(gaps)) if len(gaps) and np.median(gaps) > 0 else 30.0
        try:
            text = ci.settings_yaml(self.sensor, infos["image"], infos.get("right"), fps=round(fps, 3),
                                    depth_encoding=depth.encoding if depth is not None else None)
        except ValueError as exc:
            raise ValueError(f"{self.path}: {exc}") from None
        self.settings_yaml = text
        with tempfile.TemporaryDirectory() as tmp:
            path = pathlib.Path(tmp) / f"{self.path.stem}.camera_info.yaml"
            path.write_text(text)
            settings = _core.Settings.load(str(path))
        topics = ", ".join(self.camera_info_topic(r) for r in infos)
        settings.source = f"{self.path} camera_info ({topics})"
        settings.validate(self.sensor)
        self.warnings.append(f"settings from the bag's camera_info ({topics}) and ORB-SLAM2's extractor values; "
                             f"give --config to choose them")
        return settings

    def _choose_topics(self, available: dict, overrides: dict, sensor: str | None, use_labels: bool) -> dict:
        unknown = set(overrides) - set(ROLES)
        if unknown:
            raise ValueError(f"unknown topic roles {sorted(unknown)} (roles: {', '.join(ROLES)})")
        chosen = {}

        def present(topic: str | None) -> str | None:
            """The topic, or its compressed transport's (image_transport's names), if in the bag."""
            if topic is None:
                return None
            for candidate in (topic,) + tuple(topic + suffix for suffix in m.COMPRESSED_SUFFIXES):
                if available.get(candidate) in m.IMAGE_TYPES:
                    return candidate
            return None

        # The first known layout whose main image topic is in the bag (raw or compressed).
        for layout in _LAYOUTS:
            if present(layout.image):
                for role in ROLES:
                    topic = present(getattr(layout, role))
                    if topic:
                        chosen[role] = topic
                break
        chosen.update({r: t for r, t in overrides.items() if t})
        for role, topic in chosen.items():
            if topic not in available:
                raise ValueError(f"{self.path}: topic {topic} ({role}) is not in the bag "
                                 f"(topics: {', '.join(sorted(available))})")
            if available[topic] not in m.IMAGE_TYPES:
                raise ValueError(f"{self.path}: topic {topic} carries {available[topic]}, not "
                                 f"{' or '.join(m.IMAGE_TYPES)}")
        self._msgtypes = {role: available[topic] for role, topic in chosen.items()}
        if not use_labels:
            chosen.pop("labels", None)
        if "image" not in chosen:
            raise ValueError(f"{self.path}: no image topic found (topics: {', '.join(sorted(available))}; "
                             f"give one with --topic image=TOPIC)")
        return chosen

    def _stamp(self, raw: bytes, bag_time_ns: int) -> float:
        """A message's stamp: its header's, or the bag's record time when the
        images' headers carry none (_index)."""
        return bag_time_ns * 1e-9 if self._bag_time else m.header_stamp(raw)

    def _index(self) -> None:
        stamps = collections.defaultdict(list)
        times = collections.defaultdict(list)
        topic_of = {t: r for r, t in self.topics.items()}
        with m.open_bags(self.paths) as reader:
            conns = [c for c in reader.connections if c.topic in topic_of]
            for conn, t, raw in reader.messages(connections=conns):
                stamps[topic_of[conn.topic]].append(m.header_stamp(raw))
                times[topic_of[conn.topic]].append(t * 1e-9)
        # Some drivers leave the header stamp at zero: the bag's record times
        # stand in for every stream then, and pairs are matched within max_diff.
        self._bag_time = bool(stamps["image"]) and not any(stamps["image"])
        same = _SAME_STAMP
        if self._bag_time:
            stamps, same = times, self.max_diff
            self.warnings.append(f"the images on {self.topics['image']} carry no header stamps: the bag's record "
                                 f"times are used instead (pairs matched within {self.max_diff} s)")
        main = sorted(set(stamps["image"]))
        if len(main) < len(stamps["image"]):
            self.warnings.append(f"{len(stamps['image']) - len(main)} image messages with a repeated stamp ignored")
        partners = {}
        if self.sensor == "stereo":
            partners["right"] = self._pair(main, stamps["right"], same)
        elif self.sensor == "rgbd":
            partners["depth"] = self._pair(main, stamps["depth"], self.max_diff)
        labels = self._pair(main, stamps["labels"], same) if "labels" in self.topics else {}
        frames = []
        for s in main:
            parts = {"image": s}
            if any(s not in p for p in partners.values()):
                continue
            for role, p in partners.items():
                parts[role] = p[s]
            if s in labels:
                parts["labels"] = labels[s]
            frames.append((s, parts))
        dropped = len(main) - len(frames)
        if dropped:
            exact = self.sensor == "stereo" and not self._bag_time
            self.warnings.append(f"{dropped} images without a {'right image' if self.sensor == 'stereo' else 'depth'}"
                                 f" {'of the same stamp' if exact else f'within {self.max_diff} s'} skipped")
        if "labels" in self.topics and len(labels) < len(frames):
            self.warnings.append(f"{len(frames) - len(labels)} frames without labels of their stamp")
        self._frames = frames
        # (role, stamp ns) -> frame index, for the messages the frames need.
        self._wanted = {}
        for i, (_, parts) in enumerate(frames):
            for role, s in parts.items():
                self._wanted.setdefault((role, _ns(s)), i)

    @staticmethod
    def _pair(main: list, other: list, max_diff: float) -> dict:
        """main stamp -> other stamp, nearest within max_diff, each used once (greedy by difference)."""
        other = sorted(set(other))
        candidates = []
        for s in main:
            k = bisect.bisect_left(other, s)
            for j in (k - 1, k):
                if 0 <= j < len(other) and abs(other[j] - s) <= max_diff:
                    candidates.append((abs(other[j] - s), s, other[j]))
        candidates.sort()
        out, used = {}, set()
        for _, s, o in candidates:
            if s not in out and o not in used:
                out[s] = o
                used.add(o)
        return out

    # ------------------------------------------------------------- provider interface
    def __len__(self) -> int:
        return len(self._frames)

    @property
    def root(self) -> str:
        return str(self.path)

    def stamp(self, i: int) -> float:
        return self._frames[i][0]

    def part_stamps(self, i: int) -> dict:
        """Frame i's messages' stamps by role (a depth image's may differ from its colour image's)."""
        return dict(self._frames[i][1])

    def default_settings(self):
        return self._settings

    def ground_truth(self):
        if self._ground_truth_topic is not None:
            return self._ground_truth_topic
        if not self._ground_truth_file.is_file():
            return np.zeros(0), np.zeros((0, 4, 4))
        return core().read_tum(str(self._ground_truth_file))

    def load(self, i: int) -> BagFrame:
        """Frame i. Serial: loading frames in order reads the bag once; going
        back starts the pass again. InputError for a message it cannot read."""
        stamp, msgs = self.load_messages(i)
        return self._convert(i, stamp, msgs)

    def load_messages(self, i: int) -> tuple[float, dict]:
        """Frame i's stamp and its messages as the bag holds them (role ->
        sensor_msgs/Image), serially as load(); for writing them elsewhere."""
        _core = core()
        if i < 0 or i >= len(self._frames):
            raise IndexError(i)
        if self._messages is None or i < self._next:
            self._restart()
        stamp, parts = self._frames[i]
        keys = {role: (role, _ns(s)) for role, s in parts.items()}
        while any(k not in self._buffer for k in keys.values()):
            try:
                conn, t, raw = next(self._messages)
            except StopIteration:
                raise _core.InputError(f"{self.path}: the bag ended before frame {i}'s messages") from None
            key = (self._role_of[conn.topic], _ns(self._stamp(raw, t)))
            if self._wanted.get(key, -1) >= i:
                self._buffer[key] = raw
        self._next = i + 1
        try:
            msgs = {role: m.as_image(self._buffer.pop(k), self._msgtypes[role]) for role, k in keys.items()}
        except ValueError as exc:  # a compressed image that does not decode
            raise _core.InputError(f"{self.topics['image']}@{stamp:.6f}: {exc}") from None
        if len(self._buffer) > 64:  # messages of frames already passed are never needed again
            self._buffer = {k: v for k, v in self._buffer.items() if self._wanted.get(k, -1) > i}
        return stamp, msgs

    def _restart(self) -> None:
        self.close()
        self._reader = m.open_bags(self.paths)
        self._reader.open()
        self._role_of = {t: r for r, t in self.topics.items()}
        conns = [c for c in self._reader.connections if c.topic in self._role_of]
        self._messages = self._reader.messages(connections=conns)
        self._buffer = {}
        self._next = 0

    def _convert(self, i: int, stamp: float, msgs: dict) -> BagFrame:
        _core = core()
        s = self._settings
        where = f"{self.topics['image']}@{stamp:.6f}"
        try:
            frame = BagFrame(index=i, stamp=stamp, image=m.image_for_tracking(msgs["image"], s.rgb), image_path=where,
                              file_name=f"{stamp:.6f}.png")
            if "right" in msgs:
                frame.right = m.image_for_tracking(msgs["right"], s.rgb)
            if "depth" in msgs:
                depth = msgs["depth"]
                if depth.encoding in ("16UC1", "mono16"):
                    frame.depth = m.image_array(depth)  # as stored: the System divides by DepthMapFactor
                else:
                    # Metres: the System divides depth by DepthMapFactor whatever its type (the node's rule).
                    factor = np.float32(s.depth_map_factor or 1.0)
                    frame.depth = m.depth_in_metres(depth, float(factor)) * factor
            if "labels" in msgs:
                frame.labels = m.image_array(msgs["labels"])
        except ValueError as exc:
            raise _core.InputError(f"{where}: {exc}") from None
        return frame

    def close(self) -> None:
        if self._reader is not None:
            self._reader.close()
        self._reader = None
        self._messages = None

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown
            pass
