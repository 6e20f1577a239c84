#!/usr/bin/env python3
"""rostest: dynaorb_octomap when time goes back.

A wall of points 2 m ahead of the sensor (x > 0) stamped 100 s, then one 2 m behind it
(x < 0) stamped 50 s, to two octomap nodes: the one with ~time_jump_reset (default 1 s)
starts its map again at the second cloud (only the wall behind is occupied), the one with
0 adds it to the first (both walls).
"""
import sys
import threading
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import TransformStamped
from sensor_msgs import point_cloud2
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header

NODES = ("reset", "off")


def wall(x: float) -> list:
    """A 1 x 1 m wall of points at distance x along the sensor frame's x axis."""
    return [(x, y, z) for y in np.arange(-0.5, 0.5, 0.05) for z in np.arange(-0.5, 0.5, 0.05)]


class OctomapTimeJumpTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_octomap_time_jump")
        static = tf2_ros.StaticTransformBroadcaster()
        t = TransformStamped()
        t.header.stamp = rospy.Time.now()
        t.header.frame_id, t.child_frame_id = "map", "sensor"
        t.transform.rotation.w = 1.0
        static.sendTransform(t)
        cls.centres = {n: [] for n in NODES}
        cond = threading.Condition()

        def on_centres(msg: PointCloud2, node: str) -> None:
            pts = np.array(list(point_cloud2.read_points(msg, field_names=("x", "y", "z"))), float).reshape(-1, 3)
            with cond:
                cls.centres[node].append(pts)
                cond.notify_all()

        subs = [rospy.Subscriber(f"/{n}/octomap_point_cloud_centers", PointCloud2, on_centres, n) for n in NODES]
        pubs = {n: rospy.Publisher(f"/{n}/cloud_in", PointCloud2, queue_size=5) for n in NODES}
        deadline = rospy.Time.now() + rospy.Duration(20)
        while any(p.get_num_connections() == 0 for p in pubs.values()):
            if rospy.Time.now() > deadline:
                raise RuntimeError("dynaorb_octomap did not subscribe to cloud_in")
            rospy.sleep(0.1)
        rospy.sleep(0.5)  # the latched centres of the empty maps, if any, first
        for k, (stamp, x) in enumerate(((100.0, 2.0), (50.0, -2.0))):
            with cond:
                seen = {n: len(cls.centres[n]) for n in NODES}
            header = Header(stamp=rospy.Time.from_sec(stamp), frame_id="sensor")
            for n in NODES:
                pubs[n].publish(point_cloud2.create_cloud_xyz32(header, wall(x)))
            with cond:
                if not cond.wait_for(lambda: all(len(cls.centres[n]) > seen[n] for n in NODES), timeout=20):
                    raise RuntimeError(f"no map published after cloud {k}")
        for s in subs:
            s.unregister()

    def test_time_going_back_resets_the_map(self):
        last = self.centres["reset"][-1]
        self.assertGreater(len(last), 50)
        self.assertTrue(np.all(last[:, 0] < 0), "the wall of the time before is still in the map")

    def test_without_the_reset_both_walls_stay(self):
        last = self.centres["off"][-1]
        self.assertGreater(int(np.sum(last[:, 0] > 1.5)), 50)
        self.assertGreater(int(np.sum(last[:, 0] < -1.5)), 50)


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "octomap_time_jump", OctomapTimeJumpTest, sys.argv)
