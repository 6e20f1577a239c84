"""dynaorb bag: datasets written as ROS 1 bags (read back with rosbags), and bags run through the core."""
from __future__ import annotations

import json
import pathlib
import shutil

import cv2
import numpy as np
import pytest
from rosbags.rosbag1 import Reader, Writer

from dynaorb import core
from dynaorb.cli.main import main
from dynaorb.ros.bag import BagProvider, BagRunOptions, BagWriteOptions, run_bag, write_dataset_bag
from dynaorb.ros.bag import messages as m
from dynaorb.ros.bag.write import sidecar
from dynaorb.runner import RunOptions, run_dataset


def read_bag(path) -> dict:
    """topic -> list of (bag time ns, message)."""
    out = {}
    with Reader(path) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, m.deserialize(raw, conn.msgtype)))
    return out


def tum_rows(path) -> np.ndarray:
    return np.loadtxt(path, comments="#", ndmin=2)


# ------------------------------------------------------------------ from-dataset
def test_tum_bag_has_tums_topics_and_encodings(tmp_path, data):
    seq = data / "tum" / "rgbd_dataset_freiburg3_walking_xyz_fragment"
    bag = tmp_path / "tum.bag"
    summary = write_dataset_bag(BagWriteOptions(kind="tum", path=str(seq), out=str(bag)))
    assert summary["frames"] == 2 and summary["sensor"] == "rgbd"
    msgs = read_bag(bag)
    assert set(msgs) == {"/camera/rgb/image_color", "/camera/depth/image", "/camera/rgb/camera_info",
                         "/camera/depth/camera_info"}
    provider = core().open_dataset("tum", str(seq))
    settings = provider.default_settings()
    for k, (t, rgb) in enumerate(msgs["/camera/rgb/image_color"]):
        frame = provider.load(k)
        assert rgb.encoding == "rgb8" and rgb.header.frame_id == "camera_rgb_optical_frame"
        stamp = rgb.header.stamp.sec + rgb.header.stamp.nanosec * 1e-9
        assert stamp == pytest.approx(frame.stamp, abs=1e-6)  # TUM stamps kept (offset 0)
        assert t == m.stamp_ns(stamp)  # bag time = header stamp
        np.testing.assert_array_equal(m.image_array(rgb), cv2.cvtColor(frame.image, cv2.COLOR_BGR2RGB))
        _, depth = msgs["/camera/depth/image"][k]
        assert depth.encoding == "32FC1"
        metres = m.image_array(depth)
        raw = frame.depth.astype(np.float32)
        np.testing.assert_allclose(metres[raw > 0], raw[raw > 0] / settings.depth_map_factor, rtol=1e-6)
        assert np.all(np.isnan(metres[raw == 0]))  # no depth: NaN, as in TUM's bags
    _, info = msgs["/camera/rgb/camera_info"][0]
    assert info.K[0] == pytest.approx(settings.fx) and info.K[5] == pytest.approx(settings.cy)
    assert (tmp_path / "tum.settings.yaml").is_file()
    gt = tum_rows(tmp_path / "tum.groundtruth.tum")
    assert len(gt) == len(provider.ground_truth()[0])


def test_tum_depth_as_16uc1_keeps_the_png_units(tmp_path, data):
    seq = data / "tum" / "rgbd_dataset_freiburg3_walking_xyz_fragment"
    bag = tmp_path / "tum16.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(seq), out=str(bag), depth_encoding="16UC1"))
    _, depth = read_bag(bag)["/camera/depth/image"][0]
    assert depth.encoding == "16UC1"
    np.testing.assert_array_equal(m.image_array(depth), core().open_dataset("tum", str(seq)).load(0).depth)
    # Read back for the core, both encodings give the same depth in the System's units.
    d32 = tmp_path / "tum32.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(seq), out=str(d32)))
    a, b = BagProvider(bag).load(0).depth, BagProvider(d32).load(0).depth
    assert a.dtype == np.uint16 and b.dtype == np.float32
    valid = a > 0
    np.testing.assert_allclose(a[valid].astype(np.float32), b[valid], rtol=1e-6)
    assert np.all(np.isnan(b[~valid]))


def test_kitti_bag_stereo_topics_stamps_and_baseline(tmp_path, data):
    seq = data / "kitti" / "sequences" / "06"
    bag = tmp_path / "kitti.bag"
    summary = write_dataset_bag(BagWriteOptions(kind="kitti", path=str(seq), out=str(bag), max_frames=5))
    # KITTI's stamps start at 0, "no time" in ROS: shifted by 1 s, ground truth too.
    assert summary["stamp_offset"] == 1.0 and summary["frames"] == 5
    msgs = read_bag(bag)
    left, right = msgs["/camera/left/image_rect"], msgs["/camera/right/image_rect"]
    assert len(left) == len(right) == 5
    times = np.loadtxt(seq / "times.txt")
    for k in range(5):
        l, r = left[k][1], right[k][1]
        assert l.encoding == r.encoding == "mono8"
        assert l.header.stamp == r.header.stamp
        assert l.header.stamp.sec + l.header.stamp.nanosec * 1e-9 == pytest.approx(times[k] + 1.0, abs=1e-6)
        assert l.header.frame_id == "camera_left_optical_frame"
    settings = core().open_dataset("kitti", str(seq)).default_settings()
    _, rinfo = msgs["/camera/right/camera_info"][0]
    assert -rinfo.P[3] == pytest.approx(settings.bf)  # P[3] = -fx * baseline
    gt = tum_rows(tmp_path / "kitti.groundtruth.tum")
    assert gt[0, 0] == pytest.approx(times[0] + 1.0)


def test_euroc_bag_has_raw_images_for_the_yaml_rectification(tmp_path, data):
    seq = data / "euroc" / "V1_01_easy_micro"
    bag = tmp_path / "euroc.bag"
    summary = write_dataset_bag(BagWriteOptions(kind="euroc", path=str(seq), out=str(bag), max_frames=4))
    assert summary["sensor"] == "stereo" and summary["stamp_offset"] == 0.0
    msgs = read_bag(bag)
    assert set(msgs) == {"/cam0/image_raw", "/cam1/image_raw"}  # EuRoC's own names; no camera_info
    settings = core().Settings.load(str(tmp_path / "euroc.settings.yaml"))
    assert settings.rectified_stereo
    provider = BagProvider(bag)
    assert provider.sensor == "stereo" and len(provider) == 4
    # The cam0 ground truth (through T_BS) beside the bag.
    assert len(tum_rows(tmp_path / "euroc.groundtruth.tum")) > 0


def test_labels_go_on_the_labels_topic_with_the_image_stamps(tmp_path, synth_rgbd):
    bag = tmp_path / "synth.bag"
    summary = write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag),
                                                labels=str(synth_rgbd / "labels")))
    assert summary["labels"] == 8 and summary["labels_missing"] == 0
    msgs = read_bag(bag)
    images, labels = msgs["/camera/rgb/image_color"], msgs["/camera/rgb/labels"]
    for (_, image), (_, lab) in zip(images, labels):
        assert lab.header.stamp == image.header.stamp and lab.encoding == "mono8"
    names = sorted((synth_rgbd / "labels").iterdir())
    np.testing.assert_array_equal(m.image_array(labels[3][1]), cv2.imread(str(names[3]), cv2.IMREAD_UNCHANGED))
    provider = BagProvider(bag)
    assert provider.topics["labels"] == "/camera/rgb/labels"
    frame = provider.load(3)
    np.testing.assert_array_equal(frame.labels, cv2.imread(str(names[3]), cv2.IMREAD_UNCHANGED))


# ------------------------------------------------------------------ bag run
def trajectory(out: pathlib.Path) -> np.ndarray:
    return tum_rows(out / "trajectory.tum")


@pytest.mark.parametrize("fixture,kind", [("synth_stereo", "kitti"), ("synth_rgbd", "tum")])
def test_bag_run_equals_the_dataset_run(tmp_path, request, fixture, kind):
    """Same frames, same core, synchronous mapping: the same trajectory as `dynaorb run`."""
    seq = request.getfixturevalue(fixture)
    path = seq if kind == "tum" else seq / "sequences" / "00"
    bag = tmp_path / "seq.bag"
    # 16UC1 depth reaches the System as the PNGs hold it (32FC1 metres differ by float rounding).
    write_dataset_bag(BagWriteOptions(kind=kind, path=str(path), out=str(bag), depth_encoding="16UC1"))
    ds = run_dataset(RunOptions(kind=kind, path=str(path), out=str(tmp_path / "ds"), vocabulary="none",
                                progress=False))
    bg = run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / "bag"), vocabulary="none", progress=False))
    assert bg["tracked_frames"] == ds["tracked_frames"] > 0
    a, b = trajectory(tmp_path / "ds"), trajectory(tmp_path / "bag")
    assert a.shape == b.shape
    offset = 1.0 if kind == "kitti" else 0.0  # KITTI-layout stamps start at 0
    np.testing.assert_allclose(b[:, 0], a[:, 0] + offset, atol=1e-6)
    np.testing.assert_allclose(b[:, 1:], a[:, 1:], atol=1e-9)
    assert (tmp_path / "bag" / "map_points.ply").is_file()
    if ds.get("ate"):
        assert bg["ate"]["rmse"] == pytest.approx(ds["ate"]["rmse"], abs=1e-9)


def test_bag_run_on_kitti_06_within_slam_core_bound(tmp_path, data):
    bag = tmp_path / "kitti06.bag"
    write_dataset_bag(BagWriteOptions(kind="kitti", path=str(data / "kitti" / "sequences" / "06"), out=str(bag)))
    stats = run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / "run"), progress=False))
    assert stats["frames"] == 51 and stats["tracked_frames"] == 51
    assert stats["ate"]["rmse"] <= 0.15  # SLAM core I's bound on KITTI 06
    assert stats["bag"]["topics"] == {"image": "/camera/left/image_rect", "right": "/camera/right/image_rect"}
    on_disk = json.loads((tmp_path / "run" / "stats.json").read_text())
    assert on_disk["bag"]["frames"] == 51


def test_bag_run_masks_the_movable_labels(tmp_path, synth_rgbd):
    bag = tmp_path / "synth.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag), depth_encoding="16UC1",
                                      labels=str(synth_rgbd / "labels")))
    with_labels = run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / "a"), vocabulary="none", progress=False))
    assert with_labels["frames_with_labels"] == 8
    without = run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / "b"), vocabulary="none", progress=False,
                                    use_labels=False))
    assert without["frames_with_labels"] == 0
    # The same as a dataset run whose masks are the label images' movable classes.
    ds = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "c"), vocabulary="none",
                                masks=str(synth_rgbd / "labels"), progress=False))
    np.testing.assert_allclose(trajectory(tmp_path / "a")[:, 1:], trajectory(tmp_path / "c")[:, 1:], atol=1e-9)


def test_bag_run_reads_mask_folders_by_stamp(tmp_path, synth_rgbd):
    """A bag's frames are named <stamp>.png in per-frame folders, as TUM names its images: the sequence's
    ground-truth masks serve its bag, and the two runs agree."""
    bag = tmp_path / "synth.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag), depth_encoding="16UC1"))
    masks = str(synth_rgbd / "dynamic_masks")
    ds = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "ds"), vocabulary="none",
                                masks=masks, progress=False))
    bg = run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / "bag"), vocabulary="none", progress=False,
                               runner={"masks": masks}))
    assert bg["masks"] == ds["masks"] == {"used": 8}
    np.testing.assert_allclose(trajectory(tmp_path / "bag")[:, 1:], trajectory(tmp_path / "ds")[:, 1:], atol=1e-9)
    with pytest.raises(ValueError, match="'sensor' is the bag's own"):
        run_bag(BagRunOptions(bag=str(bag), runner={"sensor": "mono"}))
    with pytest.raises(ValueError, match="'nope' is not a runner option"):
        run_bag(BagRunOptions(bag=str(bag), runner={"nope": 1}))


def test_cli_bag_run_takes_the_run_commands_options(tmp_path, synth_rgbd):
    """`bag run` hands the runner what `dynaorb run` does: core options, pacing, priorities, saved masks."""
    bag = tmp_path / "synth.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag), depth_encoding="16UC1"))
    saved = tmp_path / "masks"
    assert main(["bag", "run", str(bag), "--out", str(tmp_path / "out"), "--vocabulary", "none", "--quiet",
                 "--dynamic", "dm", "--save-masks", str(saved), "--tracker", "max_frames=5", "--mapping",
                 "neighbors_stereo=12", "--realtime", "4", "--async-mapping", "--background-nice", "0"]) == 0
    stats = json.loads((tmp_path / "out" / "stats.json").read_text())
    assert stats["tracked_frames"] == stats["frames"] == 8
    assert stats["tracker_options"] == {"max_frames": 5.0}
    assert stats["mapping_options"] == {"neighbors_stereo": 12.0}
    assert stats["realtime"]["rate"] == 4.0 and stats["background_nice"] == 0 and not stats["synchronous_mapping"]
    names = sorted(p.name for p in saved.iterdir())
    assert len(names) == stats["dynamic_filter"]["masks_saved"] == 8
    assert names == sorted(p.name for p in (synth_rgbd / "rgb").iterdir())  # <stamp>.png, as TUM's images


# ------------------------------------------------------------------ bad input
def write_images(path: pathlib.Path, encodings: list[str]) -> None:
    with Writer(path) as w:
        conn = w.add_connection("/camera/image_raw", m.IMAGE, typestore=m.TYPESTORE)
        for k, enc in enumerate(encodings):
            img = np.full((48, 64), 100 + k, np.uint8)
            msg = m.image_msg(img, "mono8", 10.0 + k * 0.1, "cam", k)
            if enc != "mono8":
                msg = type(msg)(header=msg.header, height=msg.height, width=msg.width, encoding=enc,
                                is_bigendian=0, step=msg.step, data=msg.data)
            w.write(conn, m.stamp_ns(10.0 + k * 0.1), m.serialize(msg))


def test_unreadable_frames_are_counted_not_fatal(tmp_path):
    bag = tmp_path / "bad.bag"
    write_images(bag, ["mono8", "yuv422", "mono8", "mono8"])
    config = pathlib.Path(__file__).resolve().parents[2] / "config" / "EuRoC_mono.yaml"
    stats = run_bag(BagRunOptions(bag=str(bag), config=str(config), topics={"image": "/camera/image_raw"},
                                  out=str(tmp_path / "out"), vocabulary="none", progress=False))
    assert stats["frames"] == 4
    assert stats["frames_skipped"] == {"unreadable": 1}


def test_clear_errors(tmp_path, capsys):
    bag = tmp_path / "bad.bag"
    write_images(bag, ["mono8"])
    with pytest.raises(ValueError, match="no image topic"):  # what the bag lacks first, then what is beside it
        BagProvider(bag)
    with pytest.raises(ValueError, match="no settings"):
        BagProvider(bag, topics={"image": "/camera/image_raw"})
    config = pathlib.Path(__file__).resolve().parents[2] / "config" / "TUM3.yaml"
    with pytest.raises(ValueError, match="no image topic"):
        BagProvider(bag, settings=str(config))
    with pytest.raises(ValueError, match="no depth"):
        BagProvider(bag, settings=str(config), sensor="rgbd", topics={"image": "/camera/image_raw"})
    with pytest.raises(ValueError, match="not in the bag"):
        BagProvider(bag, settings=str(config), topics={"image": "/nope"})
    with pytest.raises(ValueError, match="unknown topic roles"):
        BagProvider(bag, settings=str(config), topics={"colour": "/camera/image_raw"})
    with pytest.raises(FileNotFoundError):
        BagProvider(tmp_path / "missing.bag")
    assert main(["bag", "run", str(bag), "--config", str(config), "--topic", "image"]) == 2
    assert "ROLE=TOPIC" in capsys.readouterr().err
    with pytest.raises(ValueError, match="depth encoding"):
        write_dataset_bag(BagWriteOptions(kind="tum", path=str(tmp_path), out=str(tmp_path / "x.bag"),
                                          depth_encoding="8UC1"))


def test_cli_from_dataset_and_run(tmp_path, synth_rgbd, capsys):
    bag = tmp_path / "cli.bag"
    assert main(["bag", "from-dataset", "tum", str(synth_rgbd), "-o", str(bag), "--labels",
                 str(synth_rgbd / "labels"), "--quiet"]) == 0
    assert "8 frames (rgbd)" in capsys.readouterr().out
    assert main(["bag", "run", str(bag), "--out", str(tmp_path / "out"), "--vocabulary", "none", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "frames tracked" in out
    assert json.loads((tmp_path / "out" / "stats.json").read_text())["frames_with_labels"] == 8


def test_bag_run_segments_in_process(tmp_path, synth_rgbd, data):
    """`bag run --segment`: the network's labels instead of the bag's labels topic."""
    model = data.parent / "models" / "segmentation" / "deeplabv3_mnv2_dm05_pascal_quant.onnx"
    if not model.is_file():
        pytest.skip(f"{model} not found")
    bag = tmp_path / "synth.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag), depth_encoding="16UC1",
                                      labels=str(synth_rgbd / "labels")))
    assert main(["bag", "run", str(bag), "--out", str(tmp_path / "out"), "--vocabulary", "none", "--quiet",
                 "--dynamic", "full", "--segment", str(model), "--segment-mode", "sync"]) == 0
    stats = json.loads((tmp_path / "out" / "stats.json").read_text())
    assert stats["tracked_frames"] == stats["frames"] == 8
    assert stats["frames_with_labels"] == 0  # the bag's labels topic is not read
    assert stats["segmentation"]["frames"] == {"fresh": 8}
    assert "labels" not in stats["bag"]["topics"]


def split_bag(bag: pathlib.Path, at_ns: int) -> list[pathlib.Path]:
    """The bag as `rosbag record --split` leaves it: two parts, messages before / from at_ns."""
    parts = [bag.with_name(f"{bag.stem}_{k}.bag") for k in range(2)]
    with Reader(bag) as reader, Writer(parts[0]) as w0, Writer(parts[1]) as w1:
        conns = {}
        for conn, t, raw in reader.messages():
            w = w0 if t < at_ns else w1
            key = (id(w), conn.topic)
            if key not in conns:
                conns[key] = w.add_connection(conn.topic, conn.msgtype, typestore=m.TYPESTORE)
            w.write(conns[key], t, raw)
    return parts


def test_split_recording_runs_as_one_bag(tmp_path, synth_rgbd, capsys):
    bag = tmp_path / "whole.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag), depth_encoding="16UC1"))
    whole = BagProvider(bag)
    parts = split_bag(bag, m.stamp_ns(whole.stamp(4)))
    whole.close()
    shutil.copy(sidecar(bag, "settings.yaml"), sidecar(parts[0], "settings.yaml"))  # the first part's sidecars
    shutil.copy(sidecar(bag, "groundtruth.tum"), sidecar(parts[0], "groundtruth.tum"))
    a = run_bag(BagRunOptions(bag=str(bag), out=str(tmp_path / "a"), vocabulary="none", progress=False))
    assert main(["bag", "run", *map(str, parts), "--out", str(tmp_path / "b"), "--vocabulary", "none",
                 "--quiet"]) == 0
    b = json.loads((tmp_path / "b" / "stats.json").read_text())
    assert b["frames"] == a["frames"] == 8 and b["tracked_frames"] == 8
    assert b["bag"]["files"] == [str(p) for p in parts]
    np.testing.assert_allclose(trajectory(tmp_path / "b"), trajectory(tmp_path / "a"), atol=1e-9)
    assert b["ate"]["rmse"] == pytest.approx(a["ate"]["rmse"], abs=1e-12)
    with pytest.raises(FileNotFoundError, match="missing.bag"):
        BagProvider([parts[0], tmp_path / "missing.bag"])


def test_bag_info(tmp_path, synth_stereo, capsys):
    bag = tmp_path / "s.bag"
    write_dataset_bag(BagWriteOptions(kind="kitti", path=str(synth_stereo / "sequences" / "00"), out=str(bag)))
    assert main(["bag", "info", str(bag), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["topics"]["/camera/left/image_rect"] == {"type": m.IMAGE, "messages": 6}
    seq = info["sequence"]
    assert seq["sensor"] == "stereo" and seq["frames"] == 6 and seq["ground_truth_poses"] == 6
    assert seq["rate_hz"] == pytest.approx(20.0, rel=1e-3)
    assert seq["topics"] == {"image": "/camera/left/image_rect", "right": "/camera/right/image_rect"}
    assert main(["bag", "info", str(bag)]) == 0
    assert "sequence: stereo, 6 frames at 20.0 Hz" in capsys.readouterr().out
    odd = tmp_path / "odd.bag"
    write_images(odd, ["mono8", "mono8"])
    assert main(["bag", "info", str(odd)]) == 0  # topics listed; why it is no sequence said
    out = capsys.readouterr().out
    assert "/camera/image_raw" in out and "not readable as a sequence" in out and "--topic image=TOPIC" in out
    assert main(["bag", "info", str(odd), "--topic", "image=/camera/image_raw"]) == 0
    assert "no settings" in capsys.readouterr().out
    config = pathlib.Path(__file__).resolve().parents[2] / "config" / "EuRoC_mono.yaml"
    assert main(["bag", "info", str(odd), "--config", str(config), "--topic", "image=/camera/image_raw"]) == 0
    assert "sequence: mono, 2 frames" in capsys.readouterr().out
