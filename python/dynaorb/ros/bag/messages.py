"""sensor_msgs/Image and CameraInfo as rosbags dataclasses, to and from numpy.

Topic names and encodings follow what users' bags carry: TUM's own bags
(/camera/rgb/image_color rgb8, /camera/depth/image 32FC1 metres with NaN
where there is no depth), the ZED / stereo_image_proc style left/right
rectified images for KITTI, and EuRoC's /cam0/image_raw, /cam1/image_raw.
"""
from __future__ import annotations

import dataclasses
import heapq
import pathlib
import struct

import cv2
import numpy as np
from rosbags.rosbag1 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TYPESTORE = get_typestore(Stores.ROS1_NOETIC)
# TF's messages, which the store lacks: tf2's and tf's (older bags, TUM's own).
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
for _name in TF_TYPES:
    TYPESTORE.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", _name))
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (IMAGE, COMPRESSED_IMAGE)
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
# image_transport's topic names for the compressed transports of an image topic.
COMPRESSED_SUFFIXES = ("/compressed", "/compressedDepth")

_Header = TYPESTORE.types["std_msgs/msg/Header"]
_Time = TYPESTORE.types["builtin_interfaces/msg/Time"]
_Image = TYPESTORE.types[IMAGE]
_CompressedImage = TYPESTORE.types[COMPRESSED_IMAGE]
_CameraInfo = TYPESTORE.types[CAMERA_INFO]
_Roi = TYPESTORE.types["sensor_msgs/msg/RegionOfInterest"]


@dataclasses.dataclass(frozen=True)
class Topics:
    """Where a sequence's streams go in a bag (None: not written / not read)."""
    image: str                      # mono image, left image, or colour image
    right: str | None = None        # stereo
    depth: str | None = None        # RGB-D
    labels: str | None = None       # class-id images (mono8), same stamps as `image`
    image_info: str | None = None   # camera_info beside image / right
    right_info: str | None = None
    depth_info: str | None = None
    frame_id: str = "camera_optical_frame"
    right_frame_id: str | None = None


# Defaults per dataset layout and sensor. The labels topic is where
# segmentation_server publishes beside the image (launch/segmentation_server.launch).
TUM_TOPICS = Topics(image="/camera/rgb/image_color", depth="/camera/depth/image", labels="/camera/rgb/labels",
                    image_info="/camera/rgb/camera_info", depth_info="/camera/depth/camera_info",
                    frame_id="camera_rgb_optical_frame")
STEREO_TOPICS = Topics(image="/camera/left/image_rect", right="/camera/right/image_rect",
                       labels="/camera/left/labels", image_info="/camera/left/camera_info",
                       right_info="/camera/right/camera_info", frame_id="camera_left_optical_frame",
                       right_frame_id="camera_right_optical_frame")
EUROC_TOPICS = Topics(image="/cam0/image_raw", right="/cam1/image_raw", labels="/cam0/labels",
                      frame_id="cam0", right_frame_id="cam1")


def bag_paths(bags) -> list[pathlib.Path]:
    """One bag or several (a recording split with `rosbag record --split`), as
    paths; FileNotFoundError naming one that does not exist."""
    paths = [pathlib.Path(b) for b in ([bags] if isinstance(bags, (str, pathlib.Path)) else bags)]
    if not paths:
        raise ValueError("no bag given")
    for p in paths:
        if not p.is_file():
            raise FileNotFoundError(f"{p}: bag does not exist")
    return paths


class Bags:
    """ROS 1 bags read as one (the parts of a split recording): their
    connections together, their messages merged in time order as raw bytes.
    Use `with`, or open() and close(). (rosbags' AnyReader would also check
    each type's definition against its digest and take only names ending in
    .bag; a bag the plain reader reads is read here.)"""

    def __init__(self, bags):
        self.paths = bag_paths(bags)
        self.readers = [Reader(p) for p in self.paths]
        self.connections = []

    def open(self) -> None:
        try:
            for r in self.readers:
                r.open()
        except Exception:
            self.close()
            raise
        self.connections = [c for r in self.readers for c in r.connections]

    def close(self) -> None:
        for r in self.readers:
            try:
                r.close()
            except Exception:  # one never opened
                pass

    def __enter__(self) -> "Bags":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def start_time(self) -> int:
        return min(r.start_time for r in self.readers)

    @property
    def end_time(self) -> int:
        return max(r.end_time for r in self.readers)

    def messages(self, connections=None):
        """(connection, bag time ns, raw bytes) of the connections given (default
        all), in time order across the bags."""
        wanted = None if connections is None else {id(c) for c in connections}
        streams = []
        for r in self.readers:
            conns = [c for c in r.connections if wanted is None or id(c) in wanted]
            if conns:
                streams.append(r.messages(connections=conns))
        return heapq.merge(*streams, key=lambda item: item[1])


def open_bags(bags) -> Bags:
    """The bags as one reader (call open() or use `with`)."""
    return Bags(bags)


def stamp_ns(stamp: float) -> int:
    return int(round(stamp * 1e9))


def header(stamp: float, frame_id: str, seq: int = 0):
    ns = stamp_ns(stamp)
    return _Header(seq=seq, stamp=_Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame_id)


def image_msg(array: np.ndarray, encoding: str, stamp: float, frame_id: str, seq: int = 0):
    """An Image message of a contiguous HxW or HxWxC array in `encoding`."""
    array = np.ascontiguousarray(array)
    channels = 1 if array.ndim == 2 else array.shape[2]
    step = array.shape[1] * channels * array.dtype.itemsize
    data = np.frombuffer(array.tobytes(), dtype=np.uint8)
    return _Image(header=header(stamp, frame_id, seq), height=array.shape[0], width=array.shape[1],
                  encoding=encoding, is_bigendian=0, step=step, data=data)


def camera_info_msg(stamp: float, frame_id: str, width: int, height: int, K: np.ndarray, D: np.ndarray,
                    P: np.ndarray, seq: int = 0):
    return _CameraInfo(header=header(stamp, frame_id, seq), height=height, width=width,
                       distortion_model="plumb_bob", D=np.asarray(D, dtype=float).ravel(),
                       K=np.asarray(K, dtype=float).ravel(), R=np.eye(3).ravel(),
                       P=np.asarray(P, dtype=float).ravel(), binning_x=0, binning_y=0,
                       roi=_Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))


def serialize(msg) -> bytes:
    return TYPESTORE.serialize_ros1(msg, msg.__msgtype__)


def deserialize(raw: bytes, msgtype: str):
    return TYPESTORE.deserialize_ros1(raw, msgtype)


def header_stamp(raw: bytes) -> float:
    """The header stamp of a serialised message that starts with a std_msgs/Header
    (seq, sec, nsec), read without deserialising the rest."""
    _, sec, nsec = struct.unpack_from("<III", raw, 0)
    return sec + nsec * 1e-9


_DTYPES = {"mono8": (np.uint8, 1), "8UC1": (np.uint8, 1), "rgb8": (np.uint8, 3), "bgr8": (np.uint8, 3),
           "rgba8": (np.uint8, 4), "bgra8": (np.uint8, 4), "mono16": (np.uint16, 1), "16UC1": (np.uint16, 1),
           "32FC1": (np.float32, 1)}


def image_array(msg) -> np.ndarray:
    """HxW / HxWxC array of an Image message (ValueError for an unknown encoding or a bad size)."""
    if msg.encoding not in _DTYPES:
        raise ValueError(f"image encoding {msg.encoding!r} is not one of {', '.join(_DTYPES)}")
    base, channels = _DTYPES[msg.encoding]
    base = np.dtype(base)  # native order: the core's bindings take only the canonical dtypes
    row = msg.width * channels * base.itemsize
    if msg.step < row or len(msg.data) < msg.step * msg.height:
        raise ValueError(f"{msg.width}x{msg.height} {msg.encoding} image with step {msg.step} "
                         f"and {len(msg.data)} bytes is truncated")
    rows = np.frombuffer(bytes(msg.data), dtype=np.uint8)[:msg.step * msg.height].reshape(msg.height, msg.step)
    packed = rows[:, :row].copy()
    if msg.is_bigendian and base.itemsize > 1:
        out = packed.view(base.newbyteorder(">")).astype(base)
    else:
        out = packed.view(base)
    return out.reshape((msg.height, msg.width) + ((channels,) if channels > 1 else ()))


def image_for_tracking(msg, rgb_order: bool) -> np.ndarray:
    """What the System takes (the node's rule): 8-bit grey stays grey, colour
    becomes RGB (rgb_order, Camera.RGB: 1) or BGR, 16-bit grey is scaled to 8 bits."""
    a = image_array(msg)
    e = msg.encoding
    if e in ("mono8", "8UC1"):
        return a
    if e in ("mono16", "16UC1"):
        return (a // 256).astype(np.uint8)
    if e == "32FC1":
        raise ValueError("a 32FC1 image is not an intensity image")
    code = {("rgb8", True): None, ("rgb8", False): cv2.COLOR_RGB2BGR,
            ("bgr8", True): cv2.COLOR_BGR2RGB, ("bgr8", False): None,
            ("rgba8", True): cv2.COLOR_RGBA2RGB, ("rgba8", False): cv2.COLOR_RGBA2BGR,
            ("bgra8", True): cv2.COLOR_BGRA2RGB, ("bgra8", False): cv2.COLOR_BGRA2BGR}[(e, rgb_order)]
    return a if code is None else cv2.cvtColor(a, code)


def depth_in_metres(msg, depth_map_factor: float) -> np.ndarray:
    """32FC1 is metres (REP-118); 16UC1 / mono16 is divided by DepthMapFactor."""
    a = image_array(msg)
    if msg.encoding == "32FC1":
        return a
    if msg.encoding in ("16UC1", "mono16"):
        return a.astype(np.float32) / np.float32(depth_map_factor)
    raise ValueError(f"depth encoding {msg.encoding!r} is neither 16UC1 nor 32FC1")


def base_topic(topic: str) -> str:
    """The image topic a compressed transport's topic belongs to (.../image/compressed -> .../image)."""
    for suffix in COMPRESSED_SUFFIXES:
        if topic.endswith(suffix):
            return topic[:-len(suffix)]
    return topic


def _compressed_depth(msg, encoding: str) -> tuple[np.ndarray, str]:
    """compressed_depth_image_transport's format: a 12-byte ConfigHeader (int32
    compression format, float32 depthQuantA, depthQuantB), then a 16-bit PNG:
    16UC1 as it was; 32FC1 as quantised inverse depth, depth = A / (q - B),
    q = 0 for no depth (NaN)."""
    if "rvl" in msg.format.lower():
        raise ValueError(f"compressedDepth format {msg.format!r}: only its png compression is read, not rvl")
    data = bytes(msg.data)
    if len(data) <= 12:
        raise ValueError(f"compressedDepth image of {len(data)} bytes has no image after its 12-byte header")
    q = cv2.imdecode(np.frombuffer(data[12:], np.uint8), cv2.IMREAD_UNCHANGED)
    if q is None or q.dtype != np.uint16 or q.ndim != 2:
        raise ValueError(f"compressedDepth image ({msg.format!r}) does not decode to a 16-bit PNG")
    if encoding in ("16UC1", "mono16"):
        return q, "16UC1"
    if encoding != "32FC1":
        raise ValueError(f"compressedDepth encoding {encoding!r} is neither 16UC1 nor 32FC1")
    _, a, b = struct.unpack_from("<iff", data, 0)
    depth = np.full(q.shape, np.nan, np.float32)
    valid = q > 0
    depth[valid] = np.float32(a) / (q[valid].astype(np.float32) - np.float32(b))
    return depth, "32FC1"


def decompress(msg):
    """A sensor_msgs/CompressedImage as the Image message it was made from
    (image_transport's compressed transport: jpeg / png, colour as bgr8 or
    bgra8, grey as mono8 / mono16; compressedDepth: png, 16UC1 or 32FC1 metres).
    ValueError naming the format when the data does not decode."""
    fmt = msg.format or ""
    encoding = fmt.split(";", 1)[0].strip() if ";" in fmt else ""
    if "compresseddepth" in fmt.lower():
        array, out_encoding = _compressed_depth(msg, encoding)
    else:
        array = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
        if array is None:
            raise ValueError(f"compressed image ({fmt!r}, {len(msg.data)} bytes) does not decode")
        channels = 1 if array.ndim == 2 else array.shape[2]
        out_encoding = {(np.dtype(np.uint8), 1): "mono8", (np.dtype(np.uint16), 1): "mono16",
                        (np.dtype(np.uint8), 3): "bgr8", (np.dtype(np.uint8), 4): "bgra8"}.get((array.dtype, channels))
        if out_encoding is None:
            raise ValueError(f"compressed image ({fmt!r}) decodes to {channels} channels of {array.dtype}")
    image = image_msg(array, out_encoding, 0.0, msg.header.frame_id)
    return _Image(header=msg.header, height=image.height, width=image.width, encoding=image.encoding,
                  is_bigendian=0, step=image.step, data=image.data)


_TO_BGR = {"rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR, "bgra8": cv2.COLOR_BGRA2BGR}
_GREY = ("mono8", "8UC1", "mono16", "16UC1")


def image_for_file(msg) -> np.ndarray:
    """An Image message as cv2.imwrite / imencode take it: colour in BGR order,
    grey as it is. ValueError for an encoding that is not an image's (32FC1)."""
    a = image_array(msg)
    if msg.encoding in _GREY or msg.encoding == "bgr8":
        return a
    if msg.encoding in _TO_BGR:
        return cv2.cvtColor(a, _TO_BGR[msg.encoding])
    raise ValueError(f"image encoding {msg.encoding!r} is not an intensity image")


def compress(msg, image_format: str = "png", depth_quantization: float = 100.0, depth_max: float = 10.0):
    """The CompressedImage image_transport makes of an Image: its compressed
    transport (jpeg or png; colour as bgr8) for intensity images, its
    compressedDepth transport (png) for 16UC1 and 32FC1 depth, 32FC1 as the
    quantised inverse depth q = A / depth + B with A = depth_quantization
    (depth_quantization + 1), B = 1 - A / depth_max (0: no depth, or beyond
    depth_max) as compressed_depth_image_transport's defaults."""
    if image_format not in ("png", "jpeg"):
        raise ValueError(f"image format must be png or jpeg, not {image_format!r}")
    if msg.encoding in ("16UC1", "32FC1"):
        a = image_array(msg)
        if msg.encoding == "16UC1":
            head, q = struct.pack("<iff", 0, 0.0, 0.0), a
        else:
            qa = depth_quantization * (depth_quantization + 1.0)
            qb = 1.0 - qa / depth_max
            q = np.zeros(a.shape, np.uint16)
            valid = np.isfinite(a) & (a > 0) & (a < depth_max)
            q[valid] = (qa / a[valid] + qb).astype(np.uint16)
            head = struct.pack("<iff", 0, qa, qb)
        fmt, data = f"{msg.encoding}; compressedDepth png", head + cv2.imencode(".png", q)[1].tobytes()
    else:
        image = image_for_file(msg)
        packed = "bgr8" if image.ndim == 3 else msg.encoding
        ok, buf = cv2.imencode(".jpg" if image_format == "jpeg" else ".png", image)
        if not ok:
            raise ValueError(f"a {msg.encoding} image cannot be compressed as {image_format}")
        fmt, data = f"{msg.encoding}; {image_format} compressed {packed}", buf.tobytes()
    return _CompressedImage(header=msg.header, format=fmt, data=np.frombuffer(data, np.uint8))


def as_image(raw: bytes, msgtype: str):
    """An Image message from a serialised Image or CompressedImage."""
    msg = deserialize(raw, msgtype)
    return decompress(msg) if msgtype == COMPRESSED_IMAGE else msg
