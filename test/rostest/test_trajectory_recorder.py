#!/usr/bin/env python3
"""rostest: odom published from ground truth plus known noise; the recorder's ATE must match it.

Then the first frames are published again with other noise (time going back,
as `rosbag play -l` does): the recorder with `~time_jump_reset` 1 s writes them
as a second pass, evaluated on its own; the one with 0 skips them.
"""
import json
import pathlib
import sys
import time
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger

N, REPLAY, SIGMA = 300, 100, 0.01


def aligned_rmse(gt_xyz, noise):
    """The position RMSE of gt + noise after the least-squares rigid (SE3) alignment onto gt
    (Umeyama without scale, as evo's ATE with SE3 alignment)."""
    est = gt_xyz + noise
    mu_e, mu_g = est.mean(axis=0), gt_xyz.mean(axis=0)
    u, _, vt = np.linalg.svd((gt_xyz - mu_g).T @ (est - mu_e))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    r = u @ d @ vt
    residual = gt_xyz - ((est - mu_e) @ r.T + mu_g)
    return float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))))


def odom(row, offset):
    msg = Odometry()
    msg.header.stamp = rospy.Time.from_sec(row[0])
    msg.header.frame_id = "map"
    p = row[1:4] + offset
    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = p
    o = msg.pose.pose.orientation
    o.x, o.y, o.z, o.w = row[4:8]
    return msg


class TrajectoryRecorderTest(unittest.TestCase):
    def report(self, service, done, deadline):
        rospy.wait_for_service(service, timeout=30)
        call = rospy.ServiceProxy(service, Trigger)
        report = {}
        while time.time() < deadline:
            report = json.loads(call().message)
            if done(report):
                break
            time.sleep(0.1)
        return report

    def test_records_and_reports(self):
        rospy.init_node("test_trajectory_recorder")
        gt = np.loadtxt(rospy.get_param("~ground_truth"), comments="#")[:N]
        rng = np.random.default_rng(0)
        noise = rng.normal(0.0, SIGMA, (N, 3))
        replay_noise = rng.normal(0.0, 2 * SIGMA, (REPLAY, 3))
        self.assertGreater(gt[N - 1, 0] - gt[0, 0], 2.0, "the replay must go back more than 1 s")
        pub = rospy.Publisher("odom", Odometry, queue_size=N + REPLAY)
        deadline = time.time() + 60
        while pub.get_num_connections() < 2 and time.time() < deadline:
            time.sleep(0.05)
        self.assertEqual(pub.get_num_connections(), 2, "the two recorders never subscribed")
        for k, row in enumerate(gt):
            pub.publish(odom(row, noise[k]))
            time.sleep(0.002)
        # A message a few stamps old is skipped and counted, not recorded.
        pub.publish(odom(gt[N - 3], np.zeros(3)))
        time.sleep(0.05)
        for k, row in enumerate(gt[:REPLAY]):
            pub.publish(odom(row, replay_noise[k]))
            time.sleep(0.002)

        report = self.report("/recorder/report", lambda r: len(r["passes"]) == 2 and
                             r["passes"][1]["poses"] >= REPLAY, deadline)
        self.assertEqual(report["poses"], N)
        self.assertEqual(report["out_of_order"], 1)
        self.assertEqual(report["matched_poses"], N)
        expected = aligned_rmse(gt[:, 1:4], noise)
        self.assertAlmostEqual(report["ate"]["rmse"], expected, delta=0.01 * expected)
        self.assertEqual(report["time_jumps"], 1)
        second = report["passes"][1]
        self.assertEqual(second["poses"], REPLAY)
        self.assertEqual(second["out_of_order"], 0)
        self.assertEqual(second["matched_poses"], REPLAY)
        expected = aligned_rmse(gt[:REPLAY, 1:4], replay_noise)
        self.assertAlmostEqual(second["ate"]["rmse"], expected, delta=0.01 * expected)
        self.assertTrue(second["output"].endswith("trajectory.pass2.tum"), second["output"])
        rows = np.loadtxt(second["output"], comments="#")
        np.testing.assert_allclose(rows[:, 0], gt[:REPLAY, 0], atol=1e-6)

        off = self.report("/recorder_off/report", lambda r: r["out_of_order"] >= 1 + REPLAY, deadline)
        self.assertEqual(off["poses"], N)
        self.assertEqual(off["out_of_order"], 1 + REPLAY)
        self.assertEqual(off["time_jumps"], 0)
        self.assertEqual(len(off["passes"]), 1)
        self.assertFalse(pathlib.Path(off["output"]).with_name("trajectory.pass2.tum").exists())


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "trajectory_recorder", TrajectoryRecorderTest, sys.argv)
