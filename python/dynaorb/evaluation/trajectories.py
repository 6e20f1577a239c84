"""Reading ground truth and estimates in TUM, KITTI and EuRoC layouts as evo trajectories.

- TUM: ``stamp tx ty tz qx qy qz qw`` (a file, or a sequence folder holding groundtruth.txt).
- KITTI: 12 numbers a line (``poses/NN.txt``); stamps come from the sequence's
  ``times.txt`` when it lies at ``ROOT/sequences/NN/times.txt``.
- EuRoC: ``state_groundtruth_estimate0/data.csv`` (or the mav0 folder / its parent):
  body (IMU) poses, turned into cam0 poses through cam0's ``T_BS``.
"""
from __future__ import annotations

import pathlib

import numpy as np
from evo.core import trajectory as evo_traj
from evo.tools import file_interface


class TrajectoryFormatError(ValueError):
    """A trajectory file that cannot be read; the message names the file (and line)."""


def _first_data_line(path: pathlib.Path) -> tuple[int, list[str]]:
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            line = line.strip()
            if line and not line.startswith("#"):
                return number, line.replace(",", " ").split()
    raise TrajectoryFormatError(f"{path}: holds no poses")


def _check_rows(path: pathlib.Path, n_fields: int, sep: str | None = None) -> None:
    """Names the first line that does not hold n_fields numbers (evo's own messages do not)."""
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            fields = text.split(sep) if sep else text.split()
            if len(fields) < n_fields:
                raise TrajectoryFormatError(
                    f"{path}:{number}: expected {n_fields} fields, found {len(fields)}")
            try:
                [float(x) for x in fields[:n_fields]]
            except ValueError:
                raise TrajectoryFormatError(f"{path}:{number}: non-numeric field in '{text}'") from None


def _euroc_t_bs(mav0: pathlib.Path) -> np.ndarray:
    """cam0's T_BS (body <- sensor) from mav0/cam0/sensor.yaml."""
    import yaml  # PyYAML comes with evo

    sensor = mav0 / "cam0" / "sensor.yaml"
    if not sensor.is_file():
        raise TrajectoryFormatError(f"{sensor}: missing (needed for cam0's T_BS)")
    text = sensor.read_text()
    if text.startswith("%YAML"):
        text = text.split("\n", 1)[1]
    try:
        data = yaml.safe_load(text)["T_BS"]["data"]
    except (KeyError, TypeError, yaml.YAMLError) as exc:
        raise TrajectoryFormatError(f"{sensor}: no T_BS data ({exc})") from None
    if len(data) != 16:
        raise TrajectoryFormatError(f"{sensor}: T_BS must hold 16 numbers")
    return np.asarray(data, dtype=float).reshape(4, 4)


def _kitti_times(poses_file: pathlib.Path) -> pathlib.Path | None:
    times = poses_file.parent.parent / "sequences" / poses_file.stem / "times.txt"
    return times if times.is_file() else None


def _resolve(path: pathlib.Path) -> tuple[str, pathlib.Path]:
    """(format, file) for a file or a dataset folder."""
    if path.is_dir():
        for mav0 in (path, path / "mav0"):
            gt = mav0 / "state_groundtruth_estimate0" / "data.csv"
            if gt.is_file():
                return "euroc", gt
        if (path / "groundtruth.txt").is_file():
            return "tum", path / "groundtruth.txt"
        raise TrajectoryFormatError(f"{path}: folder holds no ground truth (groundtruth.txt or mav0)")
    if not path.is_file():
        raise TrajectoryFormatError(f"{path}: no such file")
    _, fields = _first_data_line(path)
    if path.suffix == ".csv" or len(fields) >= 17:
        return "euroc", path
    if len(fields) == 12:
        return "kitti", path
    if len(fields) == 8:
        return "tum", path
    raise TrajectoryFormatError(
        f"{path}: cannot tell the format from a line of {len(fields)} fields "
        "(TUM has 8, KITTI 12, EuRoC csv 17)")


def load_trajectory(path: str | pathlib.Path, fmt: str = "auto"):
    """An evo PoseTrajectory3D (stamped) or PosePath3D (KITTI without times.txt).

    Poses are of the camera (TUM: colour camera; KITTI: left camera; EuRoC: cam0
    through T_BS) in the world frame.
    """
    path = pathlib.Path(path)
    kind, file = _resolve(path) if fmt == "auto" else (fmt, path)
    if not file.is_file():
        raise TrajectoryFormatError(f"{file}: no such file")
    if kind == "tum":
        _check_rows(file, 8)
        traj = file_interface.read_tum_trajectory_file(str(file))
        if np.any(np.diff(traj.timestamps) <= 0):
            bad = int(np.argmax(np.diff(traj.timestamps) <= 0)) + 1
            raise TrajectoryFormatError(f"{file}: timestamps are not increasing (pose {bad + 1})")
        return traj
    if kind == "kitti":
        _check_rows(file, 12)
        path3d = file_interface.read_kitti_poses_file(str(file))
        times = _kitti_times(file)
        if times is None:
            return path3d
        stamps = np.loadtxt(times, ndmin=1)
        if len(stamps) < path3d.num_poses:
            raise TrajectoryFormatError(
                f"{file}: {path3d.num_poses} poses but {times} has {len(stamps)} stamps")
        return evo_traj.PoseTrajectory3D(poses_se3=path3d.poses_se3,
                                         timestamps=stamps[: path3d.num_poses])
    if kind == "euroc":
        _check_rows(file, 8, sep=",")
        traj = file_interface.read_euroc_csv_trajectory(str(file))
        mav0 = file.parent.parent
        traj.transform(_euroc_t_bs(mav0), right_mul=True)  # body pose -> cam0 pose
        return traj
    raise TrajectoryFormatError(f"{path}: unknown format '{fmt}' (tum, kitti, euroc)")


def write_trajectory(path: str | pathlib.Path, stamps: np.ndarray, poses: np.ndarray, fmt: str = "tum") -> None:
    """Writes (N,) stamps and (N,4,4) poses through the core's TUM / KITTI writers."""
    from dynaorb import core

    writer = {"tum": core().write_tum, "kitti": core().write_kitti}[fmt]
    writer(str(path), np.asarray(stamps, dtype=float).reshape(-1),
           np.asarray(poses, dtype=float).reshape(-1, 4, 4))
