"""The dynamic-object front end end to end (issue 5), on synthetic sequences
with movers: people crossing, a vehicle travelling beside the camera in its
direction of motion and a parked car of a movable class. The system gets the
synthetic label images (what a segmentation network outputs) as its semantic
input, never the ground-truth dynamic masks; those only score the result.

- Each geometric stage: keypoint precision and recall against the ground-truth
  masks on frames where movers fill 20-40 % of the image.
- `full`: ATE within 1.2x of the same sequence without movers, `off` at least
  3x worse (or not initialised at all), for RGB-D, stereo and mono; as the
  median over seeds 0-2.
- `li` without any semantic input: ATE within 1.5x of the run without movers
  (stereo; median over seeds 0-2).
- Under DM-SLAM's policy the parked car keeps its features.
"""
from __future__ import annotations

import pathlib

import cv2
import numpy as np
import pytest

from dynaorb import core
from dynaorb.runner import RunOptions, run_dataset

# PASCAL VOC's ground truth leaves a 5 px "void" band along object outlines
# out of the evaluation; keypoints that close to a mover's outline are not
# scored here either (their descriptor patches straddle both sides).
VOID_BAND_PX = 5
CAR = 7
PERSON = 15


def _frames(seq: pathlib.Path, sensor: str) -> list[pathlib.Path]:
    return sorted((seq / ("rgb" if sensor == "rgbd" else "image_0")).glob("*.png"))


def _run(tmp_path, scenes, sensor, movers, name, **kw) -> dict:
    seq = scenes[sensor, movers]
    kind = "tum" if sensor == "rgbd" else "kitti"
    return run_dataset(RunOptions(kind=kind, path=str(seq), sensor=sensor, out=str(tmp_path / name),
                                  progress=False, **kw))


def _preset(tmp_path, name: str, text: str) -> str:
    path = tmp_path / f"{name}.yaml"
    path.write_text("%YAML:1.0\n" + text)
    return str(path)


def _keypoint_scores(seq, sensor, masks_dir) -> tuple[float, float, int, dict]:
    """Pooled keypoint precision and recall over the frames with 20-40 % movers
    (the first frame, which has no previous frame, left out), and the recall
    on each mover class ({label id: recall}: the persons, the vehicle)."""
    tp = fp = fn = 0
    frames = 0
    by_class = {PERSON: [0, 0], CAR: [0, 0]}  # [found, dynamic keypoints]
    settings = core().Settings.load(str(seq / "settings.yaml"))
    for i, image in enumerate(_frames(seq, sensor)):
        if i == 0:
            continue
        truth = cv2.imread(str(seq / "dynamic_masks" / image.name), cv2.IMREAD_UNCHANGED) > 0
        if not 0.2 <= truth.mean() <= 0.4:
            continue
        predicted = cv2.imread(str(masks_dir / image.name), cv2.IMREAD_UNCHANGED) > 0
        grey = cv2.imread(str(image), cv2.IMREAD_GRAYSCALE)
        kps = core().extract_orb(grey, settings)[0]
        u = np.clip(np.round(kps[:, 0]).astype(int), 0, grey.shape[1] - 1)
        v = np.clip(np.round(kps[:, 1]).astype(int), 0, grey.shape[0] - 1)
        t8 = truth.astype(np.uint8)
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * VOID_BAND_PX + 1,) * 2)
        void = (cv2.dilate(t8, k) > 0) & ~(cv2.erode(t8, k) > 0)
        keep = ~void[v, u]
        t, p = truth[v, u][keep], predicted[v, u][keep]
        tp += int(np.sum(t & p))
        fp += int(np.sum(~t & p))
        fn += int(np.sum(t & ~p))
        labels = cv2.imread(str(seq / "labels" / image.name), cv2.IMREAD_UNCHANGED)[v, u][keep]
        for c, count in by_class.items():
            count[0] += int(np.sum(t & p & (labels == c)))
            count[1] += int(np.sum(t & (labels == c)))
        frames += 1
    precision = tp / max(tp + fp, 1)
    recall = tp / max(tp + fn, 1)
    return precision, recall, frames, {c: found / max(n, 1) for c, (found, n) in by_class.items()}


SEMANTIC_CANDIDATES = "Dynamic.semantic: {classes: voc, margin: 5, policy: static_until_proven}\n"
# stage -> (sensor, preset text, least precision, least recall). The bounds
# are the 0.9 where a stage reaches it; below it they are regression
# bounds a little under the measured values (seed 0), and the target is missed:
#   dm:    1.000 / 1.000 (paper's eq. 6-8 with the ego-motion of motion_cues)
#   ddl:   0.992 / 0.967 (persons 0.970, vehicle 0.959) with sliding
#          surfaces seeding regions (seed_sliding_surfaces, ours: the side of
#          the vehicle beside the camera keeps its depth; seeds 1 / 2: 0.974 /
#          0.945, 0.990 / 0.946); 0.998 / 0.903 (vehicle 0.738) without;
#          scored without DDL-SLAM's union with every movable-class region
#          (which takes in the parked car: precision 0.78)
#   stdyn: with the papers' values (F from all points, one dynamic point moves
#          an object) 0.86 / 0.94; with F from the points outside the
#          candidates, refined on its inliers, a 1 px RANSAC threshold and
#          10 % dynamic points per object 1.00 / 0.90 (the vehicle, moving
#          along its epipolar lines, is what recall misses: 0.74); with an
#          object proven moving kept so for 3 frames (keep_moving_frames,
#          ours) 1.000 / 0.971, vehicle 0.93 (seeds 1 / 2: 0.905 / 1.000,
#          0.997 / 0.967; 0.943 / 0.948, 0.997 / 0.903 without)
#   li:    0.900 / 0.962 with the preset's additions of ours (keep_frames
#          10: a rectangle found in two frames stays dynamic while no new one
#          covers it; rigid_check: the pairs' reprojection error under the
#          camera's motion from PnP on the previous SGBM depth, with agreeing
#          neighbours; lk_forward_backward_max 3; foreground_only: of each
#          rectangle only what is as near as its object, plus 5 px;
#          f_exclude_previous_dynamic: F fitted outside the previous frame's
#          mask), no semantic input (seeds 1 / 2: 0.951 / 0.922 precision,
#          0.840 / 0.898 before F left the previous mask out; seed 0 0.901
#          then; the bound 0.89 leaves room for another CPU's rounding in
#          SGBM and LK); 0.870 / 0.968 plus 15 px; 0.76 / 0.97 with whole
#          rectangles, which overshoot the movers. Recall 0.99 on the
#          crossing persons, 0.92 on the vehicle (0.93 at 15 px), whose
#          points move along their epipolar lines (without rigid_check 0.77 /
#          0.91, vehicle 0.77). The paper's method alone (keep_frames 0, no
#          rigid_check): 0.82 / 0.76, vehicle 0.50 (Li's check finds 0.8-0.9
#          of its keypoints in 27 of 59 frames and at most 0.05 in 23).
STAGES = {
    "dm": ("rgbd", "Dynamic.stages: [semantic, dm]\n" + SEMANTIC_CANDIDATES, 0.9, 0.9),
    "ddl": ("rgbd", "Dynamic.stages: [semantic, ddl]\n" + SEMANTIC_CANDIDATES
            + "Dynamic.ddl: {combine_semantic: 0, seed_sliding_surfaces: 1}\n", 0.9, 0.9),
    "stdyn": ("stereo", "Dynamic.stages: [semantic, stdyn]\n" + SEMANTIC_CANDIDATES
              + "Dynamic.stdyn: {f_exclude_candidates: 1, f_refine_on_inliers: 1, f_ransac_threshold_px: 1.0, "
                "min_dynamic_ratio: 0.1, keep_moving_frames: 3}\n", 0.9, 0.9),
    "li": ("stereo", "Dynamic.stages: [li]\nDynamic.li: {keep_frames: 10, rigid_check: 1, "
           "lk_forward_backward_max: 3, foreground_only: 1, foreground_band_px: 5, "
           "f_exclude_previous_dynamic: 1}\n", 0.89, 0.9),
}


@pytest.mark.parametrize("stage", sorted(STAGES))
def test_geometric_stage_precision_and_recall(tmp_path, synth_scenes, stage):
    sensor, text, least_precision, least_recall = STAGES[stage]
    masks = tmp_path / "masks"
    stats = _run(tmp_path, synth_scenes, sensor, 3, stage, dynamic=_preset(tmp_path, stage, text),
                 save_masks=str(masks),
                 **({} if stage == "li" else {"labels": str(synth_scenes[sensor, 3] / "labels")}))
    precision, recall, frames, by_class = _keypoint_scores(synth_scenes[sensor, 3], sensor, masks)
    assert frames >= 30, frames
    print(f"{stage}: precision {precision:.3f} recall {recall:.3f} over {frames} frames; recall persons "
          f"{by_class[PERSON]:.3f} vehicle {by_class[CAR]:.3f}")
    assert precision >= least_precision and recall >= least_recall, (stage, precision, recall)
    # The depth-based stages catch the vehicle moving along its epipolar
    # lines too. Measured persons / vehicle: li 0.985 / 0.924 (0.991 / 0.930
    # at 15 px; the vehicle 0.77 without rigid_check), ddl 0.970 / 0.959
    # (0.963 / 0.738 without seed_sliding_surfaces).
    if stage in ("li", "ddl"):
        assert by_class[PERSON] >= 0.9 and by_class[CAR] >= 0.9, by_class
    assert stats["dynamic_filter"]["stage_failures"] == 0


SEEDS = (0, 1, 2)


@pytest.mark.parametrize("sensor", ["rgbd", "stereo", "mono"])
def test_full_within_1_2x_of_static_and_off_3x_worse(tmp_path, synth_seeds, sensor):
    """Over seeds 0-2, the median of full / static and of off / static."""
    full_ratio, off_ratio = [], []
    for seed in SEEDS:
        scenes = {(sensor, m): synth_seeds[sensor, m, seed] for m in (0, 3)}
        static = _run(tmp_path, scenes, sensor, 0, f"static{seed}")
        labels = str(scenes[sensor, 3] / "labels")
        full = _run(tmp_path, scenes, sensor, 3, f"full{seed}", dynamic="full", labels=labels)
        off = _run(tmp_path, scenes, sensor, 3, f"off{seed}")
        s, f = static["ate"]["rmse"], full["ate"]["rmse"]
        off_ate = (off.get("ate") or {}).get("rmse")
        print(f"{sensor} seed {seed}: static {s:.4f} full {f:.4f} ({f / s:.2f}x) off {off_ate} "
              f"tracked {static['tracked_frames']}/{full['tracked_frames']}/{off['tracked_frames']}")
        least_tracked = 0.9 if sensor == "mono" else 1.0
        assert full["tracked_frames"] >= least_tracked * static["tracked_frames"], seed
        full_ratio.append(f / s)
        # Not initialised, or lost for most of the clip, counts as failing.
        lost = off_ate is None or off["tracked_frames"] < 0.5 * static["tracked_frames"]
        off_ratio.append(float("inf") if lost else off_ate / s)
    full_median, off_median = float(np.median(full_ratio)), float(np.median(off_ratio))
    print(f"{sensor}: full/static median {full_median:.2f}, off/static median {off_median:.2f}")
    # Measured, full / static for seeds 0 / 1 / 2 (median); static ATE 2.1-5.5 mm:
    #   RGB-D  0.91 / 0.94 / 1.16 (0.94) with a Huber kernel in the last round of
    #          motion-only BA (TrackerOptions::pose_final_huber); before it
    #          1.11 / 1.07 / 1.21 (1.11) with the first frame's candidates
    #          dropped (Dynamic.semantic.drop_unchecked_rgbd); 1.05 / 1.28 /
    #          1.28 (1.28) before, 1.22 before the candidates' own corner
    #          quality, which over seeds 0-11 took the median 1.24 -> 1.18 and
    #          the worst seed 12.0 -> 1.40
    #   stereo 0.96 / 1.00 / 0.98 (0.98) with that Huber kernel (static 3.3 / 2.9
    #          / 3.1 mm); before it
    #          1.09 / 1.26 / 0.94 (1.09; 1.48 on seed 1 before later changes
    #          to the cues); 1.20 / 1.57 / 1.28 (1.28) before the
    #          right image's budget followed the mask (stereo_right_budget_max_factor);
    #          over seeds 0-12 the median went 1.26 -> 1.11
    #   mono   1.35 / 1.10 / 0.94 (1.10), 53-56 of 60 frames tracked (static: 55-56),
    #          at 8c64884 (the seeds suite's rows in docs/dynamic-frontend.md,
    #          the same at 8383949; seed 1's move not traced);
    #          1.34 / 0.84 / 0.90 (0.90) at 6c02b21,
    #          with the two-view initialiser trying the other model (seed 1 0.72
    #          over 53 frames before); 1.17 / 0.72 / 0.89 when first recorded (seed 0
    #          moved with later changes, not traced);
    #          1.19 / 1.06 / 1.00 (1.06) before frames left the 4x feature count
    #          once one tracks 1000 points (mono_init_release_tracked);
    #          1.24 / 1.07 / 1.00 with the backward LK check (Dynamic.motion_cues.mono: forward_backward_max)
    # off / static median: RGB-D 152, stereo 65, mono 8.2.
    assert full_median <= 1.2
    assert off_median >= 3


def test_li_without_semantic_input_within_1_5x(tmp_path, synth_seeds):
    """Over seeds 0-2, the median of li / static (no labels given), and the
    preset's keypoint precision / recall on each seed."""
    ratios, scores = [], []
    for seed in SEEDS:
        scenes = {("stereo", m): synth_seeds["stereo", m, seed] for m in (0, 3)}
        static = _run(tmp_path, scenes, "stereo", 0, f"static{seed}")
        masks = tmp_path / f"li{seed}_masks"
        li = _run(tmp_path, scenes, "stereo", 3, f"li{seed}", dynamic="li", save_masks=str(masks))
        assert li["tracked_frames"] == static["tracked_frames"], seed
        ratios.append(li["ate"]["rmse"] / static["ate"]["rmse"])
        scores.append(_keypoint_scores(scenes["stereo", 3], "stereo", masks)[:2])
    print("li / static, seeds 0-2:", [round(r, 2) for r in ratios], "precision / recall:",
          [(round(p, 3), round(r, 3)) for p, r in scores])
    # Keypoint precision / recall measured 0.900 / 0.962, 0.951 / 0.977,
    # 0.922 / 0.977; before F was fitted outside the previous frame's mask
    # (Dynamic.li.f_exclude_previous_dynamic) 0.901 / 0.959, 0.840 / 0.988,
    # 0.898 / 0.984. 0.89: room for another CPU's rounding in SGBM and LK.
    assert all(p >= 0.89 and r >= 0.9 for p, r in scores), scores
    assert float(np.median([p for p, _ in scores])) >= 0.9
    # Measured 0.98 / 1.40 / 1.13 (median 1.13) with a Huber kernel in the last
    # round of motion-only BA (TrackerOptions::pose_final_huber); before it
    # 1.73 / 1.28 / 1.05 (median 1.28; seeds 0-11 median 1.32),
    # 2.01 / 1.25 / 1.24 before f_exclude_previous_dynamic (1.25); 2.30
    # / 1.42 / 1.14 with foreground_band_px 15 (seeds 0-11 1.34); 2.20 /
    # 1.40 / 1.17 with whole rectangles (no foreground_only), 1.96 / 1.39 /
    # 0.99 without the backward LK check either. Without its
    # rigid_check 2.26 / 2.78 / 1.95; the paper's method alone (no addition)
    # 2.9x on seed 0.
    assert float(np.median(ratios)) <= 1.5


def test_li_on_a_static_street_marks_almost_nothing(tmp_path, data):
    """KITTI 06 has no movers in its 51 frames: li must leave the street to
    tracking. Without the preset's backward LK check, a quarter of the LK
    pairs there are mis-tracks that eq. 3 marks, and the kept rectangles
    covered 35-59 % of the image (median dynamic keypoints 38 %, ATE
    0.077-0.088 m against off's 0.050)."""
    stats = run_dataset(RunOptions(kind="kitti", path=str(data / "kitti" / "sequences" / "06"),
                                   sensor="stereo", out=str(tmp_path / "li"), progress=False,
                                   dynamic="li"))
    summary = stats["dynamic_filter"]["summary"]
    print("li on KITTI 06: dynamic fraction median", summary["dynamic_fraction_median"],
          "ATE", stats["ate"]["rmse"])
    assert stats["tracked_frames"] == 51
    # Measured: median 0.0 of the keypoints, ATE 0.057 m.
    assert summary["dynamic_fraction_median"] <= 0.05
    assert stats["ate"]["rmse"] <= 0.07


def test_an_epipolar_check_alone_cannot_reach_1_5x_here(tmp_path, synth_scenes):
    """Why li needs its rigid check for 1.5x: the vehicle travels beside the camera in its
    direction of motion, so its points stay on their epipolar lines, and it is
    the vehicle that drags the pose. Even the persons' exact masks, with the
    vehicle left in (what a perfect epipolar detector could give), stay far
    from 1.5x; the vehicle's mask alone, with the persons left in, is close."""
    seq = synth_scenes["stereo", 3]
    static = _run(tmp_path, synth_scenes, "stereo", 0, "static")["ate"]["rmse"]
    ratio = {}
    for name, label in (("persons", PERSON), ("vehicle", CAR)):
        masks = tmp_path / name
        masks.mkdir()
        for truth_file in sorted((seq / "dynamic_masks").glob("*.png")):
            truth = cv2.imread(str(truth_file), cv2.IMREAD_UNCHANGED) > 0
            labels = cv2.imread(str(seq / "labels" / truth_file.name), cv2.IMREAD_UNCHANGED)
            cv2.imwrite(str(masks / truth_file.name), ((truth & (labels == label)) * 255).astype(np.uint8))
        ratio[name] = _run(tmp_path, synth_scenes, "stereo", 3, name, masks=str(masks))["ate"]["rmse"] / static
    print(f"ATE / static with the exact masks of the persons only {ratio['persons']:.2f}, "
          f"of the vehicle only {ratio['vehicle']:.2f}")
    # Measured (seed 0): persons only 2.48x, vehicle only 0.86x; with plain
    # least squares in motion-only BA's last round (TrackerOptions::
    # pose_final_huber 0) 3.05x / 1.07x, 4.33x / 1.13x before later changes.
    # 2.0: well clear of the 1.5x the persons' masks alone would have to reach.
    assert ratio["persons"] > 2.0 and ratio["vehicle"] < 1.5, ratio


def test_parked_car_keeps_its_features_under_dm(tmp_path, synth_scenes):
    seq = synth_scenes["rgbd", 3]
    masks = tmp_path / "masks"
    _run(tmp_path, synth_scenes, "rgbd", 3, "dm", dynamic="dm", labels=str(seq / "labels"), save_masks=str(masks))
    marked = seen = 0
    for image in _frames(seq, "rgbd")[1:]:
        labels = cv2.imread(str(seq / "labels" / image.name), cv2.IMREAD_UNCHANGED)
        truth = cv2.imread(str(seq / "dynamic_masks" / image.name), cv2.IMREAD_UNCHANGED) > 0
        parked = (labels == CAR) & ~cv2.dilate(truth.astype(np.uint8), np.ones((31, 31), np.uint8)).astype(bool)
        if parked.sum() < 500:
            continue
        seen += 1
        predicted = cv2.imread(str(masks / image.name), cv2.IMREAD_UNCHANGED) > 0
        marked += (predicted & parked).sum() > 0.2 * parked.sum()
    assert seen >= 10
    assert marked <= 0.05 * seen, (marked, seen)
