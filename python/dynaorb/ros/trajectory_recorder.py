"""trajectory_recorder: records nav_msgs/Odometry to a TUM file and reports ATE/RPE.

Subscribes  odom (nav_msgs/Odometry); every pose is appended and flushed at
            once, so a killed run loses nothing.
Parameters  ~output (trajectory.tum), ~ground_truth (optional: any file or
            folder `dynaorb eval` reads), ~align (se3|sim3|none, default se3),
            ~rpe_delta (frames, default 1), ~report_file (default OUTPUT.eval.json),
            ~time_jump_reset (s, default 1; 0: off): an odom stamp more than
            this before the newest one (a bag played again with `rosbag play
            -l`, a simulator reset) starts a new pass, written to its own file
            (OUTPUT with .passN before the suffix: trajectory.pass2.tum) and
            evaluated on its own; a stamp that goes back less (or any, when
            off) is skipped and counted as out of order.
Services    ~report (std_srvs/Trigger): evaluates now; the message is JSON:
            the first pass's poses, out_of_order, output and ATE/RPE at the
            top level, every pass's in "passes", and "time_jumps".
At shutdown the same report is logged and written to ~report_file.
"""
from __future__ import annotations

import json
import math
import pathlib
import threading

import rospy
from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger, TriggerResponse


def pass_path(output: pathlib.Path, number: int) -> pathlib.Path:
    """The file of pass `number` (1-based): the first is `output` itself."""
    if number == 1:
        return output
    return output.with_name(f"{output.stem}.pass{number}{output.suffix}")


class _Pass:
    """One pass of the odometry: its own TUM file, pose count and out-of-order count."""

    def __init__(self, path: pathlib.Path):
        self.path = path
        self.file = open(path, "w")
        self.file.write("# timestamp tx ty tz qx qy qz qw (dynaorb trajectory_recorder)\n")
        self.file.flush()
        self.count = 0
        self.out_of_order = 0
        self.last_stamp = None

    def write(self, stamp: float, msg: Odometry) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        self.file.write(f"{stamp:.6f} {p.x:.9f} {p.y:.9f} {p.z:.9f} {q.x:.9f} {q.y:.9f} {q.z:.9f} {q.w:.9f}\n")
        self.file.flush()
        self.last_stamp = stamp
        self.count += 1


class TrajectoryRecorder:
    def __init__(self):
        self.output = pathlib.Path(rospy.get_param("~output", "trajectory.tum")).expanduser()
        self.ground_truth = rospy.get_param("~ground_truth", "")
        self.align = rospy.get_param("~align", "se3")
        self.rpe_delta = float(rospy.get_param("~rpe_delta", 1.0))
        self.report_file = pathlib.Path(rospy.get_param("~report_file", str(self.output) + ".eval.json"))
        self.time_jump_reset = float(rospy.get_param("~time_jump_reset", 1.0))
        if not math.isfinite(self.time_jump_reset) or self.time_jump_reset < 0:
            raise ValueError(f"~time_jump_reset must be a finite number of seconds >= 0 (0: off), "
                             f"got {self.time_jump_reset}")
        self.output.parent.mkdir(parents=True, exist_ok=True)
        self.lock = threading.Lock()
        self.passes = [_Pass(self.output)]
        self.sub = rospy.Subscriber("odom", Odometry, self.on_odom, queue_size=1000)
        self.srv = rospy.Service("~report", Trigger, self.on_report)
        rospy.on_shutdown(self.on_shutdown)
        rospy.loginfo("trajectory_recorder: writing %s%s", self.output,
                      f", ground truth {self.ground_truth}" if self.ground_truth else "")

    def on_odom(self, msg: Odometry) -> None:
        stamp = msg.header.stamp.to_sec()
        with self.lock:
            current = self.passes[-1]
            last = current.last_stamp
            if last is not None and stamp <= last:
                if self.time_jump_reset > 0 and stamp < last - self.time_jump_reset:
                    current.file.close()
                    current = _Pass(pass_path(self.output, len(self.passes) + 1))
                    self.passes.append(current)
                    rospy.logwarn("trajectory_recorder: odom stamp %.6f is %.3f s before %.6f (more than "
                                  "~time_jump_reset %.3f s): time went back; pass %d goes to %s", stamp,
                                  last - stamp, last, self.time_jump_reset, len(self.passes), current.path)
                else:
                    current.out_of_order += 1
                    rospy.logwarn_throttle(5.0, "trajectory_recorder: odom stamp %.6f does not follow %.6f; "
                                           "skipped (%d so far)", stamp, last, current.out_of_order)
                    return
            current.write(stamp, msg)

    def _evaluate(self, path: pathlib.Path) -> dict:
        from dynaorb.evaluation import evaluate

        try:
            result = evaluate(self.ground_truth, path, align=self.align, rpe_delta=self.rpe_delta)
        except ValueError as exc:
            return {"error": str(exc)}
        return dict(ate=result.ate, rpe_trans=result.rpe_trans, rpe_rot=result.rpe_rot,
                    matched_poses=result.matched_poses, align=self.align)

    def report(self) -> dict:
        with self.lock:
            passes = []
            for p in self.passes:
                if not p.file.closed:
                    p.file.flush()
                passes.append({"poses": p.count, "out_of_order": p.out_of_order, "output": str(p.path)})
        if self.ground_truth:
            for p in passes:
                p.update(self._evaluate(pathlib.Path(p["output"])))
        out = dict(passes[0])
        out["time_jumps"] = len(passes) - 1
        out["passes"] = passes
        return out

    def on_report(self, _req) -> TriggerResponse:
        report = self.report()
        ok = all("error" not in p for p in report["passes"])
        return TriggerResponse(success=ok, message=json.dumps(report))

    def on_shutdown(self) -> None:
        report = self.report()
        self.report_file.write_text(json.dumps(report, indent=2))
        for number, p in enumerate(report["passes"], 1):
            if "ate" in p:
                rospy.loginfo("trajectory_recorder: pass %d: %d poses, ATE RMSE %.4f m (%s)", number,
                              p["poses"], p["ate"]["rmse"], self.align)
        with self.lock:
            self.passes[-1].file.close()


def main() -> None:
    rospy.init_node("trajectory_recorder")
    try:
        TrajectoryRecorder()
    except ValueError as exc:
        rospy.logfatal("trajectory_recorder: %s", exc)
        raise SystemExit(1)
    rospy.spin()
