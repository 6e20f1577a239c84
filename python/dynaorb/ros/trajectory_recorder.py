"""trajectory_recorder: records nav_msgs/Odometry to a TUM file and reports ATE/RPE.

Subscribes  odom (nav_msgs/Odometry); every pose is appended and flushed at
            once, so a killed run loses nothing.
Parameters  ~output (trajectory.tum), ~ground_truth (optional: any file or
            folder `dynaorb eval` reads), ~align (se3|sim3|none, default se3),
            ~rpe_delta (frames, default 1), ~report_file (default OUTPUT.eval.json)
Services    ~report (std_srvs/Trigger): evaluates now; the message is JSON.
At shutdown the same report is logged and written to ~report_file.
"""
from __future__ import annotations

import json
import pathlib
import threading

import rospy
from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger, TriggerResponse


class TrajectoryRecorder:
    def __init__(self):
        self.output = pathlib.Path(rospy.get_param("~output", "trajectory.tum")).expanduser()
        self.ground_truth = rospy.get_param("~ground_truth", "")
        self.align = rospy.get_param("~align", "se3")
        self.rpe_delta = float(rospy.get_param("~rpe_delta", 1.0))
        self.report_file = pathlib.Path(rospy.get_param("~report_file", str(self.output) + ".eval.json"))
        self.output.parent.mkdir(parents=True, exist_ok=True)
        self.lock = threading.Lock()
        self.file = open(self.output, "w")
        self.file.write("# timestamp tx ty tz qx qy qz qw (dynaorb trajectory_recorder)\n")
        self.file.flush()
        self.count = 0
        self.out_of_order = 0
        self.last_stamp = None
        self.sub = rospy.Subscriber("odom", Odometry, self.on_odom, queue_size=1000)
        self.srv = rospy.Service("~report", Trigger, self.on_report)
        rospy.on_shutdown(self.on_shutdown)
        rospy.loginfo("trajectory_recorder: writing %s%s", self.output,
                      f", ground truth {self.ground_truth}" if self.ground_truth else "")

    def on_odom(self, msg: Odometry) -> None:
        stamp = msg.header.stamp.to_sec()
        with self.lock:
            if self.last_stamp is not None and stamp <= self.last_stamp:
                self.out_of_order += 1
                rospy.logwarn_throttle(5.0, "trajectory_recorder: odom stamp %.6f does not follow %.6f; "
                                       "skipped (%d so far)", stamp, self.last_stamp, self.out_of_order)
                return
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            self.file.write(f"{stamp:.6f} {p.x:.9f} {p.y:.9f} {p.z:.9f} {q.x:.9f} {q.y:.9f} {q.z:.9f} {q.w:.9f}\n")
            self.file.flush()
            self.last_stamp = stamp
            self.count += 1

    def report(self) -> dict:
        with self.lock:
            self.file.flush()
            out = {"poses": self.count, "out_of_order": self.out_of_order, "output": str(self.output)}
        if not self.ground_truth:
            return out
        from dynaorb.evaluation import evaluate

        try:
            result = evaluate(self.ground_truth, self.output, align=self.align, rpe_delta=self.rpe_delta)
            out.update(ate=result.ate, rpe_trans=result.rpe_trans, rpe_rot=result.rpe_rot,
                       matched_poses=result.matched_poses, align=self.align)
        except ValueError as exc:
            out["error"] = str(exc)
        return out

    def on_report(self, _req) -> TriggerResponse:
        report = self.report()
        return TriggerResponse(success="error" not in report, message=json.dumps(report))

    def on_shutdown(self) -> None:
        report = self.report()
        self.report_file.write_text(json.dumps(report, indent=2))
        if "ate" in report:
            rospy.loginfo("trajectory_recorder: %d poses, ATE RMSE %.4f m (%s)", report["poses"],
                          report["ate"]["rmse"], self.align)
        with self.lock:
            self.file.close()


def main() -> None:
    rospy.init_node("trajectory_recorder")
    TrajectoryRecorder()
    rospy.spin()
