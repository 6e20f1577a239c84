"""Trajectory evaluation with evo: ATE and RPE against TUM, KITTI and EuRoC ground truth."""

from dynaorb.evaluation.trajectories import load_trajectory, TrajectoryFormatError
from dynaorb.evaluation.metrics import evaluate, EvalResult

__all__ = ["load_trajectory", "TrajectoryFormatError", "evaluate", "EvalResult"]
