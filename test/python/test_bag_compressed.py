"""Bags with image_transport's compressed images (CompressedImage on .../compressed,
compressedDepth on .../compressedDepth), as robots record them (and `bag from-dataset
--image-transport compressed` writes them): read by `bag run` and `bag to-dataset` as the
raw images they were made from."""
from __future__ import annotations

import pathlib
import shutil
import struct

import cv2
import numpy as np
import pytest
from rosbags.rosbag1 import Writer

from dynaorb.ros.bag import (BagProvider, BagRunOptions, BagToDatasetOptions, BagWriteOptions, bag_to_dataset,
                             run_bag, write_dataset_bag)
from dynaorb.ros.bag import messages as m

_CompressedImage = m.TYPESTORE.types[m.COMPRESSED_IMAGE]
DEPTH_Z0, DEPTH_MAX = 100.0, 10.0  # compressed_depth_image_transport's defaults (depth_quantization, depth_max)


def compressed_depth(depth: np.ndarray, encoding: str) -> bytes:
    """compressed_depth_image_transport's encoding, written here from its codec
    (independent of messages.compress): 12-byte header + 16-bit PNG (32FC1:
    inverse depth quantised with A = Z0 (Z0 + 1), B = 1 - A / depth_max)."""
    if encoding == "16UC1":
        return struct.pack("<iff", 0, 0.0, 0.0) + cv2.imencode(".png", depth)[1].tobytes()
    a = DEPTH_Z0 * (DEPTH_Z0 + 1.0)
    b = 1.0 - a / DEPTH_MAX
    q = np.zeros(depth.shape, np.uint16)
    valid = np.isfinite(depth) & (depth > 0) & (depth < DEPTH_MAX)
    q[valid] = (a / depth[valid] + b).astype(np.uint16)
    return struct.pack("<iff", 0, a, b) + cv2.imencode(".png", q)[1].tobytes()


@pytest.mark.parametrize("fixture,kind", [("synth_rgbd", "tum"), ("synth_stereo", "kitti")])
def test_lossless_compressed_bag_runs_as_the_raw_one(tmp_path, request, fixture, kind):
    seq = request.getfixturevalue(fixture)
    path = seq if kind == "tum" else seq / "sequences" / "00"
    raw, packed = tmp_path / "raw.bag", tmp_path / "packed.bag"
    labels = str(seq / "labels") if kind == "tum" else None
    for bag, transport in ((raw, "raw"), (packed, "compressed")):  # png: lossless
        write_dataset_bag(BagWriteOptions(kind=kind, path=str(path), out=str(bag), depth_encoding="16UC1",
                                          labels=labels, image_transport=transport))
    provider = BagProvider(packed)
    expected = {"image": "/camera/rgb/image_color/compressed", "depth": "/camera/depth/image/compressedDepth",
                "labels": "/camera/rgb/labels/compressed"} if kind == "tum" else \
        {"image": "/camera/left/image_rect/compressed", "right": "/camera/right/image_rect/compressed"}
    assert provider.topics == expected
    a, b = BagProvider(raw), provider
    for i in range(len(a)):
        fa, fb = a.load(i), b.load(i)
        for field in ("image", "right", "depth", "labels"):
            va, vb = getattr(fa, field), getattr(fb, field)
            assert (va is None) == (vb is None)
            if va is not None:
                np.testing.assert_array_equal(vb, va)
    runs = [run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / bag.stem), vocabulary="none", progress=False))
            for bag in (raw, packed)]
    assert runs[0]["tracked_frames"] == runs[1]["tracked_frames"] == runs[0]["frames"]
    ta, tb = (np.loadtxt(tmp_path / n / "trajectory.tum", ndmin=2) for n in ("raw", "packed"))
    np.testing.assert_allclose(tb, ta, atol=1e-9)
    # And back to a dataset from the compressed bag, with its camera_info for settings.
    bare = tmp_path / "bare" / "packed.bag"
    bare.parent.mkdir()
    shutil.copy(packed, bare)
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bare), out=str(tmp_path / "ds")))
    assert summary["frames"] == len(a) and summary["settings_from_camera_info"]


def test_compressed_depth_in_metres_decodes_within_its_quantisation():
    depth = np.linspace(0.3, 9.0, 64 * 48, dtype=np.float32).reshape(48, 64)
    depth[0, :5] = np.nan
    depth[1, :5] = 0.0
    depth[2, :5] = 12.0  # beyond depth_max: no depth
    msg = _CompressedImage(header=m.header(1.0, "cam"), format="32FC1; compressedDepth png",
                           data=np.frombuffer(compressed_depth(depth, "32FC1"), np.uint8))
    # messages.compress makes the same bytes.
    assert bytes(m.compress(m.image_msg(depth, "32FC1", 1.0, "cam")).data) == bytes(msg.data)
    image = m.decompress(msg)
    assert image.encoding == "32FC1" and (image.width, image.height) == (64, 48)
    out = m.image_array(image)
    assert np.isnan(out[:3, :5]).all()
    valid = np.isfinite(depth) & (depth > 0) & (depth < DEPTH_MAX)
    a = DEPTH_Z0 * (DEPTH_Z0 + 1.0)
    # One step of the quantised inverse depth, about d^2 / A (truncation, as the codec; 1 % for
    # the step's own curvature).
    np.testing.assert_array_less(np.abs(out[valid] - depth[valid]), 1.01 * depth[valid] ** 2 / a)


def test_jpeg_colour_and_bad_compressed_data(tmp_path):
    rgb = np.random.default_rng(0).integers(0, 255, (48, 64, 3), dtype=np.uint8)
    rgb = cv2.GaussianBlur(rgb, (9, 9), 3)  # a JPEG-friendly image
    msg = m.image_msg(rgb, "rgb8", 1.0, "cam")
    image = m.decompress(m.compress(msg, "jpeg"))
    assert image.encoding == "bgr8"
    assert np.abs(cv2.cvtColor(m.image_array(image), cv2.COLOR_BGR2RGB).astype(int) - rgb).mean() < 3
    with pytest.raises(ValueError, match="does not decode"):
        m.decompress(_CompressedImage(header=m.header(1.0, "cam"), format="jpeg", data=np.zeros(10, np.uint8)))
    with pytest.raises(ValueError, match="rvl"):
        m.decompress(_CompressedImage(header=m.header(1.0, "cam"), format="16UC1; compressedDepth rvl",
                                      data=np.zeros(40, np.uint8)))
    # A frame whose image does not decode is counted and skipped, the run goes on.
    bag = tmp_path / "bad.bag"
    with Writer(bag) as w:
        c = w.add_connection("/cam/image/compressed", m.COMPRESSED_IMAGE, typestore=m.TYPESTORE)
        for k in range(4):
            t = 10.0 + 0.1 * k
            good = cv2.imencode(".png", np.full((48, 64), 100 + k, np.uint8))[1]
            data = good if k != 1 else np.zeros(16, np.uint8)
            w.write(c, m.stamp_ns(t), m.serialize(_CompressedImage(header=m.header(t, "cam"), format="png",
                                                                   data=np.asarray(data, np.uint8).ravel())))
    config = pathlib.Path(__file__).resolve().parents[2] / "config" / "EuRoC_mono.yaml"
    stats = run_bag(BagRunOptions(bag=str(bag), config=str(config), topics={"image": "/cam/image/compressed"},
                                  out=str(tmp_path / "out"), vocabulary="none", progress=False))
    assert stats["frames"] == 4 and stats["frames_skipped"] == {"unreadable": 1}
