"""The ROS side's constants that mirror Python's, and launch files that roslaunch can load."""
from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from conftest import REPO


def cpp_constant(pattern: str) -> str:
    text = (REPO / "src" / "ros" / "node_config.cc").read_text()
    found = re.search(pattern, text)
    assert found, pattern
    return found.group(1)


def test_node_finds_the_default_vocabulary_python_builds():
    from dynaorb.vocab.default import FILE_NAME

    assert cpp_constant(r'kDefaultVocabularyFile = "([^"]+)"') == FILE_NAME


def test_node_masks_the_movable_classes_the_runner_masks():
    from dynaorb.segmentation.labels import PASCAL_VOC_MOVABLE

    ids = [int(i) for i in cpp_constant(r"kPascalVocMovable = \{([^}]*)\}").split(",")]
    assert tuple(ids) == tuple(PASCAL_VOC_MOVABLE)


LAUNCH_ARGS = {"dynaorb_node.launch": ["sensor:=rgbd", "settings:=x.yaml"],
               "play_tum.launch": ["bag:=x.bag"], "play_kitti.launch": ["bag:=x.bag"],
               "play_euroc.launch": ["bag:=x.bag"]}


@pytest.mark.parametrize("launch", sorted(p.name for p in (REPO / "launch").glob("*.launch")))
def test_launch_files_load(launch, tmp_path):
    if shutil.which("roslaunch") is None:
        pytest.skip("roslaunch not installed")
    env = dict(os.environ, ROS_PACKAGE_PATH=str(REPO), ROS_HOME=str(tmp_path), ROS_LOG_DIR=str(tmp_path))
    run = subprocess.run(["roslaunch", "--nodes", str(REPO / "launch" / launch), *LAUNCH_ARGS.get(launch, [])],
                         capture_output=True, text=True, env=env, timeout=60)
    assert run.returncode == 0, run.stderr
    if launch.startswith("dynaorb_"):
        assert "/dynaorb" in run.stdout.split()


@pytest.mark.parametrize("node", ["dynaorb_node", "dynaorb_octomap", "segmentation_server", "trajectory_recorder"])
def test_rosrun_finds_each_node_once(node, tmp_path):
    """`rosrun dynaorb NODE` in the devel space the build makes: one match, the
    devel space's (rosrun skips PACKAGE/build/, and asks which one when it finds two)."""
    if shutil.which("rosrun") is None:
        pytest.skip("rosrun not installed")
    setup = REPO / "devel" / "setup.bash"
    assert setup.is_file(), f"{setup} missing: build first (make build)"
    env = dict(os.environ, ROS_HOME=str(tmp_path), ROS_LOG_DIR=str(tmp_path))
    run = subprocess.run(["bash", "-c", f"source {setup} && rosrun --prefix echo dynaorb {node}"],
                         capture_output=True, text=True, env=env, stdin=subprocess.DEVNULL, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.split() == [str(REPO / "devel" / "lib" / "dynaorb" / node)], run.stdout
