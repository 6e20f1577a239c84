"""Trajectory and error plots (matplotlib, headless Agg backend)."""
from __future__ import annotations

import copy
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def save_plots(ref, est, ate_result, out: pathlib.Path, *, alignment=None) -> list[str]:
    """trajectory.png (top and side view, estimate under the ATE's own alignment, a 4x4
    sim3 matrix or None) and ate.png (error over time)."""
    out.mkdir(parents=True, exist_ok=True)
    est = copy.deepcopy(est)
    if alignment is not None:
        est.transform(alignment)
    a, b = ref.positions_xyz, est.positions_xyz
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for ax, (i, j, name) in zip(axes, [(0, 1, "x-y"), (0, 2, "x-z")]):
        ax.plot(a[:, i], a[:, j], "k-", label="ground truth")
        ax.plot(b[:, i], b[:, j], "r-", label="estimate")
        ax.set_title(f"trajectory ({name})")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True)
    axes[0].legend()
    fig.tight_layout()
    paths = [out / "trajectory.png"]
    fig.savefig(paths[0], dpi=110)
    plt.close(fig)

    errors = ate_result.np_arrays["error_array"]
    t = getattr(est, "timestamps", np.arange(len(errors)))
    t = np.asarray(t, dtype=float) - float(t[0])
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(t, errors, "b-")
    ax.axhline(ate_result.stats["rmse"], color="r", linestyle="--", label=f"RMSE {ate_result.stats['rmse']:.4f} m")
    ax.set_xlabel("time [s]" if hasattr(est, "timestamps") else "pose")
    ax.set_ylabel("ATE [m]")
    ax.legend()
    ax.grid(True)
    fig.tight_layout()
    paths.append(out / "ate.png")
    fig.savefig(paths[1], dpi=110)
    plt.close(fig)
    return [str(p) for p in paths]
