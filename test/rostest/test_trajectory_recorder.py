#!/usr/bin/env python3
"""rostest: odom published from ground truth plus known noise; the recorder's ATE must match it."""
import json
import sys
import time
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger

N, SIGMA = 300, 0.01


class TrajectoryRecorderTest(unittest.TestCase):
    def test_records_and_reports(self):
        rospy.init_node("test_trajectory_recorder")
        gt = np.loadtxt(rospy.get_param("~ground_truth"), comments="#")[:N]
        noise = np.random.default_rng(0).normal(0.0, SIGMA, (N, 3))
        expected = float(np.sqrt(np.mean(np.sum(noise ** 2, axis=1))))
        pub = rospy.Publisher("odom", Odometry, queue_size=N)
        deadline = time.time() + 30
        while pub.get_num_connections() == 0 and time.time() < deadline:
            time.sleep(0.05)
        self.assertGreater(pub.get_num_connections(), 0, "recorder never subscribed")
        for k, row in enumerate(gt):
            msg = Odometry()
            msg.header.stamp = rospy.Time.from_sec(row[0])
            msg.header.frame_id = "map"
            p = row[1:4] + noise[k]
            msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = p
            o = msg.pose.pose.orientation
            o.x, o.y, o.z, o.w = row[4:8]
            pub.publish(msg)
            time.sleep(0.002)
        # A stale message is skipped and counted, not recorded.
        stale = Odometry()
        stale.header.stamp = rospy.Time.from_sec(gt[0, 0])
        stale.pose.pose.orientation.w = 1.0
        pub.publish(stale)
        rospy.wait_for_service("/recorder/report", timeout=30)
        report_srv = rospy.ServiceProxy("/recorder/report", Trigger)
        report = {}
        while time.time() < deadline:
            report = json.loads(report_srv().message)
            if report["poses"] >= N and report.get("out_of_order", 0) >= 1:
                break
            time.sleep(0.1)
        self.assertEqual(report["poses"], N)
        self.assertEqual(report["out_of_order"], 1)
        self.assertEqual(report["matched_poses"], N)
        self.assertAlmostEqual(report["ate"]["rmse"], expected, delta=0.02 * expected)


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "trajectory_recorder", TrajectoryRecorderTest, sys.argv)
