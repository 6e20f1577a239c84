"""dynaorb run with the dynamic-object front end: presets, label folders, saved masks, stats."""
from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

from conftest import REPO
from dynaorb.runner import RunOptions, dynamic_presets, run_dataset

VOC_MOVABLE = (1, 2, 3, 4, 6, 7, 8, 10, 12, 13, 14, 15, 17, 19)


def _movable(labels: np.ndarray) -> np.ndarray:
    return np.isin(labels, VOC_MOVABLE)


def test_presets_are_shipped():
    assert {"off", "stdyn", "dm", "ddl", "li", "full"} <= set(dynamic_presets())


def test_dm_run_saves_masks_and_stats(tmp_path, synth_rgbd):
    masks = tmp_path / "masks"
    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "out"), dynamic="dm",
                                   labels=str(synth_rgbd / "labels"), save_masks=str(masks), progress=False))
    frames = sorted((synth_rgbd / "rgb").iterdir())
    assert sorted(p.name for p in masks.iterdir()) == [p.with_suffix(".png").name for p in frames]
    dyn = stats["dynamic_filter"]
    assert dyn["stages"] == ["semantic", "dm"]
    assert dyn["labels"] == {"used": 8}
    assert dyn["masks_saved"] == 8 and dyn["stage_failures"] == 0
    assert len(dyn["per_frame"]) == 8
    first = dyn["per_frame"][0]
    assert set(first) >= {"index", "dynamic_keypoints", "dynamic_fraction", "stage_ms", "values"}
    for key in ("dynamic", "dynamic.semantic", "dynamic.dm", "dynamic.motion_cues"):
        assert key in dyn["summary"]["stage_ms_median"], key
        assert key in stats["stage_ms_median"], key
    assert "semantic.candidate_fraction" in first["values"]
    on_disk = json.loads((tmp_path / "out" / "stats.json").read_text())
    assert on_disk["dynamic_filter"]["summary"] == json.loads(json.dumps(dyn["summary"]))
    # Static until proven moving: whatever dm drops lies in a movable-class
    # region widened by the 15 px margin, never elsewhere; the parked car may stay.
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (31, 31))
    for i, frame in enumerate(frames):
        mask = cv2.imread(str(masks / frame.with_suffix(".png").name), cv2.IMREAD_UNCHANGED)
        assert mask.shape == (240, 320) and mask.dtype == np.uint8
        assert set(np.unique(mask)) <= {0, 255}
        labels = cv2.imread(str(synth_rgbd / "labels" / frame.name), cv2.IMREAD_UNCHANGED)
        widened = cv2.dilate(_movable(labels).astype(np.uint8), disc) > 0
        assert not np.any((mask > 0) & ~widened), frame.name
        assert dyn["per_frame"][i]["dynamic_fraction"] == pytest.approx(np.count_nonzero(mask) / mask.size)


def test_drop_preset_file_masks_every_movable_pixel(tmp_path, synth_rgbd):
    preset = tmp_path / "drop.yaml"
    preset.write_text("%YAML:1.0\nDynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n")
    masks = tmp_path / "masks"
    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "out"), dynamic=str(preset),
                                   labels=str(synth_rgbd / "labels"), save_masks=str(masks), progress=False))
    for frame in sorted((synth_rgbd / "rgb").iterdir()):
        mask = cv2.imread(str(masks / frame.name), cv2.IMREAD_UNCHANGED)
        labels = cv2.imread(str(synth_rgbd / "labels" / frame.name), cv2.IMREAD_UNCHANGED)
        assert np.array_equal(mask > 0, _movable(labels)), frame.name
    assert stats["dynamic_filter"]["summary"]["dynamic_keypoints_total"] > 0


def test_label_folder_with_labels_json_brings_its_movable_ids(tmp_path, synth_rgbd):
    # A `dynaorb segment` folder whose label set calls only the car movable.
    labels = tmp_path / "labels"
    labels.mkdir()
    for p in (synth_rgbd / "labels").iterdir():
        (labels / p.name).write_bytes(p.read_bytes())
    (labels / "labels.json").write_text(json.dumps({"model": "test", "labels": [], "movable": [7]}))
    preset = tmp_path / "drop.yaml"
    preset.write_text("%YAML:1.0\nDynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n")
    masks = tmp_path / "masks"
    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "out"), dynamic=str(preset),
                                   labels=str(labels), save_masks=str(masks), progress=False))
    assert stats["dynamic_filter"]["movable_classes"] == [7]
    frame = sorted((synth_rgbd / "rgb").iterdir())[0]
    mask = cv2.imread(str(masks / frame.name), cv2.IMREAD_UNCHANGED)
    ids = cv2.imread(str(labels / frame.name), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(mask > 0, ids == 7)


def test_stereo_full_preset(tmp_path, synth_stereo):
    seq = synth_stereo / "sequences" / "00"
    masks = tmp_path / "masks"
    stats = run_dataset(RunOptions(kind="kitti", path=str(seq), out=str(tmp_path / "out"), dynamic="full",
                                   labels=str(seq / "labels"), save_masks=str(masks), progress=False))
    dyn = stats["dynamic_filter"]
    assert dyn["stages"] == ["semantic", "dm", "stdyn"]
    assert dyn["stage_failures"] == 0
    assert len(list(masks.iterdir())) == stats["frames"] == 6
    assert "dynamic.stdyn" in dyn["summary"]["stage_ms_median"]
    # The corners (and their stereo depth) found ahead on the filter's worker
    # thread: from the third frame on (the second tracks the first's corners,
    # detected then); DM-SLAM's regions cut there beside the motion cues;
    # apart from the stages' times.
    worker = dyn["summary"]["worker_ms_median"]
    assert set(worker) == {"corners_ahead", "stereo_ahead", "regions_ahead"} and min(worker.values()) > 0, worker
    assert not any(k.endswith("_ahead") for k in dyn["summary"]["stage_ms_median"])


@pytest.mark.parametrize("sensor", ["rgbd", "stereo"])
def test_filter_beside_the_corner_detection_changes_no_result(tmp_path, sensor, synth_rgbd, synth_stereo):
    # Dynamic.overlap_extraction 1 runs the filter while a worker thread
    # detects the ORB corners, 0 runs it first: the same features, so the same
    # (synchronous, repeatable) run.
    kind, seq = ("tum", synth_rgbd) if sensor == "rgbd" else ("kitti", synth_stereo / "sequences" / "00")
    full = (REPO / "config" / "dynamic" / "full.yaml").read_text()
    runs = {}
    for overlap in (0, 1):
        preset = tmp_path / f"full_{overlap}.yaml"
        preset.write_text(full + f"\nDynamic.overlap_extraction: {overlap}\n")
        out = tmp_path / f"o{overlap}"
        stats = run_dataset(RunOptions(kind=kind, path=str(seq), out=str(out), dynamic=str(preset),
                                       labels=str(seq / "labels"), progress=False))
        assert stats["tracked_fraction"] == 1.0
        runs[overlap] = ((out / "trajectory.tum").read_text(),
                         [f["dynamic_keypoints"] for f in stats["dynamic_filter"]["per_frame"]],
                         stats["stage_ms_median"])
    assert runs[0][0] == runs[1][0]
    assert runs[0][1] == runs[1][1] and sum(runs[1][1]) > 0
    assert "extract_overlapped" in runs[1][2] and "extract_overlapped" not in runs[0][2]


def test_cli_dynamic_run_and_errors(tmp_path, synth_rgbd):
    ok = subprocess.run([sys.executable, "-m", "dynaorb", "run", "tum", str(synth_rgbd), "--out", str(tmp_path / "o"),
                         "--dynamic", "dm", "--labels", str(synth_rgbd / "labels"), "--save-masks",
                         str(tmp_path / "m"), "--quiet"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert "dynamic filter (semantic, dm)" in ok.stdout
    assert len(list((tmp_path / "m").iterdir())) == 8

    def error(*args):
        r = subprocess.run([sys.executable, "-m", "dynaorb", "run", "tum", str(synth_rgbd), "--out",
                            str(tmp_path / "e"), "--quiet", *args], capture_output=True, text=True)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        return r.stderr

    assert "dynamic mode" in error("--dynamic", "magic")
    li = error("--dynamic", "li")  # stereo only: refused on RGB-D, naming the sensor
    assert "rgbd" in li and "li.yaml" in li
    assert "--dynamic" in error("--labels", str(synth_rgbd / "labels"))
    assert "--dynamic" in error("--save-masks", str(tmp_path / "m2"))
    bad = tmp_path / "bad.yaml"
    bad.write_text("%YAML:1.0\nDynamic.stages: [semantic]\nDynamic.semantic: {margn: 3}\n")
    assert "Dynamic.semantic.margn" in error("--dynamic", str(bad))


def test_bindings_labels_mask_and_dense_frame(synth_rgbd):
    from dynaorb import core

    _core = core()
    preset = _core.DynamicFilterOptions.parse(
        "Dynamic.stages: [semantic]\nDynamic.semantic: {policy: drop, margin: 0}\n", "inline")
    assert preset.stages_for("rgbd") == ["semantic"]
    assert set(_core.dynamic_stages()) >= {"semantic", "dm", "stdyn", "ddl", "li"}
    rng = np.random.default_rng(0)
    rgb = cv2.GaussianBlur(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8), (5, 5), 1.2)
    depth = np.full((240, 320), 10000, np.uint16)
    labels = np.zeros((240, 320), np.uint8)
    labels[50:150, 100:180] = 15
    cfg = _core.Settings.load(str(synth_rgbd / "settings.yaml"))
    system = _core.System(cfg, "rgbd", synchronous_mapping=True, dynamic=preset)
    assert system.dynamic_filter_enabled
    assert system.last_dynamic_mask() is None and system.dense_frame() is None
    r = system.track_rgbd(rgb, depth, 1.0, labels=labels)
    assert r.labels_used and r.dynamic_fraction == pytest.approx(100 * 80 / (240 * 320))
    assert r.dynamic_keypoints > 0 and "dynamic.semantic" in r.stage_ms
    assert r.dynamic_values["semantic.regions"] == 1
    assert np.array_equal(system.last_dynamic_mask() > 0, labels == 15)
    d = system.dense_frame()
    assert d["colour"].shape == (240, 320, 3) and d["depth"].dtype == np.float32
    assert d["T_wc"].shape == (4, 4) and d["K"][0, 0] == cfg.fx and not d["inpainted"]
    # The first frame: nothing to judge motion by, so its movable regions are unchecked.
    assert d["motion_checked"] is False and np.array_equal(d["candidates"] > 0, labels == 15)
    assert system.counters()["labels_dropped"] == 0
    system.track_rgbd(rgb, depth, 2.0, labels=np.zeros((10, 10), np.uint8))
    assert system.counters()["labels_dropped"] == 1
    # Another label set's ids, announced after start-up: class 15 is no longer movable.
    assert 15 in system.movable_classes
    system.set_movable_classes([24])
    assert system.movable_classes == [24]
    assert system.track_rgbd(rgb, depth, 3.0, labels=labels).dynamic_fraction == 0
    off = _core.System(cfg, "rgbd")
    assert not off.dynamic_filter_enabled
    assert off.track_rgbd(rgb, depth, 1.0, labels=labels).dynamic_keypoints == 0



def test_segment_feeds_labels_to_the_filter(tmp_path, synth_rgbd, data):
    models = data.parent / "models" / "segmentation"
    model = models / "deeplabv3_mnv2_dm05_pascal_quant.onnx"
    if not model.is_file():
        pytest.skip(f"model not found at {model}")
    stats = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "o"), progress=False,
                                   dynamic="dm", segment=str(model), segment_mode="sync",
                                   save_masks=str(tmp_path / "m")))
    dyn = stats["dynamic_filter"]
    assert dyn["labels"] == "segmentation"
    assert dyn["movable_classes"] == list(VOC_MOVABLE)  # the model card's movable ids
    assert all(f["labels_used"] for f in dyn["per_frame"])
    assert stats["masks"] is None and len(list((tmp_path / "m").iterdir())) == 8
    with pytest.raises(ValueError, match="not both"):
        run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "x"), progress=False,
                               dynamic="dm", segment=str(model), labels=str(synth_rgbd / "labels")))
