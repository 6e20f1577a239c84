"""dynaorb eval against known errors: the reported RMSE must match the error we put in."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dynaorb import core
from dynaorb.evaluation import TrajectoryFormatError, evaluate

TUM_GT = "tum/groundtruth/rgbd_dataset_freiburg3_walking_xyz-groundtruth.txt"


def read_tum(path):
    a = np.loadtxt(path, comments="#")
    poses = np.tile(np.eye(4), (len(a), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(a[:, 4:8]).as_matrix()
    poses[:, :3, 3] = a[:, 1:4]
    return a[:, 0], poses


def perturbed(poses, sigma, seed, transform=None, scale=1.0):
    """poses moved by a rigid transform (and scale) with N(0, sigma) noise on each position axis."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, sigma, (len(poses), 3))
    out = poses.copy()
    out[:, :3, 3] = poses[:, :3, 3] * scale + noise
    if transform is not None:
        out = transform[None] @ out
    return out, np.sqrt(np.mean(np.sum(noise ** 2, axis=1)))


def known_transform():
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [20, -35, 110], degrees=True).as_matrix()
    T[:3, 3] = [3.0, -1.5, 0.7]
    return T


@pytest.fixture(scope="module")
def tum_gt(data):
    return data / TUM_GT


def test_se3_alignment_recovers_known_rmse(tmp_path, tum_gt):
    stamps, poses = read_tum(tum_gt)
    est, true_rmse = perturbed(poses, 0.02, seed=1, transform=known_transform())
    core().write_tum(str(tmp_path / "est.tum"), stamps, est)
    result = evaluate(tum_gt, tmp_path / "est.tum", align="se3", rpe_delta=None)
    assert result.matched_poses == len(stamps)
    assert result.ate["rmse"] == pytest.approx(true_rmse, rel=0.01)
    unaligned = evaluate(tum_gt, tmp_path / "est.tum", align="none", rpe_delta=None)
    assert unaligned.ate["rmse"] > 1.0  # the transform is still in there


def test_no_alignment_gives_exact_rmse_and_rpe(tmp_path, tum_gt):
    stamps, poses = read_tum(tum_gt)
    est, true_rmse = perturbed(poses, 0.01, seed=2)
    core().write_tum(str(tmp_path / "est.tum"), stamps, est)
    result = evaluate(tum_gt, tmp_path / "est.tum", align="none", rpe_delta=1, rpe_unit="frames")
    assert result.ate["rmse"] == pytest.approx(true_rmse, rel=1e-4)
    # Consecutive independent noises: RPE translation RMSE ~ sigma * sqrt(6).
    assert result.rpe_trans["rmse"] == pytest.approx(0.01 * np.sqrt(6), rel=0.05)
    assert result.rpe_rot["rmse"] < 0.05  # rotations were not perturbed (file rounding only)


def test_sim3_recovers_scale(tmp_path, tum_gt):
    stamps, poses = read_tum(tum_gt)
    est, true_rmse = perturbed(poses, 0.005, seed=3, transform=known_transform(), scale=0.5)
    core().write_tum(str(tmp_path / "est.tum"), stamps, est)
    result = evaluate(tum_gt, tmp_path / "est.tum", align="sim3", rpe_delta=None)
    assert result.scale == pytest.approx(2.0, rel=0.01)
    assert result.ate["rmse"] == pytest.approx(2 * true_rmse, rel=0.02)  # noise scaled up with the estimate


def test_euroc_ground_truth_through_t_bs(tmp_path, data):
    """The C++ provider's cam0 poses and evo's reading of the EuRoC csv agree exactly."""
    provider = core().open_dataset("euroc", str(data / "euroc/V1_01_easy_micro"))
    stamps, poses = provider.ground_truth()
    core().write_tum(str(tmp_path / "cam0.tum"), stamps, poses)
    result = evaluate(data / "euroc/V1_01_easy_micro", tmp_path / "cam0.tum", align="none", rpe_delta=None)
    assert result.matched_poses == len(stamps)
    assert result.ate["rmse"] < 1e-6


def test_kitti_ground_truth_with_times(tmp_path, data):
    provider = core().open_dataset("kitti", str(data / "kitti/sequences/06"))
    stamps, poses = provider.ground_truth()
    est, true_rmse = perturbed(poses, 0.05, seed=4)
    core().write_tum(str(tmp_path / "est.tum"), stamps, est)
    core().write_kitti(str(tmp_path / "est.kitti"), stamps, est)
    gt = data / "kitti/poses/06.txt"
    for est_file in ("est.tum", "est.kitti"):
        result = evaluate(gt, tmp_path / est_file, align="none", rpe_delta=None)
        assert result.matched_poses == 51
        assert result.ate["rmse"] == pytest.approx(true_rmse, rel=1e-4)


def test_cli_json_and_plots(tmp_path, tum_gt):
    stamps, poses = read_tum(tum_gt)
    est, true_rmse = perturbed(poses, 0.02, seed=5, transform=known_transform())
    core().write_tum(str(tmp_path / "est.tum"), stamps, est)
    proc = subprocess.run([sys.executable, "-m", "dynaorb", "eval", str(tum_gt), str(tmp_path / "est.tum"),
                           "--align", "se3", "--rpe", "0.5", "--rpe-unit", "m", "--plot", str(tmp_path / "plots"),
                           "--json"], capture_output=True, text=True, check=True)
    out = json.loads(proc.stdout)
    assert out["ate"]["rmse"] == pytest.approx(true_rmse, rel=0.01)
    assert out["rpe_percent"]["rmse"] > 0
    assert (tmp_path / "plots" / "trajectory.png").stat().st_size > 1000
    assert (tmp_path / "plots" / "ate.png").stat().st_size > 1000
    table = subprocess.run([sys.executable, "-m", "dynaorb", "eval", str(tum_gt), str(tmp_path / "est.tum")],
                           capture_output=True, text=True, check=True).stdout
    assert "ATE [m]" in table and "rmse" in table


def test_bad_files_are_named(tmp_path, tum_gt):
    bad = tmp_path / "bad.tum"
    bad.write_text("# x\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 zero 1\n")
    with pytest.raises(TrajectoryFormatError, match=r"bad.tum:3"):
        evaluate(tum_gt, bad)
    with pytest.raises(TrajectoryFormatError, match="no such file"):
        evaluate(tum_gt, tmp_path / "absent.tum")
    far = tmp_path / "far.tum"
    far.write_text("".join(f"{t} 0 0 0 0 0 0 1\n" for t in (1.0, 2.0, 3.0, 4.0)))
    with pytest.raises(TrajectoryFormatError, match="match"):
        evaluate(tum_gt, far)
    proc = subprocess.run([sys.executable, "-m", "dynaorb", "eval", str(tum_gt), str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and "bad.tum:3" in proc.stderr
