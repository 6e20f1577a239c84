"""ATE and RPE through evo (no hand-written error metric here)."""
from __future__ import annotations

import copy
import logging
import dataclasses
import pathlib

import numpy as np
from evo.core import metrics, sync
from evo.core import trajectory as evo_traj
from evo.core.units import Unit
from evo.main_ape import ape
from evo.main_rpe import rpe

from dynaorb.evaluation.trajectories import TrajectoryFormatError, load_trajectory

logging.getLogger("evo").setLevel(logging.WARNING)  # evo prints every result at INFO

STAT_KEYS = ("rmse", "mean", "median", "std", "min", "max")


@dataclasses.dataclass
class EvalResult:
    align: str
    matched_poses: int
    reference_poses: int
    estimate_poses: int
    ate: dict                       # metres: rmse mean median std min max
    rpe_trans: dict | None = None   # metres per delta
    rpe_rot: dict | None = None     # degrees per delta
    rpe_percent: dict | None = None # RPE translation / delta, % (delta in metres)
    rpe_delta: float | None = None
    rpe_unit: str | None = None
    scale: float | None = None      # Sim3 scale, when aligned with sim3
    plots: list = dataclasses.field(default_factory=list)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def table(self) -> str:
        rows = [("ATE [m]", self.ate)]
        if self.rpe_trans:
            unit = "m" if self.rpe_unit == "m" else "frames"
            rows.append((f"RPE trans [m / {self.rpe_delta:g} {unit}]", self.rpe_trans))
            rows.append((f"RPE rot [deg / {self.rpe_delta:g} {unit}]", self.rpe_rot))
        if self.rpe_percent:
            rows.append(("RPE trans [%]", self.rpe_percent))
        width = max(len(name) for name, _ in rows)
        lines = [f"{'':{width}}  " + "  ".join(f"{k:>9}" for k in STAT_KEYS)]
        for name, stats in rows:
            lines.append(f"{name:{width}}  " + "  ".join(f"{stats[k]:9.4f}" for k in STAT_KEYS))
        head = (f"poses: {self.matched_poses} matched (reference {self.reference_poses}, "
                f"estimate {self.estimate_poses}); alignment: {self.align}")
        if self.scale is not None:
            head += f", scale {self.scale:.4f}"
        return head + "\n" + "\n".join(lines)


def _stats(result) -> dict:
    return {k: float(result.stats[k]) for k in STAT_KEYS}


def _match(ref, est, max_diff: float):
    stamped = isinstance(ref, evo_traj.PoseTrajectory3D) and isinstance(est, evo_traj.PoseTrajectory3D)
    if stamped:
        try:
            return sync.associate_trajectories(ref, est, max_diff=max_diff)
        except sync.SyncException as exc:
            raise TrajectoryFormatError(f"no poses match within {max_diff} s: {exc}") from None
    if ref.num_poses != est.num_poses:
        raise TrajectoryFormatError(
            f"unstamped trajectories must have equal length ({ref.num_poses} vs {est.num_poses}); "
            "give KITTI ground truth its times.txt (ROOT/sequences/NN/times.txt) or use TUM files")
    return ref, est


def evaluate(reference, estimate, *, align: str = "se3", rpe_delta: float | None = 1.0,
             rpe_unit: str = "frames", max_diff: float = 0.02, plot_dir=None) -> EvalResult:
    """ATE (and RPE when rpe_delta is given) of `estimate` against `reference`.

    reference / estimate: paths (any format load_trajectory reads) or evo trajectories.
    align: "se3" (Umeyama without scale), "sim3" (with scale, monocular) or "none".
    """
    if align not in ("se3", "sim3", "none"):
        raise ValueError(f"align must be se3, sim3 or none, not {align!r}")
    ref = load_trajectory(reference) if not hasattr(reference, "poses_se3") else reference
    est = load_trajectory(estimate) if not hasattr(estimate, "poses_se3") else estimate
    n_ref, n_est = ref.num_poses, est.num_poses
    ref, est = _match(ref, est, max_diff)
    if ref.num_poses < 3:
        raise TrajectoryFormatError(f"only {ref.num_poses} poses match: too few to evaluate")
    do_align, scale = align != "none", align == "sim3"

    # evo aligns the estimate in place: every metric gets its own copy.
    ate = ape(copy.deepcopy(ref), copy.deepcopy(est), metrics.PoseRelation.translation_part, align=do_align,
              correct_scale=scale)
    result = EvalResult(align=align, matched_poses=ref.num_poses, reference_poses=n_ref,
                        estimate_poses=n_est, ate=_stats(ate))
    alignment = ate.np_arrays.get("alignment_transformation_sim3")  # set when aligned
    if scale:
        result.scale = float(np.linalg.norm(alignment[:3, 0]))  # sim3 block is s * R

    if rpe_delta is not None:
        unit = {"frames": Unit.frames, "f": Unit.frames, "m": Unit.meters}[rpe_unit]
        common = dict(delta=rpe_delta, delta_unit=unit, all_pairs=True, align=do_align, correct_scale=scale)
        try:
            trans = rpe(copy.deepcopy(ref), copy.deepcopy(est), metrics.PoseRelation.translation_part, **common)
            rot = rpe(copy.deepcopy(ref), copy.deepcopy(est), metrics.PoseRelation.rotation_angle_deg, **common)
            result.rpe_trans, result.rpe_rot = _stats(trans), _stats(rot)
            result.rpe_delta, result.rpe_unit = float(rpe_delta), "m" if unit == Unit.meters else "frames"
            if unit == Unit.meters:  # pairs span delta metres (within evo's 10 % tolerance)
                result.rpe_percent = {k: 100.0 * v / rpe_delta for k, v in result.rpe_trans.items()}
        except Exception as exc:  # evo raises plain exceptions when no pair spans delta
            raise TrajectoryFormatError(f"RPE with delta {rpe_delta} {rpe_unit}: {exc}") from None

    if plot_dir is not None:
        from dynaorb.evaluation.plots import save_plots

        result.plots = save_plots(ref, est, ate, pathlib.Path(plot_dir), alignment=alignment)
    return result
