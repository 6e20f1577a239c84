#!/usr/bin/env python3
"""rostest: segmentation_server labels a real TUM frame through its service and its topic."""
import sys
import threading
import time
import unittest

import cv2
import numpy as np
import rospy
import rostest
from cv_bridge import CvBridge
from sensor_msgs.msg import CompressedImage, Image

from dynaorb.srv import Segment

PERSON = 15  # PASCAL VOC


class SegmentationServerTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_segmentation_server")
        cls.bridge = CvBridge()
        cls.image = cv2.imread(rospy.get_param("~image"))
        assert cls.image is not None

    def image_msg(self, stamp: float, encoding: str = "bgr8") -> Image:
        img = self.image if encoding == "bgr8" else cv2.cvtColor(self.image, cv2.COLOR_BGR2RGB)
        msg = self.bridge.cv2_to_imgmsg(img, encoding=encoding)
        msg.header.stamp = rospy.Time.from_sec(stamp)
        msg.header.frame_id = "camera_rgb_optical_frame"
        return msg

    def check_labels(self, labels: Image, stamp: float) -> None:
        self.assertEqual(labels.encoding, "mono8")
        self.assertEqual((labels.height, labels.width), self.image.shape[:2])
        self.assertAlmostEqual(labels.header.stamp.to_sec(), stamp, places=6)
        self.assertEqual(labels.header.frame_id, "camera_rgb_optical_frame")
        ids = self.bridge.imgmsg_to_cv2(labels)
        # Two people fill about a fifth of this frame.
        self.assertGreater(np.mean(ids == PERSON), 0.10)

    def test_service(self):
        rospy.wait_for_service("segment", timeout=60)
        segment = rospy.ServiceProxy("segment", Segment)
        for encoding in ("bgr8", "rgb8"):
            res = segment(self.image_msg(1341846313.592026, encoding))
            self.check_labels(res.labels, 1341846313.592026)
            self.assertEqual(len(res.class_names), 21)
            self.assertEqual(res.class_names[PERSON], "person")
            self.assertIn(PERSON, list(bytearray(res.movable_ids)))
        bad = Image(height=2, width=2, encoding="32FC1", step=8, data=bytes(16))
        with self.assertRaises(rospy.ServiceException):
            segment(bad)

    def labels_for(self, image_topic: str, msgtype, msg, labels_topic: str, first=None) -> list:
        """The labels the server publishes on labels_topic for msg, published (once a second
        until labels come, at most 60 s) on image_topic; `first` published once before it."""
        got = []
        done = threading.Event()

        def on_labels(labels):
            got.append(labels)
            done.set()

        rospy.Subscriber(labels_topic, Image, on_labels)
        pub = rospy.Publisher(image_topic, msgtype, queue_size=1)
        deadline = time.time() + 60
        while pub.get_num_connections() == 0 and time.time() < deadline:
            time.sleep(0.05)
        if first is not None:
            pub.publish(first)
        while not done.is_set() and time.time() < deadline:
            pub.publish(msg)
            done.wait(1.0)
        return got

    def test_topic(self):
        stamp = 1341846313.5
        got = self.labels_for("image", Image, self.image_msg(stamp), "labels")
        self.assertTrue(got, "no labels published")
        self.check_labels(got[0], stamp)

    def test_compressed_topic(self):
        # ~image_transport compressed: JPEG on /camera/rgb/image_color/compressed (the node's
        # image remapped to /camera/rgb/image_color); undecodable data is skipped, not fatal.
        junk = CompressedImage(format="jpeg", data=bytes(32))
        junk.header.stamp = rospy.Time.from_sec(1.0)
        stamp = 1341846313.6
        msg = CompressedImage(format="bgr8; jpeg compressed bgr8", data=cv2.imencode(".jpg", self.image)[1].tobytes())
        msg.header.stamp = rospy.Time.from_sec(stamp)
        msg.header.frame_id = "camera_rgb_optical_frame"
        got = self.labels_for("/camera/rgb/image_color/compressed", CompressedImage, msg, "/compressed/labels",
                              first=junk)
        self.assertTrue(got, "no labels published from the compressed topic")
        self.check_labels(got[0], stamp)

    def test_runs_below_the_slam_nodes_priority(self):
        # ~nice (default 10): every thread of the server, the network's included,
        # 10 steps below the processes roslaunch started beside it (this test's).
        import os
        import xmlrpc.client

        import rosgraph

        rospy.wait_for_service("segment", timeout=60)   # the network is loaded, its threads started
        uri = rosgraph.Master(rospy.get_name()).lookupNode("/segmentation_server")
        code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/test_segmentation_server")
        self.assertEqual(code, 1)
        nices = []
        for tid in os.listdir(f"/proc/{pid}/task"):
            try:
                with open(f"/proc/{pid}/task/{tid}/stat") as f:
                    nices.append(int(f.read().rsplit(") ", 1)[1].split()[16]))
            except FileNotFoundError:  # a connection's thread that ended meanwhile
                pass
        ours = os.getpriority(os.PRIO_PROCESS, 0)
        self.assertTrue(nices and all(n == min(19, ours + 10) for n in nices), (ours, nices))


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "segmentation_server_test", SegmentationServerTest, sys.argv)
