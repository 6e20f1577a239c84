#!/usr/bin/env python3
"""rostest: dynaorb_node (+ dynaorb_octomap, trajectory_recorder) on a bag made from a sequence.

The bag is written at the start (`dynaorb bag from-dataset`, cached under
$ROS_HOME/dynaorb_rostest), from ../shared/data or from a synthetic sequence
rendered here, and played with `rosbag play --clock`. Checks: every frame
answered on tracking_state; Odometry for each tracked frame, stamped with
the image stamp, map -> base_link; TF map -> odom -> base_link resolves at
those stamps and agrees with the Odometry; keyframe clouds in the camera
frame at keyframe stamps within the maximum depth; the trajectory recorder's
ATE against the bag's ground truth within the bound; an occupancy map from
the octomap node; the labels seen as expected (segmentation server up, labels
from the bag, none, or a publisher that never publishes: the first map waits
~first_labels_timeout for it, then the frames are tracked without labels). With a synthetic sequence: no occupied voxel of the
map built from the dynamic-free clouds lies on a mover's path, while the map
built from the unfiltered clouds has some (checked against synth.json).

Parameters (private): kind (tum | kitti), source (dataset folder) or synth
(render one: synth_movers, synth_frames), bag, ate_max, min_tracked_fraction,
camera_frame, max_depth, labels (server | bag | none | silent), labels_topic (silent),
play_labels (bool),
mover_check (bool), octomap_resolution.
"""
import fcntl
import json
import os
import pathlib
import subprocess
import sys
import threading
import time
import unittest

import numpy as np
import rosgraph
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import Point
from nav_msgs.msg import OccupancyGrid, Odometry
from sensor_msgs import point_cloud2
from sensor_msgs.msg import Image, PointCloud2
from std_srvs.srv import Empty, SetBool, Trigger

from dynaorb.msg import TrackingStatus
from dynaorb.srv import ClearBBX, MapFile


def prepare_bag(kind: str, source: str, bag: pathlib.Path, synth: bool, movers: int, frames: int) -> None:
    """Writes the bag (and its sidecars) unless a complete one is cached. Tests running in
    parallel share a bag: the first writes it under a lock, the others wait and reuse it."""
    with open(bag.with_name(bag.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        _prepare_bag_locked(kind, source, bag, synth, movers, frames)


def _prepare_bag_locked(kind: str, source: str, bag: pathlib.Path, synth: bool, movers: int, frames: int) -> None:
    done = bag.with_name(bag.name + ".done")
    recipe = json.dumps({"kind": kind, "source": source, "synth": synth, "movers": movers, "frames": frames,
                         "version": 1})
    if bag.is_file() and done.is_file() and done.read_text() == recipe:
        return
    from dynaorb.ros.bag import BagWriteOptions, write_dataset_bag

    labels = None
    if synth:
        from dynaorb.synth.generate import SynthConfig, generate

        generate(source, SynthConfig(sensor="rgbd" if kind == "tum" else "stereo", movers=movers, frames=frames))
        sequence = synth_sequence(kind, source)
        labels = str(sequence / "labels")
        source = str(sequence)
    write_dataset_bag(BagWriteOptions(kind=kind, path=source, out=str(bag), labels=labels))
    done.write_text(recipe)


def synth_sequence(kind: str, source: str) -> pathlib.Path:
    """The frames of a `dynaorb synth` folder: TUM layout at its root, KITTI layout in sequences/00."""
    return pathlib.Path(source) if kind == "tum" else pathlib.Path(source) / "sequences" / "00"


def synth_ground_truth(kind: str, source: str) -> np.ndarray:
    """(N, 4, 4) ground-truth poses of a `dynaorb synth` folder (the first camera at the origin)."""
    if kind == "tum":
        from dynaorb.evaluation import load_trajectory

        return load_trajectory(pathlib.Path(source) / "groundtruth.txt").poses_se3
    rows = np.loadtxt(pathlib.Path(source) / "poses" / "00.txt").reshape(-1, 3, 4)
    return np.array([np.vstack([r, [0, 0, 0, 1]]) for r in rows])


def quaternion_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def transform_matrix(t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = quaternion_matrix((t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w))
    T[:3, 3] = (t.translation.x, t.translation.y, t.translation.z)
    return T


def cloud_xyz(msg: PointCloud2) -> np.ndarray:
    return np.array(list(point_cloud2.read_points(msg, field_names=("x", "y", "z"))), dtype=float).reshape(-1, 3)


class SlamNodeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_slam_node")
        p = lambda name, default=None: rospy.get_param("~" + name, default)  # noqa: E731
        cls.kind = p("kind")
        cache = pathlib.Path(os.environ.get("ROS_HOME", pathlib.Path.home() / ".ros")) / "dynaorb_rostest"
        cache.mkdir(parents=True, exist_ok=True)
        cls.synth = bool(p("synth", False))
        cls.source = str(cache / p("synth_name", "synth")) if cls.synth else p("source")
        cls.bag = cache / p("bag")
        t0 = time.time()
        prepare_bag(cls.kind, cls.source, cls.bag, cls.synth, int(p("synth_movers", 2)), int(p("synth_frames", 45)))
        cls.prepare_s = time.time() - t0
        cls.camera_frame = p("camera_frame")
        cls.max_depth = float(p("max_depth"))
        cls.labels_mode = p("labels", "none")
        cls.lock = threading.Lock()
        cls.status, cls.odom, cls.clouds, cls.octomaps, cls.grids = [], [], [], {}, {}
        cls.tf = tf2_ros.Buffer(cache_time=rospy.Duration(600))
        cls.tf_listener = tf2_ros.TransformListener(cls.tf)
        rospy.Subscriber("/tracking_state", TrackingStatus, lambda m: cls._add(cls.status, m), queue_size=1000)
        rospy.Subscriber("/odom", Odometry, lambda m: cls._add(cls.odom, m), queue_size=1000)
        rospy.Subscriber("/cloud", PointCloud2, lambda m: cls._add(cls.clouds, m), queue_size=100,
                         buff_size=1 << 26)
        rospy.Subscriber("/map_points", PointCloud2, lambda m: cls._add(cls.map_points, m), queue_size=100,
                         buff_size=1 << 24)
        cls.map_points = []
        cls.masks = []  # (stamp, fraction of masked pixels)
        rospy.Subscriber("/dynamic_mask", Image, lambda m: cls._add(cls.masks, (m.header.stamp, m.encoding, np.mean(
            np.frombuffer(m.data, np.uint8) > 0))), queue_size=1000, buff_size=1 << 26)
        for ns in ("", "/raw"):
            rospy.Subscriber(ns + "/octomap_point_cloud_centers", PointCloud2,
                             lambda m, ns=ns: cls.octomaps.__setitem__(ns, m), queue_size=1, buff_size=1 << 26)
            rospy.Subscriber(ns + "/projected_map", OccupancyGrid, lambda m, ns=ns: cls.grids.__setitem__(ns, m),
                             queue_size=1, buff_size=1 << 24)

        from rosbags.rosbag1 import Reader

        with Reader(cls.bag) as reader:
            cls.bag_topics = {c.topic: c.msgcount for c in reader.connections}
        image_topic = "/camera/rgb/image_color" if cls.kind == "tum" else "/camera/left/image_rect"
        cls.frames = cls.bag_topics[image_topic]
        play = [t for t in cls.bag_topics if p("play_labels", True) or not t.endswith("/labels")]
        cls._wait_for_subscriber(image_topic, 90.0)
        # Only topics somebody reads, and only once each reader is connected
        # (--wait-for-subscribers): a fixed delay lost the first frame on a loaded machine.
        play = cls._subscribed_topics(play, settle=1.0)
        if cls.labels_mode == "silent":  # a labels publisher the node is connected to, that never publishes
            cls.silent = rospy.Publisher(p("labels_topic"), Image, queue_size=1)
            deadline = time.time() + 30.0
            while cls.silent.get_num_connections() == 0 and time.time() < deadline:
                time.sleep(0.1)
        if cls.labels_mode == "server" and p("wait_server", True):  # its model loaded (it sets ~movable_ids then)
            deadline = time.time() + 90.0
            while not rospy.has_param("/segmentation_server/movable_ids") and time.time() < deadline:
                time.sleep(0.2)
        t0 = time.time()
        subprocess.run(["rosbag", "play", "--clock", "-q", "-d", "1", "--wait-for-subscribers", str(cls.bag),
                        "--topics", *play],
                       check=True, stdout=subprocess.DEVNULL, timeout=300)
        cls.play_s = time.time() - t0
        # Frames still queued in the node, then the octomap's last cloud.
        cls._wait_quiet(lambda: len(cls.status) >= cls.frames, 10.0, 120.0)
        cls._wait_quiet(lambda: cls._octomap_caught_up(), 5.0, 60.0)
        cls.process_s = time.time() - t0
        rospy.wait_for_service("/recorder/report", timeout=30)
        cls.report = json.loads(rospy.ServiceProxy("/recorder/report", Trigger)().message)
        rospy.wait_for_service("/dynaorb/stats", timeout=30)
        cls.stats = json.loads(rospy.ServiceProxy("/dynaorb/stats", Trigger)().message)
        rospy.loginfo("test_slam_node: bag %.1f s to prepare, played in %.1f s, processed in %.1f s; "
                      "ATE %s; node stats %s", cls.prepare_s, cls.play_s, cls.process_s,
                      cls.report.get("ate", {}).get("rmse"), cls.stats)

    @classmethod
    def _add(cls, store, msg):
        with cls.lock:
            store.append(msg)

    @classmethod
    def _octomap_caught_up(cls) -> bool:
        if not cls.clouds:
            return True
        last = cls.clouds[-1].header.stamp
        return "" in cls.octomaps and cls.octomaps[""].header.stamp >= last

    @staticmethod
    def _wait_for_subscriber(topic: str, timeout: float) -> None:
        master = rosgraph.Master(rospy.get_name())
        deadline = time.time() + timeout
        while time.time() < deadline:
            _, subscribers, _ = master.getSystemState()
            for name, nodes in subscribers:
                if name == topic and "/dynaorb" in nodes:
                    return
            time.sleep(0.2)
        raise AssertionError(f"dynaorb_node never subscribed to {topic}")

    @staticmethod
    def _subscribed_topics(topics, settle: float):
        """Those of `topics` with a subscriber, once that set has not changed for `settle` s."""
        master = rosgraph.Master(rospy.get_name())
        last, since = None, time.time()
        while True:
            _, subscribers, _ = master.getSystemState()
            now = sorted(t for t in topics if any(name == t for name, _ in subscribers))
            if now != last:
                last, since = now, time.time()
            elif time.time() - since >= settle:
                return now
            time.sleep(0.1)

    @classmethod
    def _wait_quiet(cls, done, quiet: float, timeout: float) -> None:
        """Until done() or nothing new on tracking_state for `quiet` s (wall clock)."""
        deadline = time.time() + timeout
        last_count, last_change = -1, time.time()
        while time.time() < deadline and not done():
            count = len(cls.status) + len(cls.clouds)
            if count != last_count:
                last_count, last_change = count, time.time()
            elif time.time() - last_change > quiet:
                return
            time.sleep(0.1)

    def skipped(self) -> list:
        """The tracking_state answers of frames skipped while the first map
        waited for the first labels (~first_labels_timeout): the system never saw them."""
        return [s for s in self.status if s.rejected == "waiting_for_labels"]

    def seen_frames(self) -> int:
        """Frames given to the system: all but the skipped ones."""
        return self.frames - len(self.skipped())

    # ------------------------------------------------------------------ checks
    def test_every_frame_answered_and_tracked(self):
        self.assertEqual(len(self.status), self.frames, "one tracking_state per frame")
        # Frames answered as skipped while the first map waited for the first
        # labels (~first_labels_timeout): only those, and only with a server.
        skipped = len(self.skipped())
        self.assertEqual(skipped, self.stats["skipped_before_labels"])
        self.assertLessEqual(skipped, int(rospy.get_param("~max_skipped", 0)))
        self.assertEqual(sum(s.rejected not in ("none", "waiting_for_labels") for s in self.status), 0)
        ok = sum(s.state == "OK" for s in self.status)
        self.assertGreaterEqual(ok / self.seen_frames(), float(rospy.get_param("~min_tracked_fraction", 0.95)))

    def test_odometry_stamped_with_the_images(self):
        image_stamps = {s.header.stamp for s in self.status}
        ok_stamps = [s.header.stamp for s in self.status if s.state == "OK"]
        self.assertEqual([o.header.stamp for o in self.odom], ok_stamps)
        for o in self.odom:
            self.assertIn(o.header.stamp, image_stamps)
            self.assertEqual(o.header.frame_id, "map")
            self.assertEqual(o.child_frame_id, "base_link")
        stamps = [o.header.stamp.to_sec() for o in self.odom]
        self.assertTrue(all(b > a for a, b in zip(stamps, stamps[1:])))

    def test_tf_tree_resolves_at_the_odometry_stamps(self):
        for o in self.odom:
            t = self.tf.lookup_transform("map", "base_link", o.header.stamp, rospy.Duration(1.0))
            p = o.pose.pose.position
            self.assertAlmostEqual(t.transform.translation.x, p.x, places=5)
            self.assertAlmostEqual(t.transform.translation.y, p.y, places=5)
            self.assertAlmostEqual(t.transform.translation.z, p.z, places=5)
            self.tf.lookup_transform("map", "odom", o.header.stamp, rospy.Duration(1.0))
            self.tf.lookup_transform("odom", "base_link", o.header.stamp, rospy.Duration(1.0))
        # base_link -> camera: the REP-103 body <- optical rotation (camera z forward = base x).
        T = transform_matrix(self.tf.lookup_transform("base_link", self.camera_frame, rospy.Time(0),
                                                      rospy.Duration(1.0)).transform)
        np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-6)
        np.testing.assert_allclose(T[:3, 1], [0, 0, -1], atol=1e-6)
        # The robot moves forward: along map x, not along the optical z.
        last = self.odom[-1].pose.pose.position
        self.assertGreater(last.x, 5 * max(abs(last.z), 0.05))

    def test_keyframe_clouds(self):
        self.assertGreater(len(self.clouds), 0)
        keyframe_stamps = {s.header.stamp for s in self.status if s.new_keyframe}
        for c in self.clouds:
            self.assertEqual(c.header.frame_id, self.camera_frame)
            self.assertIn(c.header.stamp, keyframe_stamps)
            xyz = cloud_xyz(c)
            self.assertGreater(len(xyz), 1000)
            self.assertTrue(np.all(np.isfinite(xyz)))
            self.assertTrue(np.all(xyz[:, 2] > 0) and np.all(xyz[:, 2] <= self.max_depth + 1e-4))

    def test_map_points_per_keyframe(self):
        keyframe_stamps = [s.header.stamp for s in self.status if s.new_keyframe]
        self.assertEqual([m.header.stamp for m in self.map_points], keyframe_stamps)
        last = self.map_points[-1]
        self.assertEqual(last.header.frame_id, "map")
        self.assertEqual(last.width, self.stats["map_points"])
        xyz = cloud_xyz(last)
        self.assertTrue(np.all(np.isfinite(xyz)))

    def test_trajectory_matches_ground_truth(self):
        self.assertIn("ate", self.report, self.report)
        self.assertGreaterEqual(self.report["matched_poses"], 0.95 * self.seen_frames())
        self.assertLessEqual(self.report["ate"]["rmse"], float(rospy.get_param("~ate_max")))

    def test_octomap_produces_a_map(self):
        self.assertIn("", self.octomaps)
        centres = self.octomaps[""]
        self.assertEqual(centres.header.frame_id, "map")
        self.assertGreater(centres.width, 500)
        grid = self.grids[""]
        data = np.asarray(grid.data)
        self.assertEqual(len(data), grid.info.width * grid.info.height)
        self.assertGreater(np.count_nonzero(data == 100), 20)
        self.assertGreater(np.count_nonzero(data == 0), 20)

    def test_labels(self):
        if self.labels_mode == "server":
            self.assertGreater(self.stats["labels_in"], 0, "segmentation_server published no labels")
            self.assertGreater(self.stats["labels_used"], 0)
            # The first map waited for the server's first labels (~first_labels_timeout).
            self.assertEqual(self.stats["first_labels_timed_out"], 0)
            first = next(s for s in self.status if s.rejected == "none")
            self.assertTrue(first.mask_used, "the first map was built from a frame without labels")
            skipped = self.skipped()
            self.assertEqual(len(skipped), self.stats["skipped_before_labels"])
            self.assertTrue(all(k.header.stamp < first.header.stamp for k in skipped))
            # The network lags the camera: frames take older labels moved onto them by optical flow
            # (~propagate_labels), never labels from beyond ~max_label_age.
            self.assertGreater(self.stats["labels_propagated"], 0)
            self.assertGreater(self.stats["label_propagation_ms_total"], 0)
            # The classes in use are those the server announced for its model.
            self.assertEqual(self.stats["movable_classes"], rospy.get_param("/segmentation_server/movable_ids"))
            ages = [s.label_age for s in self.status if s.mask_used]
            self.assertTrue(all(-0.5 <= a <= 0.5 for a in ages), ages)
        elif self.labels_mode == "bag":
            self.assertEqual(self.stats["labels_used"], self.frames)
            self.assertTrue(all(s.mask_used for s in self.status))
        else:
            self.assertEqual(self.stats["labels_in"], 0)
            self.assertFalse(any(s.mask_used for s in self.status))
            self.assertEqual(self.stats["skipped_before_labels"], 0)
            # silent: the wait ended once, on ~first_labels_timeout; none: nobody to wait for.
            self.assertEqual(self.stats["first_labels_timed_out"], int(self.labels_mode == "silent"))

    def test_dynamic_counters(self):
        # The core's degradations reach ~stats. No stage fails on these clips,
        # and their 640x480 first frames start the map without their movers.
        for key in ("dynamic_all_frames", "dynamic_stage_failures", "unchecked_kept"):
            self.assertIn(key, self.stats)
        self.assertEqual(self.stats["dynamic_stage_failures"], 0)
        self.assertEqual(self.stats["unchecked_kept"], 0)

    def test_inpainted_clouds(self):
        if not rospy.get_param("~inpainted_clouds", False):
            return
        # With a dynamic preset and ~cloud/inpaint, keyframe clouds after the
        # first keyframe come from DDL-SLAM's background inpainting.
        self.assertGreater(self.stats["inpainted_clouds"], 0)

    def test_dynamic_mask_per_frame(self):
        # One per frame the system saw (not those skipped before the first labels).
        skipped = {s.header.stamp for s in self.skipped()}
        self.assertEqual([s for s, _, _ in self.masks],
                         [s.header.stamp for s in self.status if s.header.stamp not in skipped])
        self.assertTrue(all(e == "mono8" for _, e, _ in self.masks))
        masked = np.array([f for _, _, f in self.masks])
        if self.labels_mode == "bag":  # the synthetic movers cover about a third of the image
            self.assertGreater(masked.mean(), 0.1)
        elif self.labels_mode in ("none", "silent"):
            self.assertEqual(masked.max(), 0.0)

    def test_zz_services(self):
        """Last (alphabetical order): the services change the node's state."""
        folder = pathlib.Path(os.environ.get("ROS_HOME", "/tmp")) / "dynaorb_rostest" / rospy.get_name().strip("/")
        folder.mkdir(parents=True, exist_ok=True)
        final = rospy.get_param("~final_trajectory", "")
        if final:  # ~trajectory_file: the final trajectory now, then a new pass after ~reset
            self._check_final_trajectory(pathlib.Path(final))
        res = rospy.ServiceProxy("/dynaorb/save_map", MapFile)(str(folder / "slam.map"))
        self.assertTrue(res.success, res.message)
        self.assertTrue((folder / "slam.map").is_file())
        self.assertTrue(rospy.ServiceProxy("/dynaorb/set_localization_mode", SetBool)(True).success)
        self.assertTrue(rospy.ServiceProxy("/dynaorb/reset", Trigger)().success)
        res = rospy.ServiceProxy("/dynaorb/load_map", MapFile)(str(folder / "slam.map"))
        self.assertTrue(res.success, res.message)
        bad = rospy.ServiceProxy("/dynaorb/load_map", MapFile)(str(folder / "missing.map"))
        self.assertFalse(bad.success)
        for ext in ("bt", "ot"):
            res = rospy.ServiceProxy("/octomap/save", MapFile)(str(folder / f"octomap.{ext}"))
            self.assertTrue(res.success, res.message)
            self.assertGreater((folder / f"octomap.{ext}").stat().st_size, 100)
        self.assertFalse(rospy.ServiceProxy("/octomap/save", MapFile)(str(folder / "octomap.txt")).success)
        cleared = rospy.ServiceProxy("/octomap/clear_bbx", ClearBBX)
        big = cleared(min=Point(-1e3, -1e3, -1e3), max=Point(1e3, 1e3, 1e3))
        self.assertGreater(big.cleared, 0)
        rospy.ServiceProxy("/octomap/reset", Empty)()

    def _check_final_trajectory(self, final: pathlib.Path):
        for f in final.parent.glob(final.stem + "*"):
            f.unlink()
        save = rospy.ServiceProxy("/dynaorb/save_trajectory", MapFile)
        res = save("")  # to ~trajectory_file
        self.assertTrue(res.success, res.message)
        from dynaorb.evaluation import evaluate

        rows = np.loadtxt(final, ndmin=2)
        self.assertEqual(len(rows), self.stats["tracked"], "one pose per tracked frame")
        gt = self.bag.with_name(self.bag.stem + ".groundtruth.tum")
        result = evaluate(str(gt), str(final), align="se3")
        # The loop-closed, bundle-adjusted trajectory: within the bound the recorder's odometry meets.
        self.assertLessEqual(result.ate["rmse"], float(rospy.get_param("~ate_max")))
        # ~reset ends the pass (written again), the next goes to FILE-stem.pass2.tum: nothing tracked there yet.
        self.assertTrue(rospy.ServiceProxy("/dynaorb/reset", Trigger)().success)
        res = save("")
        self.assertFalse(res.success)
        self.assertIn("pass2", res.message)
        self.assertEqual(len(np.loadtxt(final, ndmin=2)), len(rows))
        stats = json.loads(rospy.ServiceProxy("/dynaorb/stats", Trigger)().message)
        self.assertEqual(stats["trajectory_passes"], 1)
        self.assertEqual(stats["trajectory_write_failures"], 0)

    def test_no_occupied_voxels_on_the_movers_paths(self):
        if not rospy.get_param("~mover_check", False):
            self.skipTest("no synthetic ground truth")
        self.assertIn("/raw", self.octomaps, "the unfiltered octomap published nothing")
        summary = json.loads((pathlib.Path(self.source) / "synth.json").read_text())
        gt = synth_ground_truth(self.kind, self.source)
        duration = summary["duration_s"]
        res = float(rospy.get_param("~octomap_resolution"))
        # map (first base frame) -> room: room = T0 * world, world = B^-1 * map (B: base <- camera).
        B = transform_matrix(self.tf.lookup_transform("base_link", self.camera_frame, rospy.Time(0),
                                                      rospy.Duration(1.0)).transform)
        from dynaorb.synth.scene import CameraPath

        T0 = CameraPath().pose(0.0)
        self.assertTrue(np.allclose(gt[0][:3, 3], 0.0))
        map_to_room = T0 @ np.linalg.inv(B)
        statics = [o for o in summary["objects"] if not o["moving"]]
        movers = [o for o in summary["objects"] if o["moving"]]

        def on_mover_paths(msg):
            xyz = cloud_xyz(msg)
            room = (map_to_room[:3, :3] @ xyz.T).T + map_to_room[:3, 3]
            # Away from static surfaces by more than a voxel and a half.
            d_static = np.full(len(room), np.inf)
            for o in statics:
                lo, hi = np.array(o["lo"]), np.array(o["hi"])
                d_static = np.minimum(d_static, np.linalg.norm(room - np.clip(room, lo, hi), axis=1))
            hits = np.zeros(len(room), bool)
            for o in movers:
                v = np.array(o["velocity"])
                lo = np.minimum(np.array(o["lo"]), np.array(o["lo"]) + v * duration) - res / 2
                hi = np.maximum(np.array(o["hi"]), np.array(o["hi"]) + v * duration) + res / 2
                hits |= np.all((room >= lo) & (room <= hi), axis=1)
            return int(np.count_nonzero(hits & (d_static > 1.5 * res)))

        filtered, raw = on_mover_paths(self.octomaps[""]), on_mover_paths(self.octomaps["/raw"])
        rospy.loginfo("test_slam_node: occupied voxels on the movers' paths: %d filtered, %d unfiltered",
                      filtered, raw)
        self.assertEqual(filtered, 0)
        self.assertGreater(raw, 20)


if __name__ == "__main__":
    rostest.rosrun("dynaorb", "slam_node", SlamNodeTest, sys.argv)
