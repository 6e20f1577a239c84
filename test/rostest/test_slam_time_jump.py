#!/usr/bin/env python3
"""rostest: dynaorb_node when time goes back (a bag played again or looped, a simulator reset).

KITTI 06's first 20 frames are published to stereo nodes, then its first 12 again stamped
0.5 s later than the first time: time goes back 1.4 s, as when a simulator is reset or a bag
played again (`rosbag play -l` gives the same stamps again; these do not meet the first
ones, so no label of the time before can pass for one of the replay's). Each frame is published once the nodes
answered the one before on tracking_state. The node with ~time_jump_reset (default 1 s) drops
its map at the first replayed frame and tracks the replay in a new one (~stats time_jumps 1);
the node with ~time_jump_reset 0 refuses every replayed frame as out of order. A third node
waits for each frame's labels (~wait_for_labels; label images published just after the
frame): the labels of the time before are dropped at the jump (kept, they would tell the first
replayed frame that its labels had passed), and every replayed frame is tracked with its own.
The node with the reset writes each pass's trajectory (~trajectory_file): the first pass's at
the jump, the replay's to FILE-stem.pass2.tum on ~save_trajectory.
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
from sensor_msgs.msg import Image
from std_srvs.srv import Trigger

from dynaorb.msg import TrackingStatus
from dynaorb.srv import MapFile

NODES = ("reset", "off", "labels")
FIRST_PASS = 20  # frames, then the first REPLAY of them again
REPLAY = 12
BASE = 1000.0    # s added to KITTI's stamps (which start at 0)
SHIFT = 0.5      # s added to the replay's


def mono8(path: pathlib.Path, stamp: rospy.Time, frame_id: str) -> Image:
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise FileNotFoundError(f"{path}: not a readable image")
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = image.shape
    msg.encoding = "mono8"
    msg.step = image.shape[1]
    msg.data = image.tobytes()
    return msg


class SlamTimeJumpTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_slam_time_jump")
        seq = pathlib.Path(rospy.get_param("~sequence"))
        times = [float(t) for t in (seq / "times.txt").read_text().split()]
        frames = list(range(FIRST_PASS)) + list(range(REPLAY))
        cls.final = pathlib.Path(rospy.get_param("~final_trajectory"))
        for old in [*cls.final.parent.glob(cls.final.stem + "*"), *cls.final.parent.glob("asked/*")]:
            old.unlink()
        cls.stamps = [BASE + times[i] + (SHIFT if k >= FIRST_PASS else 0.0) for k, i in enumerate(frames)]
        cls.answers = {n: [] for n in NODES}
        cond = threading.Condition()

        def on_status(msg: TrackingStatus, node: str) -> None:
            with cond:
                cls.answers[node].append(msg)
                cond.notify_all()

        subs = [rospy.Subscriber(f"/{n}/tracking_state", TrackingStatus, on_status, n, queue_size=100) for n in NODES]
        pubs = {(n, side): rospy.Publisher(f"/{n}/{side}/image_rect", Image, queue_size=5)
                for n in NODES for side in ("left", "right")}
        pubs["labels", "labels"] = rospy.Publisher("/labels/semantic/labels", Image, queue_size=5)
        for n in NODES:
            rospy.wait_for_service(f"/{n}/dynaorb_node/stats", timeout=60)
        deadline = rospy.Time.now() + rospy.Duration(20)
        while any(p.get_num_connections() == 0 for p in pubs.values()):
            if rospy.Time.now() > deadline:
                raise RuntimeError("dynaorb_node did not subscribe to the image topics")
            rospy.sleep(0.1)
        for k, i in enumerate(frames):
            stamp = rospy.Time.from_sec(BASE + times[i] + (SHIFT if k >= FIRST_PASS else 0.0))
            left = mono8(seq / "image_0" / f"{i:06d}.png", stamp, "camera_left_optical_frame")
            right = mono8(seq / "image_1" / f"{i:06d}.png", stamp, "camera_left_optical_frame")
            for n in NODES:
                pubs[n, "left"].publish(left)
                pubs[n, "right"].publish(right)
            # The labels after their frame, as a segmentation server's come: the frame waits for them.
            rospy.sleep(0.05)
            pubs["labels", "labels"].publish(Image(header=left.header, height=left.height, width=left.width,
                                                   encoding="mono8", step=left.width,
                                                   data=bytes(left.width * left.height)))  # background only
            with cond:
                if not cond.wait_for(lambda: all(len(cls.answers[n]) > k for n in NODES), timeout=30):
                    raise RuntimeError(f"no answer on tracking_state for published frame {k} "
                                       f"({ {n: len(a) for n, a in cls.answers.items()} })")
        for s in subs:
            s.unregister()
        cls.stats = {n: json.loads(rospy.ServiceProxy(f"/{n}/dynaorb_node/stats", Trigger)().message)
                     for n in NODES}

    def test_first_pass_tracked_by_both(self):
        for n in NODES:
            first = self.answers[n][:FIRST_PASS]
            self.assertEqual([a.state for a in first], ["OK"] * FIRST_PASS, n)
            self.assertEqual(first[0].method, "init", n)

    def test_replay_starts_a_new_map(self):
        replay = self.answers["reset"][FIRST_PASS:]
        self.assertEqual(len(replay), REPLAY)
        self.assertEqual([a.rejected for a in replay], ["none"] * REPLAY)
        self.assertEqual([a.state for a in replay], ["OK"] * REPLAY)
        self.assertEqual(replay[0].method, "init")  # a new map from the first replayed frame
        self.assertTrue(all(a.method != "init" for a in replay[1:]))
        self.assertEqual(self.stats["reset"]["time_jumps"], 1)
        self.assertEqual(self.stats["reset"]["rejected"], 0)

    def test_labels_of_the_replay_are_used(self):
        answers = self.answers["labels"]
        self.assertEqual([a.state for a in answers], ["OK"] * (FIRST_PASS + REPLAY))
        self.assertEqual(answers[FIRST_PASS].method, "init")
        self.assertTrue(all(a.mask_used and a.label_age == 0.0 for a in answers), [a.label_age for a in answers])
        self.assertEqual(self.stats["labels"]["time_jumps"], 1)
        self.assertEqual(self.stats["labels"]["labels_missing"], 0)

    def test_each_pass_writes_its_trajectory(self):
        self.assertEqual(self.stats["reset"]["trajectory_passes"], 1)  # the first, written at the jump
        first = np.loadtxt(self.final, ndmin=2)
        np.testing.assert_allclose(first[:, 0], self.stamps[:FIRST_PASS], atol=1e-6)
        res = rospy.ServiceProxy("/reset/dynaorb_node/save_trajectory", MapFile)("")
        self.assertTrue(res.success, res.message)
        replay = np.loadtxt(self.final.with_name(self.final.stem + ".pass2.tum"), ndmin=2)
        np.testing.assert_allclose(replay[:, 0], self.stamps[FIRST_PASS:], atol=1e-6)
        np.testing.assert_allclose(replay[0, 1:], [0, 0, 0, 0, 0, 0, 1], atol=1e-9)  # a new map's world
        # KITTI 06 moves about 0.8 m a frame: the replay covers the first pass's first frames again.
        self.assertGreater(np.linalg.norm(first[REPLAY - 1, 1:4]), 5.0)
        np.testing.assert_allclose(replay[:, 1:4], first[:REPLAY, 1:4], atol=0.1)
        # A node without ~trajectory_file writes where it is asked to: its one map, the first pass's frames.
        save_off = rospy.ServiceProxy("/off/dynaorb_node/save_trajectory", MapFile)
        self.assertFalse(save_off("").success)  # no path, no ~trajectory_file
        asked = self.final.parent / "asked" / "final.tum"  # its folder made
        res = save_off(str(asked))
        self.assertTrue(res.success, res.message)
        np.testing.assert_allclose(np.loadtxt(asked, ndmin=2)[:, 0], self.stamps[:FIRST_PASS], atol=1e-6)

    def test_without_the_reset_the_replay_is_refused(self):
        replay = self.answers["off"][FIRST_PASS:]
        self.assertEqual(len(replay), REPLAY)
        self.assertEqual([a.rejected for a in replay], ["stamp_not_increasing"] * REPLAY)
        self.assertEqual(self.stats["off"]["time_jumps"], 0)
        self.assertEqual(self.stats["off"]["rejected"], REPLAY)


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "slam_time_jump", SlamTimeJumpTest, sys.argv)
