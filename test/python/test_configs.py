"""config/ agrees with what the providers derive from the datasets' own calibration."""
from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO
from dynaorb import core


def same_camera(a, b, tol=1e-6):
    for key in ("fx", "fy", "cx", "cy", "width", "height", "bf", "th_depth", "depth_map_factor", "n_features"):
        va, vb = getattr(a, key), getattr(b, key)
        assert (va is None) == (vb is None), key
        if va is not None:
            assert va == pytest.approx(vb, rel=tol, abs=tol), key
    assert np.allclose(a.dist.ravel()[:4], b.dist.ravel()[:4], atol=tol)


def test_euroc_stereo_config_is_derived_from_sensor_yaml(tmp_path, data):
    out = tmp_path / "euroc.yaml"
    subprocess.run([sys.executable, "-m", "dynaorb", "config", "euroc", str(data / "euroc/V1_01_easy_micro"),
                    "-o", str(out)], check=True, capture_output=True)
    derived = core().Settings.load(str(out))
    shipped = core().Settings.load(str(REPO / "config" / "EuRoC_stereo.yaml"))
    same_camera(derived, shipped, tol=1e-9)
    assert shipped.rectified_stereo
    assert np.allclose(derived.rectification_R_left, shipped.rectification_R_left)


def test_euroc_mono_and_kitti_configs(data):
    mono = core().open_dataset("euroc", str(data / "euroc/MH_05_difficult_head")).default_settings()
    same_camera(core().Settings.load(str(REPO / "config" / "EuRoC_mono.yaml")), mono)
    kitti = core().open_dataset("kitti", str(data / "kitti/sequences/06")).default_settings()
    same_camera(core().Settings.load(str(REPO / "config" / "KITTI04-12.yaml")), kitti, tol=1e-4)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_tum_builtin_camera_matches_config(tmp_path, data, n):
    seq = tmp_path / f"rgbd_dataset_freiburg{n}_copy"  # the camera is chosen by the folder name
    shutil.copytree(data / "tum/rgbd_dataset_freiburg3_walking_xyz_fragment", seq)
    builtin = core().open_dataset("tum", str(seq)).default_settings()
    shipped = core().Settings.load(str(REPO / "config" / f"TUM{n}.yaml"))
    same_camera(shipped, builtin)
    pad = lambda d: np.pad(d.ravel(), (0, 5 - d.size))  # noqa: E731  (k3 absent = 0)
    assert np.allclose(pad(shipped.dist), pad(builtin.dist))
