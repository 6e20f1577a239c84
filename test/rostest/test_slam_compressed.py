#!/usr/bin/env python3
"""rostest: dynaorb_node reading compressed images (~image_transport compressed).

Stereo: KITTI 06's first FRAMES frames go raw to /raw and as lossless PNG CompressedImage
(image_transport's names: .../image_rect/compressed) to /compressed; both nodes give the same
odometry. RGB-D: a static synthetic room rendered here goes as JPEG colour
(/camera/rgb/image_color/compressed, the node's rgb/image remapped to /camera/rgb/image_color)
and compressedDepth 32FC1 (/camera/depth/image/compressedDepth: a 12-byte
header and the PNG of the quantised inverse depth, compressed_depth_image_transport's
defaults; both made by dynaorb.ros.bag.messages.compress, the Python bag tools' encoder,
decoded here by the node's C++ codec) with camera_info to /rgbd: every frame tracked, ATE (the recorder on /rgbd/odom)
within SLAM core I's 0.01 m. Each frame is published once the nodes answered the one before on
tracking_state. Then a CompressedImage that does not decode: counted as unreadable.
"""
import json
import pathlib
import sys
import threading
import unittest

import cv2
import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from std_srvs.srv import Trigger

from dynaorb.msg import TrackingStatus

FRAMES = 15       # KITTI 06 frames
RGBD_FRAMES = 20  # synthetic room
BASE = 1000.0     # s added to KITTI's stamps (which start at 0)


def grey(path: pathlib.Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise FileNotFoundError(f"{path}: not a readable image")
    return image


def raw_msg(image: np.ndarray, stamp: rospy.Time, frame_id: str) -> Image:
    msg = Image()
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    msg.height, msg.width = image.shape[:2]
    msg.encoding = "mono8"
    msg.step = image.shape[1]
    msg.data = image.tobytes()
    return msg


def compressed_msg(fmt: str, data: bytes, stamp: rospy.Time, frame_id: str) -> CompressedImage:
    msg = CompressedImage()
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    msg.format = fmt
    msg.data = data
    return msg


class SlamCompressedTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_slam_compressed")
        cls.answers = {n: [] for n in ("raw", "compressed", "rgbd")}
        cls.odom = {n: {} for n in cls.answers}
        cond = threading.Condition()

        def on_status(msg, node):
            with cond:
                cls.answers[node].append(msg)
                cond.notify_all()

        def on_odom(msg, node):
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            cls.odom[node][round(msg.header.stamp.to_sec(), 6)] = [p.x, p.y, p.z, q.x, q.y, q.z, q.w]

        subs = [rospy.Subscriber(f"/{n}/tracking_state", TrackingStatus, on_status, n, queue_size=100)
                for n in cls.answers]
        subs += [rospy.Subscriber(f"/{n}/odom", Odometry, on_odom, n, queue_size=100) for n in cls.answers]
        pub = {
            "raw_l": rospy.Publisher("/raw/left/image_rect", Image, queue_size=5),
            "raw_r": rospy.Publisher("/raw/right/image_rect", Image, queue_size=5),
            "c_l": rospy.Publisher("/compressed/left/image_rect/compressed", CompressedImage, queue_size=5),
            "c_r": rospy.Publisher("/compressed/right/image_rect/compressed", CompressedImage, queue_size=5),
            "rgb": rospy.Publisher("/camera/rgb/image_color/compressed", CompressedImage, queue_size=5),
            "depth": rospy.Publisher("/camera/depth/image/compressedDepth", CompressedImage, queue_size=5),
            "info": rospy.Publisher("/rgbd/rgb/camera_info", CameraInfo, queue_size=5, latch=True),
        }
        for n in cls.answers:
            rospy.wait_for_service(f"/{n}/dynaorb_node/stats", timeout=60)
        deadline = rospy.Time.now() + rospy.Duration(20)
        while any(p.get_num_connections() == 0 for p in pub.values()):
            if rospy.Time.now() > deadline:
                raise RuntimeError("dynaorb_node did not subscribe to the image topics: " +
                                   ", ".join(k for k, p in pub.items() if p.get_num_connections() == 0))
            rospy.sleep(0.1)

        def wait(node, count):
            with cond:
                if not cond.wait_for(lambda: len(cls.answers[node]) >= count, timeout=30):
                    raise RuntimeError(f"{node}: no answer on tracking_state for frame {count - 1}")

        # Stereo, raw and lossless PNG.
        seq = pathlib.Path(rospy.get_param("~sequence"))
        times = [float(t) for t in (seq / "times.txt").read_text().split()]
        for i in range(FRAMES):
            stamp = rospy.Time.from_sec(BASE + times[i])
            for side, folder in (("l", "image_0"), ("r", "image_1")):
                image = grey(seq / folder / f"{i:06d}.png")
                pub["raw_" + side].publish(raw_msg(image, stamp, "camera_left_optical_frame"))
                pub["c_" + side].publish(compressed_msg("mono8; png compressed mono8",
                                                        cv2.imencode(".png", image)[1].tobytes(), stamp,
                                                        "camera_left_optical_frame"))
            wait("raw", i + 1)
            wait("compressed", i + 1)

        # RGB-D: a static synthetic room, JPEG colour and compressedDepth 32FC1.
        from dynaorb import core
        from dynaorb.ros.bag.messages import compress, image_msg
        from dynaorb.synth import SynthConfig, generate

        room = pathlib.Path(rospy.get_param("~rgbd_dir")) / "room"
        generate(room, SynthConfig(sensor="rgbd", movers=0, frames=RGBD_FRAMES, seed=1, width=320, height=240,
                                   fx=262.5))
        provider = core().open_dataset("tum", str(room))
        s = provider.default_settings()
        info = CameraInfo(width=s.width, height=s.height, distortion_model="plumb_bob", D=[0.0] * 5,
                          K=[s.fx, 0, s.cx, 0, s.fy, s.cy, 0, 0, 1], R=[1, 0, 0, 0, 1, 0, 0, 0, 1],
                          P=[s.fx, 0, s.cx, 0, 0, s.fy, s.cy, 0, 0, 0, 1, 0])
        info.header.frame_id = "camera_rgb_optical_frame"
        pub["info"].publish(info)
        for i in range(RGBD_FRAMES):
            f = provider.load(i)
            stamp = rospy.Time.from_sec(f.stamp)
            metres = f.depth.astype(np.float32) / np.float32(s.depth_map_factor)
            metres[f.depth == 0] = np.nan
            for key, image, encoding, fmt in (("rgb", f.image, "bgr8", "jpeg"), ("depth", metres, "32FC1", "png")):
                packed = compress(image_msg(image, encoding, f.stamp, "camera_rgb_optical_frame"), fmt)
                pub[key].publish(compressed_msg(packed.format, bytes(packed.data), stamp, "camera_rgb_optical_frame"))
            wait("rgbd", i + 1)
        cls.rgbd_stamps = [provider.stamp(i) for i in range(RGBD_FRAMES)]

        # Data that does not decode: counted, the node goes on.
        junk_stamp = rospy.Time.from_sec(BASE + times[FRAMES])
        pub["c_l"].publish(compressed_msg("mono8; png compressed mono8", b"\x00" * 64, junk_stamp, "camera"))
        deadline = rospy.Time.now() + rospy.Duration(10)
        stats = rospy.ServiceProxy("/compressed/dynaorb_node/stats", Trigger)
        while json.loads(stats().message)["unreadable"] < 1 and rospy.Time.now() < deadline:
            rospy.sleep(0.1)
        rospy.sleep(0.5)  # the last odometry messages
        for sub in subs:
            sub.unregister()
        cls.stats = {n: json.loads(rospy.ServiceProxy(f"/{n}/dynaorb_node/stats", Trigger)().message)
                     for n in cls.answers}
        cls.rgbd_report = json.loads(rospy.ServiceProxy("/rgbd/recorder/report", Trigger)().message)

    def test_compressed_stereo_tracks_as_raw(self):
        for n in ("raw", "compressed"):
            self.assertEqual([a.state for a in self.answers[n]], ["OK"] * FRAMES, n)
        self.assertEqual(sorted(self.odom["raw"]), sorted(self.odom["compressed"]))
        self.assertEqual(len(self.odom["raw"]), FRAMES)
        for stamp, pose in self.odom["raw"].items():
            np.testing.assert_allclose(self.odom["compressed"][stamp], pose, atol=1e-9, err_msg=str(stamp))

    def test_undecodable_image_is_counted(self):
        self.assertEqual(self.stats["compressed"]["unreadable"], 1)
        self.assertEqual(self.stats["raw"]["unreadable"], 0)

    def test_compressed_rgbd_with_camera_info(self):
        self.assertEqual([a.state for a in self.answers["rgbd"]], ["OK"] * RGBD_FRAMES)
        self.assertEqual(self.stats["rgbd"]["unreadable"], 0)
        report = self.rgbd_report
        self.assertEqual(report["poses"], RGBD_FRAMES)
        self.assertEqual(report["matched_poses"], RGBD_FRAMES)
        self.assertLessEqual(report["ate"]["rmse"], 0.01)  # SLAM core I's bound, synthetic RGB-D


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "slam_compressed", SlamCompressedTest, sys.argv)
