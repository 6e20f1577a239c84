#!/usr/bin/env python3
"""rostest: dynaorb_node (and dynaorb_octomap) refuse bad parameters at start-up,
naming the parameter, before they load a vocabulary or subscribe to anything."""
import itertools
import subprocess
import sys
import unittest

import roslib.packages
import rospy
import rostest

# parameter -> (bad value, what the error says)
REFUSED = {
    "max_label_age": ("-0.5", "~max_label_age must be a finite number of seconds >= 0"),
    "label_wait_timeout": ("-1.0", "~label_wait_timeout must be a finite number of seconds >= 0"),
    "first_labels_timeout": ("-2.0", "~first_labels_timeout must be a finite number of seconds >= 0"),
    "max_frames_waiting": ("0", "~max_frames_waiting must be >= 1"),
    "label_flow_scale": ("1.5", "~label_flow_scale must be in (0, 1]"),
    "queue_size": ("0", "~queue_size must be >= 1"),
    "time_jump_reset": ("-1.0", "~time_jump_reset must be a finite number of seconds >= 0"),
    "image_transport": ("theora", "~image_transport must be 'raw' or 'compressed', got 'theora'"),
    "trajectory_file": ("/proc/dynaorb/final.tum", "~trajectory_file: cannot make its folder /proc/dynaorb"),
    # The core's options (~tracker/, ~mapping/, ~loop/), checked by their own validate().
    "tracker/min_pose_inliers": ("-1", "tracker option 'min_pose_inliers' is -1"),
    "tracker/reloc/pnp/probability": ("1.5", "tracker option 'reloc.pnp.probability' is 1.5"),
    "mapping/neighbors_stereo": ("0", "local mapping option 'neighbors_stereo' is 0"),
    "loop/ransac/chi2": ("-2.0", "loop closing option 'ransac.chi2' is -2"),
}


class SlamNodeParamsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_slam_node_params")
        cls.settings = rospy.get_param("~settings")
        found = roslib.packages.find_node("dynaorb", "dynaorb_node")  # as roslaunch finds it
        assert found, "dynaorb_node not built"
        cls.node = found[0]
        cls.octomap = roslib.packages.find_node("dynaorb", "dynaorb_octomap")[0]
        cls.runs = itertools.count()

    def run_node(self, name: str, extra: list[str], params: dict | None = None,
                 octomap: bool = False) -> subprocess.CompletedProcess:
        # `_key:=value` sets ~key on the master, where it outlives the node:
        # one name per run, so no run sees another's values.
        name = f"{name}_{next(self.runs)}"
        for key, value in (params or {}).items():
            rospy.set_param(f"/{name}/{key}", value)
        if octomap:
            cmd = [self.octomap, f"__name:={name}", *extra]
        else:
            cmd = [self.node, f"__name:={name}", "_sensor:=stereo", f"_settings:={self.settings}",
                   "_vocabulary:=none", *extra]
        try:
            return subprocess.run(cmd, capture_output=True, text=True, timeout=20)
        except subprocess.TimeoutExpired:
            self.fail(f"{' '.join(cmd)} did not stop within 20 s: the parameter was accepted")

    def assert_refused(self, done: subprocess.CompletedProcess, message: str) -> None:
        """The node stopped at start-up (exit 1) with `message` in its output."""
        self.assertEqual(done.returncode, 1, (message, done.stdout[-500:], done.stderr[-500:]))
        self.assertIn(message, done.stdout + done.stderr)

    def test_movable_ids_must_be_label_ids(self):
        self.assert_refused(self.run_node("refuse_ids", [], {"movable_ids": [15, -1]}),
                            "~movable_ids: -1 is not a label id (0-65535)")

    def test_bad_values_refused_naming_the_parameter(self):
        for key, (value, message) in REFUSED.items():
            with self.subTest(key=key):
                name = key.replace("/", "_")  # node names hold no slash
                self.assert_refused(self.run_node(f"refuse_{name}", [f"_{key}:={value}"]), message)

    def test_wrong_types_refused_not_replaced_by_defaults(self):
        self.assert_refused(self.run_node("refuse_nan", [], {"max_label_age": float("nan")}),
                            "~max_label_age must be a finite number")
        for arg, message in (("_max_label_age:=soon", "~max_label_age must be a number"),
                             ("_queue_size:=ten", "~queue_size must be an integer"),
                             ("_queue_size:=10.5", "~queue_size must be an integer"),  # not rounded
                             ("_use_labels:=1", "~use_labels must be true or false"),
                             ("_movable_ids:=person", "~movable_ids must be a list of integers"),
                             ("_Camera/fx:=wide", "~Camera/fx must be a number"),
                             ("_camera_rpy:=up", "~camera_rpy must be a list of numbers")):
            with self.subTest(arg=arg):
                self.assert_refused(self.run_node("refuse_type", [arg]), message)

    def test_core_options_by_name(self):
        # A misspelt or misplaced option is refused, naming it, not ignored.
        for arg, message in (("_mapping/neighbours_stereo:=20", "~mapping/neighbours_stereo is not a local mapping option"),
                             ("_loop/chi2:=5.0", "~loop/chi2 is not a loop closing option"),
                             ("_tracker/reloc/pnp:=3", "~tracker/reloc/pnp is not a tracker option"),
                             ("_mapping/local_ba:=1", "~mapping/local_ba must be true or false"),
                             ("_tracker/min_pose_inliers:=12.5", "~tracker/min_pose_inliers must be an integer"),
                             ("_tracker/reloc/pnp/seed:=-3", "~tracker/reloc/pnp/seed must be an integer >= 0")):
            with self.subTest(arg=arg):
                self.assert_refused(self.run_node("refuse_option", [arg]), message)
        # Good values are taken and logged at start-up (the bad queue size
        # read after them stops the node there).
        done = self.run_node("options_set", ["_queue_size:=0"],
                             {"tracker/min_pose_inliers": 15, "mapping": {"local_ba": False},
                              "loop": {"ransac": {"chi2": 8.5}}})
        self.assert_refused(done, "~queue_size must be >= 1")
        out = done.stdout + done.stderr
        for line in ("~tracker options set: min_pose_inliers=15", "~mapping options set: local_ba=false",
                     "~loop options set: ransac/chi2=8.5"):
            self.assertIn(line, out)

    def test_camera_offset_needs_three_finite_numbers(self):
        for key, value in (("camera_xyz", [0.1, 0.0]), ("camera_rpy", [0.0, float("nan"), 0.0]),
                           ("camera_xyz", [0.0, float("inf"), 0.0])):
            with self.subTest(key=key, value=value):
                self.assert_refused(self.run_node("refuse_triple", [], {key: value}),
                                    f"~{key} must hold 3 finite numbers")

    def test_octomap_wrong_types_refused(self):
        # roslaunch reads value="-1e9" as the string "-1e9" (no '.'): refused, not ignored.
        for key, value, message in (("resolution", "fine", "~resolution must be a number"),
                                    ("pointcloud_min_z", "-1e9", "~pointcloud_min_z must be a number"),
                                    ("latch", 1, "~latch must be true or false"),
                                    ("time_jump_reset", -1.0,
                                     "~time_jump_reset must be a finite number of seconds >= 0")):
            with self.subTest(key=key):
                self.assert_refused(self.run_node("refuse_octomap", [], {key: value}, octomap=True), message)


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "slam_node_params", SlamNodeParamsTest, sys.argv)
