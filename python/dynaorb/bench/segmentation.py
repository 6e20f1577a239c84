"""`dynaorb bench --suite segmentation`: network latency and SLAM speed with segmentation.

1. Latency of every model in a folder, per back end (ONNX, TFLite) and thread
   count (1, 2): median over runs of the network alone and of the whole
   segment() call (with resizing), on a real 640x480 TUM frame.
2. SLAM on one sequence as a live camera runs it (local mapping in its own
   thread) without segmentation, with synchronous segmentation (every frame
   waits for the network) and with asynchronous segmentation (network on its
   own thread, masks propagated): fps of the whole loop, median
   tracking-thread ms per frame, mask ages, in one process so the ratios
   compare like with like.
"""
from __future__ import annotations

import json
import pathlib
import statistics

import cv2

from dynaorb.bench.report import markdown_table
from dynaorb.segmentation import Segmenter

BENCH_FRAME = "tum/rgbd_dataset_freiburg3_walking_xyz_fragment/rgb/1341846313.592026.png"


def model_latency(models_dir: pathlib.Path, image, runs: int, threads=(1, 2)) -> list[dict]:
    rows = []
    for model in sorted(p for p in models_dir.iterdir() if p.suffix in (".onnx", ".tflite")):
        for n in threads:
            seg = Segmenter(model, threads=n)
            seg.segment(image)  # warm-up: first-run allocations
            net, total = [], []
            for _ in range(runs):
                r = seg.segment(image)
                net.append(r.inference_ms)
                total.append(r.total_ms)
            rows.append({"model": model.stem, "backend": seg.card.backend, "threads": n,
                         "network_ms_median": statistics.median(net), "total_ms_median": statistics.median(total)})
    return rows


def slam_speed(kind: str, path: str, model: pathlib.Path, out: pathlib.Path) -> list[dict]:
    from dynaorb.runner import RunOptions, run_dataset

    rows = []
    for label, segment, mode in (("no segmentation", None, "async"), ("synchronous", str(model), "sync"),
                                 ("asynchronous", str(model), "async")):
        stats = run_dataset(RunOptions(kind=kind, path=path, out=str(out / label.replace(" ", "_")),
                                       progress=False, segment=segment, segment_mode=mode,
                                       synchronous_mapping=False))
        seg = stats.get("segmentation") or {}
        rows.append({"run": label, "fps": stats["fps"], "frame_ms_median": stats["stage_ms_median"]["frame_total"],
                     "tracked": f"{stats['tracked_frames']}/{stats['frames']}",
                     "mask_frames": seg.get("frames"), "mask_age_median": seg.get("age_median"),
                     "propagate_ms_median": seg.get("propagate_ms_median")})
    base = rows[0]["fps"]
    for r in rows:
        r["fps_ratio_to_no_segmentation"] = r["fps"] / base if base else None
    return rows


def markdown(latency: list[dict], slam: list[dict], sequence: str, model: str) -> str:
    lines = ["# Segmentation benchmark", "", "## Network latency (640x480 TUM frame, median)", ""]
    lines += markdown_table(["model", "back end", "threads", "network ms", "segment() ms"],
                            ([r["model"], r["backend"], r["threads"], f"{r['network_ms_median']:.1f}",
                              f"{r['total_ms_median']:.1f}"] for r in latency))
    lines += ["", f"## SLAM with segmentation ({sequence}, model {model})", ""]
    lines += markdown_table(
        ["run", "fps", "fps / no segmentation", "tracking ms/frame (median)", "tracked", "mask age (median)"],
        ([r["run"], f"{r['fps']:.1f}", f"{r['fps_ratio_to_no_segmentation']:.2f}", f"{r['frame_ms_median']:.1f}",
          r["tracked"], "" if r["mask_age_median"] is None else f"{r['mask_age_median']:.0f}"] for r in slam))
    return "\n".join(lines) + "\n"


def run(out: str, models_dir: str, data_dir: str, runs: int = 10, sequence: tuple[str, str] | None = None,
        model: str | None = None) -> dict:
    out_dir = pathlib.Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    models = pathlib.Path(models_dir)
    image_path = pathlib.Path(data_dir) / BENCH_FRAME
    image = cv2.imread(str(image_path))
    if image is None:
        raise FileNotFoundError(f"{image_path}: benchmark frame not found")
    latency = model_latency(models, image, runs)
    if sequence is None:
        from dynaorb.synth import SynthConfig, generate

        seq_dir = out_dir / "synth_rgbd"
        if not (seq_dir / "rgb.txt").is_file():
            generate(seq_dir, SynthConfig(sensor="rgbd", movers=3, frames=60, seed=0))
        sequence = ("tum", str(seq_dir))
    model_path = pathlib.Path(model) if model else models / "deeplabv3_mnv2_dm05_pascal_quant.onnx"
    slam = slam_speed(sequence[0], sequence[1], model_path, out_dir / "runs")
    result = {"latency": latency, "slam": slam, "sequence": list(sequence), "model": str(model_path),
              "runs": runs}
    (out_dir / "segmentation.json").write_text(json.dumps(result, indent=2))
    (out_dir / "segmentation.md").write_text(markdown(latency, slam, sequence[1], model_path.name))
    return result
