"""dynaorb bag to-dataset: bags written back as TUM / KITTI folders; settings from
a bag's camera_info; ground truth from a pose topic."""
from __future__ import annotations

import dataclasses
import pathlib
import shutil

import cv2
import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from scipy.spatial.transform import Rotation

from dynaorb import core
from dynaorb.cli.main import main
from dynaorb.ros.bag import (BagProvider, BagRunOptions, BagToDatasetOptions, BagWriteOptions, bag_to_dataset,
                             run_bag, write_dataset_bag)
from dynaorb.ros.bag import messages as m
from dynaorb.ros.bag.info import bag_info
from dynaorb.ros.bag.poses import read_pose_topic, read_tf, sample
from dynaorb.runner import RunOptions, run_dataset


def frames(provider) -> list:
    return [provider.load(i) for i in range(len(provider))]


def tum_rows(path) -> np.ndarray:
    return np.loadtxt(path, comments="#", ndmin=2)


def without_sidecars(bag: pathlib.Path, tmp_path: pathlib.Path) -> pathlib.Path:
    """A copy of the bag with nothing beside it (a bag as a robot records it)."""
    bare = tmp_path / "bare" / bag.name
    bare.parent.mkdir()
    shutil.copy(bag, bare)
    return bare


def pinhole_info(stamp: float, width: int, height: int, f: float = 80.0):
    """A plumb_bob CameraInfo without distortion, principal point at the centre."""
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
    return m.camera_info_msg(stamp, "cam", width, height, K, np.zeros(5), np.hstack([K, np.zeros((3, 1))]))


def write_rgbd_bag(path: pathlib.Path, times, depth_delays, depth_m: float, stamped: bool = True) -> None:
    """A TUM-topic RGB-D bag of 64x48 frames recorded at `times` (grey level 60 + k), each
    depth image `depth_delays[k]` s later at `depth_m` metres, with camera_info; headers
    stamped with the record times, or left at zero (`stamped` False)."""
    with Writer(path) as w:
        rgb = w.add_connection("/camera/rgb/image_color", m.IMAGE, typestore=m.TYPESTORE)
        depth = w.add_connection("/camera/depth/image", m.IMAGE, typestore=m.TYPESTORE)
        info = w.add_connection("/camera/rgb/camera_info", m.CAMERA_INFO, typestore=m.TYPESTORE)
        for k, (t, delay) in enumerate(zip(times, depth_delays)):
            stamp = t if stamped else 0.0
            image = np.full((48, 64, 3), 60 + k, np.uint8)
            w.write(rgb, m.stamp_ns(t), m.serialize(m.image_msg(image, "rgb8", stamp, "c")))
            w.write(info, m.stamp_ns(t), m.serialize(pinhole_info(stamp, 64, 48)))
            d = t + delay
            w.write(depth, m.stamp_ns(d), m.serialize(m.image_msg(np.full((48, 64), depth_m, np.float32), "32FC1",
                                                                  d if stamped else 0.0, "c")))


# ------------------------------------------------------------------ round trips
def test_rgbd_bag_back_to_tum_gives_the_same_frames_and_run(tmp_path, synth_rgbd):
    bag = tmp_path / "rgbd.bag"  # 32FC1 metres, as TUM's own bags
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag), labels=str(synth_rgbd / "labels")))
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "tum")))
    assert summary["layout"] == "tum" and summary["frames"] == 8 and summary["labels"] == 8
    assert summary["run"] == f"dynaorb run tum {tmp_path / 'tum'} --labels {tmp_path / 'tum' / 'labels'}"
    original, back = core().open_dataset("tum", str(synth_rgbd)), core().open_dataset("tum", str(tmp_path / "tum"))
    assert len(back) == len(original)
    for a, b in zip(frames(original), frames(back)):
        assert b.stamp == pytest.approx(a.stamp, abs=1e-6)
        np.testing.assert_array_equal(b.image, a.image)
        np.testing.assert_array_equal(b.depth, a.depth)  # metres x DepthMapFactor back to the PNG units
        labels_a = cv2.imread(str(synth_rgbd / "labels" / pathlib.Path(a.image_path).name), cv2.IMREAD_UNCHANGED)
        labels_b = cv2.imread(str(tmp_path / "tum" / "labels" / pathlib.Path(b.image_path).name), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(labels_b, labels_a)
    np.testing.assert_allclose(tum_rows(tmp_path / "tum" / "groundtruth.txt"), tum_rows(synth_rgbd / "groundtruth.txt"),
                               atol=1e-6)
    runs = [run_dataset(RunOptions(kind="tum", path=str(p), out=str(tmp_path / name), vocabulary="none",
                                   progress=False)) for p, name in ((synth_rgbd, "a"), (tmp_path / "tum", "b"))]
    assert runs[1]["tracked_frames"] == runs[0]["tracked_frames"] == 8
    np.testing.assert_allclose(tum_rows(tmp_path / "b" / "trajectory.tum"), tum_rows(tmp_path / "a" / "trajectory.tum"),
                               atol=1e-9)


def test_stereo_bag_back_to_kitti_with_calibration_and_poses(tmp_path, synth_stereo):
    seq = synth_stereo / "sequences" / "00"
    bag = tmp_path / "stereo.bag"
    write_dataset_bag(BagWriteOptions(kind="kitti", path=str(seq), out=str(bag)))  # stamps + 1 s
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "kitti")))
    assert summary["layout"] == "kitti" and summary["sensor"] == "stereo" and summary["frames"] == 6
    assert summary["ground_truth"] == {"poses": 6, "frames_covered": 6, "kitti_poses": 6}
    back_seq = tmp_path / "kitti" / "sequences" / "00"
    original, back = core().open_dataset("kitti", str(seq)), core().open_dataset("kitti", str(back_seq))
    for a, b in zip(frames(original), frames(back)):
        assert b.stamp == pytest.approx(a.stamp + 1.0, abs=1e-6)
        np.testing.assert_array_equal(b.image, a.image)
        np.testing.assert_array_equal(b.right, a.right)
    sa, sb = original.default_settings(), back.default_settings()
    assert (sb.fx, sb.fy, sb.cx, sb.cy, sb.bf) == (sa.fx, sa.fy, sa.cx, sa.cy, sa.bf)
    calib = {line.split(":")[0]: np.array(line.split()[1:], float)
             for line in (back_seq / "calib.txt").read_text().splitlines()}
    np.testing.assert_allclose(calib["P1"][3], -sa.bf)
    ga, gb = original.ground_truth(), back.ground_truth()
    np.testing.assert_allclose(gb[1], ga[1], atol=1e-6)  # the synthetic poses are relative to frame 0 already


# ------------------------------------------------------------------ camera_info
@pytest.mark.parametrize("fixture,kind,depth", [("synth_stereo", "kitti", None), ("synth_rgbd", "tum", "32FC1"),
                                                ("synth_rgbd", "tum", "16UC1")])
def test_settings_from_the_bags_camera_info(tmp_path, request, fixture, kind, depth):
    seq = request.getfixturevalue(fixture)
    path = seq if kind == "tum" else seq / "sequences" / "00"
    bag = tmp_path / "seq.bag"
    write_dataset_bag(BagWriteOptions(kind=kind, path=str(path), out=str(bag), depth_encoding=depth or "32FC1"))
    bare = without_sidecars(bag, tmp_path)
    provider = BagProvider(bare)
    assert provider.settings_from_camera_info
    s, ref = provider.default_settings(), core().open_dataset(kind, str(path)).default_settings()
    assert (s.fx, s.fy, s.cx, s.cy, s.width, s.height) == (ref.fx, ref.fy, ref.cx, ref.cy, ref.width, ref.height)
    assert s.n_features == 1000 and "camera_info" in s.source
    assert s.fps == pytest.approx(ref.fps, rel=1e-3)
    if kind == "kitti":
        assert s.bf == pytest.approx(ref.bf) and s.th_depth == 35.0
    else:  # REP-118: 16UC1 in millimetres; 32FC1 metres, written at TUM's 5000 per metre
        assert s.depth_map_factor == {"32FC1": 5000.0, "16UC1": 1000.0}[depth]
        assert s.bf == pytest.approx(ref.fx * 0.08) and s.th_depth == 40.0
    provider.close()
    if depth != "16UC1":  # the synthetic PNG units are not millimetres: that bag needs its settings
        stats = run_bag(BagRunOptions(bag=str(bare), out=str(tmp_path / "run"), vocabulary="none", progress=False))
        assert stats["tracked_frames"] == stats["frames"] > 0
        assert (tmp_path / "run" / "settings.camera_info.yaml").is_file()


def test_camera_info_it_cannot_use_is_named(tmp_path):
    bag = tmp_path / "fisheye.bag"
    with Writer(bag) as w:
        img = w.add_connection("/cam/image_raw", m.IMAGE, typestore=m.TYPESTORE)
        info = w.add_connection("/cam/camera_info", m.CAMERA_INFO, typestore=m.TYPESTORE)
        for k in range(3):
            t = 5.0 + 0.1 * k
            w.write(img, m.stamp_ns(t), m.serialize(m.image_msg(np.zeros((48, 64), np.uint8), "mono8", t, "cam")))
            msg = dataclasses.replace(pinhole_info(t, 64, 48, f=50.0), distortion_model="equidistant")
            w.write(info, m.stamp_ns(t), m.serialize(msg))
    with pytest.raises(ValueError, match="equidistant"):
        BagProvider(bag, topics={"image": "/cam/image_raw"})


def test_tum_named_bag_takes_the_benchmarks_camera_not_its_camera_info(tmp_path, synth_rgbd):
    """TUM's own bags (rgbd_dataset_freiburgN_*.bag) carry the driver's default
    camera_info: the name picks ORB-SLAM2's TUM1/2/3 calibration, as a TUM folder's does."""
    bag = tmp_path / "seq.bag"
    write_dataset_bag(BagWriteOptions(kind="tum", path=str(synth_rgbd), out=str(bag)))
    bare = without_sidecars(bag, tmp_path)
    tum = bare.rename(bare.with_name("rgbd_dataset_freiburg2_desk.bag"))
    provider = BagProvider(tum)
    s = provider.default_settings()
    assert not provider.settings_from_camera_info
    assert (s.fx, s.fy, s.depth_map_factor) == (520.908620, 521.007327, 5208.0)
    assert "freiburg2" in s.source and tum.name in s.source
    assert any("chosen by the bag's name" in w for w in provider.warnings)
    provider.close()
    info = bag_info(tum)
    assert "freiburg2" in info["sequence"]["settings"]
    given = BagProvider(tum, settings=str(synth_rgbd / "settings.yaml"))  # --config still wins
    assert given.default_settings().fx != 520.908620 and not any("bag's name" in w for w in given.warnings)
    given.close()
    assert core().tum_settings_for_name("rgbd_dataset_freiburg1_xyz.bag").fx == 517.306408
    assert core().tum_settings_for_name("robot.bag") is None


def test_a_bag_without_images_is_named_before_missing_settings(tmp_path):
    bag = tmp_path / "status.bag"  # no images, no settings beside it, no camera_info
    with Writer(bag) as w:
        conn = w.add_connection("/status", "std_msgs/msg/String", typestore=m.TYPESTORE)
        w.write(conn, m.stamp_ns(1.0), m.TYPESTORE.serialize_ros1(m.TYPESTORE.types["std_msgs/msg/String"](data="up"),
                                                                  "std_msgs/msg/String"))
    with pytest.raises(ValueError, match="no image topic"):
        BagProvider(bag)
    assert "no image topic" in bag_info(bag)["sequence"]["error"]


# ------------------------------------------------------------------ ground truth from a topic
POSE_RATE, FRAME_RATE = 100.0, 10.0


def body_pose(t: float) -> np.ndarray:
    """A known motion: 0.5 m/s along x and 20 deg/s about z."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", 20.0 * t, degrees=True).as_matrix()
    T[:3, 3] = [0.5 * t, 0.1, 1.0]
    return T


def pose_message(msgtype: str, t: float):
    types = m.TYPESTORE.types
    T = body_pose(t)
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    point = types["geometry_msgs/msg/Point"](x=T[0, 3], y=T[1, 3], z=T[2, 3])
    quat = types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])
    pose = types["geometry_msgs/msg/Pose"](position=point, orientation=quat)
    header = m.header(t, "world")
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return types[msgtype](header=header, pose=pose)
    if msgtype == "geometry_msgs/msg/TransformStamped":
        v = types["geometry_msgs/msg/Vector3"](x=T[0, 3], y=T[1, 3], z=T[2, 3])
        return types[msgtype](header=header, child_frame_id="body",
                              transform=types["geometry_msgs/msg/Transform"](translation=v, rotation=quat))
    with_cov = types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36))
    if msgtype == "nav_msgs/msg/Odometry":
        twist = types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](linear=types["geometry_msgs/msg/Vector3"](x=0, y=0, z=0),
                                                   angular=types["geometry_msgs/msg/Vector3"](x=0, y=0, z=0)),
            covariance=np.zeros(36))
        return types[msgtype](header=header, child_frame_id="body", pose=with_cov, twist=twist)
    return types[msgtype](header=header, pose=with_cov)


def mono_bag_with_poses(path: pathlib.Path, msgtype: str, first_pose: float = 0.0, topic: str = "/mocap/pose",
                        message=None) -> np.ndarray:
    """10 grey frames at 10 Hz from t = 100.003 s (between pose samples), camera_info,
    and poses at 100 Hz on `topic` from 100 + first_pose s (`message(msgtype, t)`,
    default pose_message); returns the frame stamps."""
    stamps = 100.003 + np.arange(10) / FRAME_RATE
    rng = np.random.default_rng(0)
    with Writer(path) as w:
        img = w.add_connection("/camera/image_raw", m.IMAGE, typestore=m.TYPESTORE)
        info = w.add_connection("/camera/camera_info", m.CAMERA_INFO, typestore=m.TYPESTORE)
        pose = w.add_connection(topic, msgtype, typestore=m.TYPESTORE)
        for k, t in enumerate(stamps):
            image = rng.integers(0, 255, (96, 128), dtype=np.uint8)
            w.write(img, m.stamp_ns(t), m.serialize(m.image_msg(image, "mono8", t, "cam", k)))
            w.write(info, m.stamp_ns(t), m.serialize(pinhole_info(t, 128, 96)))
        for t in 100.0 + first_pose + np.arange(int(1.2 * POSE_RATE)) / POSE_RATE:
            w.write(pose, m.stamp_ns(t), m.serialize((message or pose_message)(msgtype, t)))
    return stamps


@pytest.mark.parametrize("msgtype", ["geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TransformStamped",
                                     "nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseWithCovarianceStamped"])
def test_ground_truth_from_a_pose_topic(tmp_path, msgtype):
    bag = tmp_path / "robot.bag"
    stamps = mono_bag_with_poses(bag, msgtype)
    gt_stamps, gt_poses = read_pose_topic(bag, "/mocap/pose")
    assert len(gt_stamps) == 120
    np.testing.assert_allclose(gt_poses[37], body_pose(gt_stamps[37]), atol=1e-9)
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "ds"),
                                                 topics={"image": "/camera/image_raw"},
                                                 ground_truth_topic="/mocap/pose"))
    assert summary["sensor"] == "mono" and summary["settings_from_camera_info"]
    assert summary["run"].endswith("--sensor mono")
    assert summary["ground_truth"] == {"poses": 120, "frames_covered": 10, "kitti_poses": 10}
    seq = tmp_path / "ds" / "sequences" / "00"
    back = core().open_dataset("kitti", str(seq), "mono")
    assert len(back) == 10 and [back.stamp(i) for i in range(10)] == pytest.approx(stamps, abs=1e-6)
    # KITTI poses: the body at each frame stamp (interpolated between the 100 Hz
    # samples: linear in position, slerp at a constant rate) in the first frame's.
    _, poses = back.ground_truth()
    first_inv = np.linalg.inv(body_pose(stamps[0]))
    for k, t in enumerate(stamps):
        np.testing.assert_allclose(poses[k], first_inv @ body_pose(t), atol=1e-6)
    np.testing.assert_allclose(tum_rows(seq / "groundtruth.tum")[:, 0], gt_stamps, atol=1e-6)


def test_ground_truth_that_starts_late_gives_no_kitti_poses(tmp_path):
    bag = tmp_path / "late.bag"
    mono_bag_with_poses(bag, "geometry_msgs/msg/PoseStamped", first_pose=0.25)
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "ds"),
                                                 topics={"image": "/camera/image_raw"},
                                                 ground_truth_topic="/mocap/pose"))
    assert summary["ground_truth"]["kitti_poses"] == 0 and summary["ground_truth"]["frames_covered"] == 7
    assert not (tmp_path / "ds" / "poses").exists()
    assert (tmp_path / "ds" / "sequences" / "00" / "groundtruth.tum").is_file()


def test_sampling_a_trajectory():
    stamps = np.array([0.0, 0.1, 0.2, 0.5])
    poses = np.stack([body_pose(t) for t in stamps])
    at = sample(stamps, poses, np.array([0.1, 0.15, 0.3, -0.1, 0.6]), max_gap=0.15)
    np.testing.assert_allclose(at[0], poses[1])
    np.testing.assert_allclose(at[1], body_pose(0.15), atol=1e-12)
    assert np.isnan(at[2:]).all()  # in a 0.3 s gap; before; after


# ------------------------------------------------------------------ bad input and the command line
def test_to_dataset_errors_are_named(tmp_path, synth_stereo):
    bag = tmp_path / "s.bag"
    write_dataset_bag(BagWriteOptions(kind="kitti", path=str(synth_stereo / "sequences" / "00"), out=str(bag)))
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    with pytest.raises(FileExistsError, match="not empty"):
        bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "full")))
    with pytest.raises(ValueError, match="largest gap"):
        bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "gap"), ground_truth_max_gap=float("nan")))
    with pytest.raises(ValueError, match="one way"):
        BagProvider(bag, ground_truth=str(tmp_path / "s.groundtruth.tum"), ground_truth_topic="/x")
    with pytest.raises(ValueError, match="is not in the bag"):
        BagProvider(bag, ground_truth_topic="/mocap/pose")
    with pytest.raises(ValueError, match="not a stamped pose"):
        BagProvider(bag, ground_truth_topic="/camera/left/image_rect")
    bare = without_sidecars(bag, tmp_path)
    with Writer(tmp_path / "no_info.bag") as w:
        c = w.add_connection("/camera/left/image_rect", m.IMAGE, typestore=m.TYPESTORE)
        w.write(c, m.stamp_ns(1.0), m.serialize(m.image_msg(np.zeros((8, 8), np.uint8), "mono8", 1.0, "cam")))
    with pytest.raises(ValueError, match="no settings.*CameraInfo"):
        BagProvider(tmp_path / "no_info.bag")
    assert BagProvider(bare).settings_from_camera_info


def test_cli_to_dataset(tmp_path, synth_stereo, capsys):
    bag = tmp_path / "s.bag"
    write_dataset_bag(BagWriteOptions(kind="kitti", path=str(synth_stereo / "sequences" / "00"), out=str(bag)))
    out = tmp_path / "ds"
    assert main(["bag", "to-dataset", str(bag), "-o", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "6 frames (stereo)" in printed and f"run it: dynaorb run kitti {out / 'sequences' / '00'}" in printed
    assert main(["bag", "to-dataset", str(bag), "-o", str(out), "--quiet"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(["bag", "to-dataset", str(bag), "-o", str(out), "--quiet", "--overwrite"]) == 0
    assert main(["run", "kitti", str(out / "sequences" / "00"), "--out", str(tmp_path / "run"),
                 "--vocabulary", "none", "--quiet"]) == 0
    assert "6/6 frames tracked" in capsys.readouterr().out


def test_pairs_further_apart_than_the_tum_reader_pairs_are_counted(tmp_path):
    bag = tmp_path / "late_depth.bag"
    # Every other depth image 30 ms late.
    write_rgbd_bag(bag, 50.0 + 0.1 * np.arange(4), [0.01, 0.03, 0.01, 0.03], depth_m=1.5)
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "ds"), max_diff=0.05))
    assert summary["frames"] == 4 and summary["depth_pairs_beyond_tum"] == 2
    depth_png = cv2.imread(str(next((tmp_path / "ds" / "depth").iterdir())), cv2.IMREAD_UNCHANGED)
    assert depth_png.dtype == np.uint16 and (depth_png == 7500).all()  # 1.5 m at 5000 per metre
    assert len(core().open_dataset("tum", str(tmp_path / "ds"))) == 2  # the TUM reader pairs within 0.02 s


def tf_message(msgtype: str, t: float):
    """One TF message with the motion-capture pose (/world -> /kinect, leading slashes as
    TUM's bags) and another transform beside it."""
    types = m.TYPESTORE.types
    out = []
    for parent, child, T in (("/world", "/kinect", body_pose(t)), ("/kinect", "/openni_camera", np.eye(4))):
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        v = types["geometry_msgs/msg/Vector3"](x=T[0, 3], y=T[1, 3], z=T[2, 3])
        quat = types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])
        out.append(types["geometry_msgs/msg/TransformStamped"](
            header=m.header(t, parent), child_frame_id=child,
            transform=types["geometry_msgs/msg/Transform"](translation=v, rotation=quat)))
    return types[msgtype](transforms=out)


@pytest.mark.parametrize("msgtype", m.TF_TYPES)
def test_ground_truth_from_tf(tmp_path, msgtype):
    # The frames of the pose-topic tests, with the poses on /tf instead.
    stamps = mono_bag_with_poses(tmp_path / "tf.bag", msgtype, topic="/tf", message=tf_message)
    gt_stamps, gt_poses = read_tf(tmp_path / "tf.bag", "world", "/kinect")
    assert len(gt_stamps) == 120
    np.testing.assert_allclose(gt_poses[50], body_pose(gt_stamps[50]), atol=1e-9)
    _, inverse = read_tf(tmp_path / "tf.bag", "kinect", "world")  # the other way round: inverted
    np.testing.assert_allclose(inverse[50], np.linalg.inv(body_pose(gt_stamps[50])), atol=1e-9)
    with pytest.raises(ValueError, match="kinect -> openni_camera"):
        read_tf(tmp_path / "tf.bag", "world", "openni_camera")  # not joined directly: the pairs named
    out = tmp_path / "ds"
    assert main(["bag", "to-dataset", str(tmp_path / "tf.bag"), "-o", str(out), "--topic", "image=/camera/image_raw",
                 "--ground-truth-tf", "world:kinect", "--quiet"]) == 0
    _, poses = core().open_dataset("kitti", str(out / "sequences" / "00"), "mono").ground_truth()
    first_inv = np.linalg.inv(body_pose(stamps[0]))
    for k, t in enumerate(stamps):
        np.testing.assert_allclose(poses[k], first_inv @ body_pose(t), atol=1e-6)
    assert main(["bag", "to-dataset", str(tmp_path / "tf.bag"), "-o", str(tmp_path / "x"),
                 "--ground-truth-tf", "world"]) == 2


def test_a_pose_that_is_not_one_is_refused_by_name(tmp_path):
    """A zero quaternion at 100.5 s, on a pose topic and on TF alike: a ValueError naming where."""
    def broken(message):
        def make(msgtype, t):
            msg = message(msgtype, t)
            if abs(t - 100.5) < 1e-9:
                zero = m.TYPESTORE.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=0.0)
                if msgtype in m.TF_TYPES:
                    msg.transforms[0].transform.rotation = zero
                else:
                    msg.pose.orientation = zero
            return msg
        return make

    mono_bag_with_poses(tmp_path / "pose.bag", "geometry_msgs/msg/PoseStamped", message=broken(pose_message))
    with pytest.raises(ValueError, match=r"/mocap/pose at 100\.500000: orientation .* is not a unit quaternion"):
        read_pose_topic(tmp_path / "pose.bag", "/mocap/pose")
    mono_bag_with_poses(tmp_path / "tf.bag", "tf2_msgs/msg/TFMessage", topic="/tf", message=broken(tf_message))
    with pytest.raises(ValueError, match=r"TF world -> kinect at 100\.500000: orientation .* is not a unit quaternion"):
        read_tf(tmp_path / "tf.bag", "world", "kinect")


def test_images_without_header_stamps_take_the_bags_record_times(tmp_path):
    """A driver that leaves header stamps at zero: the bag's record times stand in, and
    an RGB-D pair recorded 5 ms apart is still paired."""
    bag = tmp_path / "unstamped.bag"
    write_rgbd_bag(bag, 70.0 + 0.1 * np.arange(3), [0.005] * 3, depth_m=2.0, stamped=False)
    provider = BagProvider(bag)
    assert len(provider) == 3 and provider.stamp(2) == pytest.approx(70.2, abs=1e-6)
    assert any("record times" in w for w in provider.warnings)
    assert provider.load(1).image[0, 0, 0] == 61
    provider.close()
    summary = bag_to_dataset(BagToDatasetOptions(bag=str(bag), out=str(tmp_path / "ds")))
    assert summary["frames"] == 3 and summary["depth_pairs_beyond_tum"] == 0
    back = core().open_dataset("tum", str(tmp_path / "ds"))
    assert [back.stamp(i) for i in range(3)] == pytest.approx([70.0, 70.1, 70.2], abs=1e-6)
