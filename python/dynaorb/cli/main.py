"""dynaorb command line: run, eval, synth, demo, config, models, segment, vocab, bench, bag."""
from __future__ import annotations

import argparse
import logging
import sys

from dynaorb.cli import commands


def _bag_input_args(p: argparse.ArgumentParser) -> None:
    """What `bag run` and `bag to-dataset` read from a bag."""
    p.add_argument("--config", help="ORB-SLAM2 settings YAML (default: BAG-stem.settings.yaml, else the "
                                    "intrinsics of the bag's camera_info with ORB-SLAM2's extractor values)")
    p.add_argument("--sensor", choices=["mono", "stereo", "rgbd"], help="default: the richest the topics allow")
    p.add_argument("--topic", action="append", default=[], metavar="ROLE=TOPIC",
                   help="topic of a role (image, right, depth, labels); default: TUM, KITTI-style stereo or "
                        "EuRoC names found in the bag")
    gt = p.add_mutually_exclusive_group()
    gt.add_argument("--ground-truth", help="TUM file (default: BAG-stem.groundtruth.tum when present)")
    gt.add_argument("--ground-truth-topic", metavar="TOPIC",
                    help="ground truth from a pose topic of the bag (PoseStamped, PoseWithCovarianceStamped, "
                         "TransformStamped or Odometry), taken as it is")
    gt.add_argument("--ground-truth-tf", metavar="PARENT:CHILD",
                    help="ground truth from the bag's TF: CHILD's pose in PARENT where a transform joins them "
                         "directly (TUM's bags: world:kinect)")
    p.add_argument("--no-labels", action="store_true", help="ignore a labels topic in the bag")
    p.add_argument("--max-diff", type=float, default=0.02, help="RGB-D colour/depth association [s]")


def _runner_args(p: argparse.ArgumentParser, default_out: str) -> None:
    """What `run` and `bag run` hand the runner (RunOptions): outputs, the dynamic
    front end, segmentation, mapping, pacing, maps and the core's options.
    Per-frame folders are named like the frames: a dataset's image names, a
    bag's frames by stamp (<stamp>.png, 6 decimals, as `bag to-dataset` names
    TUM-layout images)."""
    p.add_argument("--out", default=default_out, help=f"output folder (default {default_out})")
    p.add_argument("--frames", metavar="START:END",
                   help="run only these frames (numbers from 0, END not included; '500:' or ':300' leave a side "
                        "open); the outputs and the evaluation cover them")
    p.add_argument("--dynamic", default="off", metavar="PRESET|FILE",
                   help="dynamic-object front end: a preset of config/dynamic/ (off, stdyn, dm, ddl, li, full) "
                        "or a preset YAML file (default off)")
    p.add_argument("--labels", metavar="DIR",
                   help="label images (class ids) named like the frames (a bag's: <stamp>.png) for the dynamic "
                        "filter's semantic stage: a `dynaorb segment` folder (labels.json names the movable ids) or a folder in the "
                        "preset's label set (e.g. a synthetic sequence's labels/, PASCAL VOC ids)")
    p.add_argument("--labels-delay", type=int, default=0, metavar="N",
                   help="emulate a segmentation network N frames behind the camera on the --labels folder: "
                        "each frame gets the newest labels it would have finished, moved by optical flow "
                        "(default 0: every frame its own labels)")
    p.add_argument("--no-label-propagation", action="store_true",
                   help="with --labels-delay (or --segment, async): use older labels as they are, not moved "
                        "by optical flow")
    p.add_argument("--save-masks", metavar="DIR",
                   help="write the dynamic filter's mask of every frame here (PNG named like the frame; a "
                        "bag's: <stamp>.png)")
    p.add_argument("--masks", help="folder of per-frame exclusion masks / label images named like the frames "
                                   "(a bag's: <stamp>.png; a `dynaorb segment` cache: its movable classes are "
                                   "masked; ground-truth masks)")
    p.add_argument("--vocabulary", default="default", metavar="FILE|default|none",
                   help="bag-of-words vocabulary for relocalisation and loop closing (default: dynaorb's own, "
                        "built on first use with `dynaorb vocab default`; or a binary / ORBvoc.txt file; "
                        "none: without; --load-map needs one)")
    p.add_argument("--segment", metavar="MODEL",
                   help="segment in-process with this model (file or name from `dynaorb models list`); "
                        "its movable classes are masked, or, with a --dynamic preset, its labels feed the "
                        "filter's semantic stage (a bag's labels topic is then not read)")
    p.add_argument("--segment-mode", choices=["async", "sync"], default="async",
                   help="async (default): the network runs on its own thread on the newest frame and "
                        "older masks are propagated by optical flow; sync: every frame waits for its mask")
    p.add_argument("--segment-threads", type=int, default=1,
                   help="network threads (default 1: the tracking thread keeps a core)")
    p.add_argument("--segment-nice", type=int, choices=range(0, 20), metavar="0-19", default=10,
                   help="async: nice value of the network's thread above tracking's, so tracking gets the "
                        "CPU first on a busy machine and the network what is left (default 10; 0: the same "
                        "priority as tracking)")
    p.add_argument("--max-mask-age", type=int, default=30,
                   help="frames a propagated mask stays usable (default 30)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--async-mapping", action="store_true",
                   help="run local mapping concurrently as on a live camera (default: each keyframe is "
                        "mapped before the next frame, which makes runs repeatable)")
    p.add_argument("--realtime", type=float, nargs="?", const=1.0, default=0.0, metavar="RATE",
                   help="deliver the frames at RATE x the recording's rate (by their stamps; default 1 when "
                        "given), as a live camera would; with --async-mapping this gives local mapping the "
                        "time between frames that a camera gives it (default: as fast as tracking goes)")
    p.add_argument("--background-nice", type=int, choices=range(0, 20), metavar="0-19", default=None,
                   help="nice value of the local mapping, loop closing and global BA threads above the "
                        "process's, so tracking gets the CPU first on a busy machine (default 10; 0: the "
                        "same priority as tracking)")
    p.add_argument("--save-map", metavar="OUT.map", help="write the map to this file after the run")
    p.add_argument("--load-map", metavar="IN.map",
                   help="start from a saved map (the first frame is relocalised in it; needs a vocabulary)")
    p.add_argument("--localization", action="store_true",
                   help="localisation only: track in the map, no new keyframes or map points "
                        "(with --load-map)")
    p.add_argument("--tracker", metavar="KEY=VALUE", action="append", default=[],
                   help="a tracking option (a field of dynaorb._core.TrackerOptions), repeatable; e.g. "
                        "--tracker mono_init_feature_factor=5 --tracker mono_init_feature_frames=40")
    p.add_argument("--mapping", metavar="KEY=VALUE", action="append", default=[],
                   help="a local mapping option (a field of dynaorb._core.LocalMapperOptions), repeatable; "
                        "e.g. --mapping neighbors_stereo=15")
    p.add_argument("--loop", metavar="KEY=VALUE", action="append", default=[],
                   help="a loop closing option (a field of dynaorb._core.LoopCloserOptions; ransac.NAME for "
                        "its Sim3RansacOptions), repeatable; e.g. --loop min_projection_matches=50")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dynaorb", description="Visual SLAM for dynamic scenes.")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run SLAM on a dataset sequence")
    r.add_argument("kind", choices=["tum", "kitti", "euroc"])
    r.add_argument("path", help="TUM sequence folder, KITTI ROOT/sequences/NN, or EuRoC folder (with mav0)")
    r.add_argument("--sensor", choices=["mono", "stereo", "rgbd"], help="default: the richest the dataset has")
    r.add_argument("--config", help="ORB-SLAM2 settings YAML (default: from the dataset's calibration)")
    _runner_args(r, default_out="out/run")
    r.set_defaults(func=commands.cmd_run)

    e = sub.add_parser("eval", help="ATE / RPE of an estimate against ground truth (evo)")
    e.add_argument("gt", help="ground truth: TUM file or folder, KITTI poses file, EuRoC data.csv or folder")
    e.add_argument("est", help="estimate: TUM or KITTI file")
    e.add_argument("--align", choices=["se3", "sim3", "none"], default="se3")
    e.add_argument("--rpe", type=float, metavar="DELTA", help="RPE over DELTA (frames, or metres with --rpe-unit m)")
    e.add_argument("--rpe-unit", choices=["frames", "m"], default="frames")
    e.add_argument("--max-diff", type=float, default=0.02, help="stamp association tolerance [s]")
    e.add_argument("--plot", metavar="DIR", help="write trajectory and error plots here")
    e.add_argument("--json", action="store_true", help="print JSON instead of a table")
    e.set_defaults(func=commands.cmd_eval)

    s = sub.add_parser("synth", help="render a synthetic dynamic sequence with exact ground truth")
    s.add_argument("out")
    s.add_argument("--sensor", choices=["rgbd", "stereo", "mono"], default="rgbd")
    s.add_argument("--movers", type=int, default=3, help="moving objects (0: static scene)")
    s.add_argument("--frames", type=int, default=90)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--width", type=int, default=640)
    s.add_argument("--height", type=int, default=480)
    s.add_argument("--textures", help="folder of real images used as textures (default ../shared/data)")
    s.add_argument("--quiet", action="store_true")
    s.set_defaults(func=commands.cmd_synth)

    d = sub.add_parser("demo", help="the built-in default: synthetic RGB-D sequences, static and dynamic")
    d.add_argument("--out", default="out/demo")
    d.add_argument("--frames", type=int, default=60)
    d.add_argument("--seed", type=int, default=0)
    d.set_defaults(func=commands.cmd_demo)

    m = sub.add_parser("models", help="segmentation models: list them, fetch them into the cache")
    msub = m.add_subparsers(dest="models_command", required=True)
    ml = msub.add_parser("list", help="known models and what is installed")
    ml.add_argument("--cache", help="model cache (default $DYNAORB_MODEL_CACHE or ~/.cache/dynaorb/models)")
    ml.set_defaults(func=commands.cmd_models_list)
    mf = msub.add_parser("fetch", help="download (or copy) the public models, verify, convert")
    mf.add_argument("names", nargs="*", help="models to fetch (default: all)")
    mf.add_argument("--from", dest="from_dir", metavar="DIR",
                    help="install from a local folder holding the files instead of downloading")
    mf.add_argument("--cache", help="model cache (default $DYNAORB_MODEL_CACHE or ~/.cache/dynaorb/models)")
    mf.add_argument("--force", action="store_true", help="fetch again even when cached")
    mf.add_argument("--quiet", action="store_true")
    mf.set_defaults(func=commands.cmd_models_fetch)

    g = sub.add_parser("segment", help="write label images for a whole sequence (a mask cache for --masks)")
    g.add_argument("kind", choices=["tum", "kitti", "euroc"])
    g.add_argument("path")
    g.add_argument("--model", help="model file or name (default: the default model from the cache)")
    g.add_argument("--out", required=True, help="folder for the label PNGs and labels.json")
    g.add_argument("--threads", type=int, default=2)
    g.add_argument("--overwrite", action="store_true", help="segment frames already in the cache again")
    g.add_argument("--quiet", action="store_true")
    g.set_defaults(func=commands.cmd_segment)

    v = sub.add_parser("vocab", help="bag-of-words vocabularies: train one, build the default")
    vsub = v.add_subparsers(dest="vocab_command", required=True)
    vt = vsub.add_parser("train", help="train a vocabulary on images (files or folders)")
    vt.add_argument("images", nargs="+", help="image files or folders (searched recursively)")
    vt.add_argument("-k", type=int, default=10, help="branching factor (default 10)")
    vt.add_argument("-L", type=int, default=6, help="depth (default 6)")
    vt.add_argument("-o", "--output", required=True, help="vocabulary file: binary, or ORBvoc text if .txt")
    vt.add_argument("--seed", type=int, default=0)
    vt.add_argument("--config", help="settings YAML whose ORBextractor.* parameters are used "
                                     "(default config/TUM3.yaml: ORB-SLAM2's defaults)")
    vt.add_argument("--max-images", type=int, help="use at most this many images, spread over all given")
    vt.add_argument("--quiet", action="store_true")
    vt.set_defaults(func=commands.cmd_vocab_train)
    vd = vsub.add_parser("default", help="path of the default vocabulary, trained on rendered sequences "
                                         "and cached the first time")
    vd.add_argument("--force", action="store_true", help="train it again")
    vd.set_defaults(func=commands.cmd_vocab_default)

    b = sub.add_parser("bench", help="benchmarks (speed as medians; JSON and a Markdown report)")
    b.add_argument("--suite", choices=["segmentation", "quick", "full", "long", "seeds"],
                   help="segmentation: network latency per model, back end and thread count, and SLAM "
                        "fps without / with synchronous / with asynchronous segmentation; quick: a few "
                        "sequences (EuRoC V1_01 stereo, KITTI 06, synthetic RGB-D and stereo with movers); "
                        "full: every sequence and sensor of ../shared/data and the synthetic suite with and "
                        "without movers; both in off mode and every dynamic preset, against ORB-SLAM3; "
                        "long: a 1500-frame synthetic walk down a 62 m room, stereo and monocular, off and full, "
                        "against ORB-SLAM3 (rendered once, about 2 min on two cores); "
                        "seeds: the end-to-end accuracy targets (full, ground-truth masks and off against the "
                        "static room) over many synthetic seeds per sensor (OUT/seeds.md)")
    b.add_argument("--out", default="out/bench", help="output folder (default out/bench)")
    b.add_argument("--runs", type=int, help="runs per case (quick/full/long, default 3) or timed runs per model and "
                                            "thread count (segmentation, default 10)")
    b.add_argument("--seeds", default="12", metavar="N|A-B|LIST",
                   help="seeds: how many (0..N-1), a range or a comma list (default 12)")
    b.add_argument("--sensors", default="rgbd,stereo,mono", help="seeds: comma list (default rgbd,stereo,mono)")
    b.add_argument("--conditions", default="static,full,masks,off",
                   help="seeds: comma list of static (no movers), full (movers, --preset with the label images), "
                        "masks (movers, ground-truth masks), off (movers, no filter), full_static (no movers, --preset with "
                        "the label images), peer_static / peer_movers "
                        "(ORB-SLAM3 without / with the movers, compared seed by seed: ATE, and with --realtime speed); static is required")
    b.add_argument("--preset", default="full",
                   help="seeds: what the full and full_static conditions run, a preset name or YAML file (default full)")
    b.add_argument("--synth-root", metavar="DIR",
                   help="seeds, quick/full/long: where the rendered sequences are cached (default OUT/synth)")
    b.add_argument("--jobs", type=int, default=1,
                   help="seeds: runs at a time (default 1; the runs map synchronously, so their ATE does not "
                        "depend on it; 1 with --realtime)")
    for flag, what in (("--tracker", "tracking"), ("--mapping", "local mapping"), ("--loop", "loop closing")):
        b.add_argument(flag, metavar="KEY=VALUE", action="append", default=[],
                       help=f"seeds: a {what} option for every dynaorb run, as `dynaorb run {flag}` "
                            "(repeatable; a variant under test against the defaults of another --out)")
    b.add_argument("--only", metavar="SEQ[,SEQ...]",
                   help="quick/full/long: only these sequences of the suite, as NAME (every sensor) or "
                        "NAME:SENSOR, e.g. synth/mono_m3 or euroc/MH_05_difficult_head:mono (one clip again "
                        "with more --runs)")
    b.add_argument("--presets", metavar="PRESET[,PRESET...]",
                   help="quick/full/long: only these dynamic presets beside `off` (default: every preset)")
    b.add_argument("--no-peer", action="store_true", help="quick/full/long: without the ORB-SLAM3 comparison")
    b.add_argument("--realtime", type=float, nargs="?", const=1.0, default=0.0, metavar="RATE",
                   help="quick/full/long: deliver the frames to dynaorb and to ORB-SLAM3 alike at RATE times the "
                        "recording's rate by their stamps (default without the option: as fast as the track "
                        "calls take them; the option alone: 1, as a camera or `rosbag play` delivers them); "
                        "seeds: the same pacing with asynchronous mapping instead of synchronous (as users' runs; "
                        "runs do not repeat; --jobs 1)")
    b.add_argument("--peer-venv", metavar="DIR",
                   help="quick/full/long/seeds: virtual environment for pyorbslam3 (default ~/.cache/dynaorb/peer/orbslam3-venv; "
                        "created and installed on first use)")
    b.add_argument("--readme", action="store_true",
                   help="write the README's Results section from OUT/results.json (after the run; "
                        "alone, without --suite, from a finished run)")
    b.add_argument("--resume", action="store_true",
                   help="quick/full/long/seeds: take each run whose OUT/runs folder holds a record for the same spec from "
                        "there instead of running it again (a bench stopped part way goes on where it stopped; "
                        "the reused runs' times are from when they ran)")
    b.add_argument("--report-only", action="store_true",
                   help="render OUT/report.md again from OUT/results.json without running anything")
    b.add_argument("--models", help="folder of models (default ../shared/models/segmentation, else the cache)")
    b.add_argument("--model", help="model for the SLAM runs (default the dm05 PASCAL model of --models); "
                                   "quick/full: run asynchronously for the presets with a semantic stage on "
                                   "sequences without label images")
    b.add_argument("--no-network", action="store_true",
                   help="quick/full: no segmentation network (the semantic stage sees no labels on real data)")
    b.add_argument("--sequence", nargs=2, metavar=("KIND", "PATH"),
                   help="sequence for the SLAM runs (default: a synthetic 60-frame RGB-D sequence)")
    b.set_defaults(func=commands.cmd_bench)

    bg = sub.add_parser("bag", help="ROS 1 bags: write a dataset sequence as a bag, run SLAM on a bag")
    bsub = bg.add_subparsers(dest="bag_command", required=True)
    bf = bsub.add_parser("from-dataset", help="write a TUM, KITTI or EuRoC sequence as a ROS 1 bag (rosbags), "
                                              "with BAG-stem.settings.yaml and BAG-stem.groundtruth.tum beside it")
    bf.add_argument("kind", choices=["tum", "kitti", "euroc"])
    bf.add_argument("path", help="TUM sequence folder, KITTI ROOT/sequences/NN, or EuRoC folder (with mav0)")
    bf.add_argument("-o", "--output", required=True, metavar="BAG")
    bf.add_argument("--sensor", choices=["mono", "stereo", "rgbd"], help="default: the richest the dataset has")
    bf.add_argument("--depth-encoding", choices=["32FC1", "16UC1"], default="32FC1",
                    help="RGB-D depth: 32FC1 metres with NaN for no depth, as TUM's bags (default), or 16UC1 "
                         "in the PNGs' units (DepthMapFactor)")
    bf.add_argument("--labels", metavar="DIR", help="folder of per-frame label images named like the frames "
                                                    "(e.g. `dynaorb synth`'s labels/): written on the labels topic")
    bf.add_argument("--stamp-offset", type=float, help="seconds added to every stamp (default: 1 for sequences "
                                                       "starting below 1 s, as KITTI's, else 0)")
    bf.add_argument("--max-frames", type=int, help="only the first N frames")
    bf.add_argument("--image-transport", choices=["raw", "compressed"], default="raw",
                    help="compressed: images as image_transport records them, CompressedImage on TOPIC/compressed "
                         "and depth on TOPIC/compressedDepth (default raw)")
    bf.add_argument("--image-format", choices=["png", "jpeg"], default="png",
                    help="compressed images: png (lossless, default) or jpeg; labels and depth are always png")
    bf.add_argument("--quiet", action="store_true")
    bf.set_defaults(func=commands.cmd_bag_from_dataset)
    br = bsub.add_parser("run", help="run SLAM on a bag serially: every frame in stamp order (repeatable unless "
                                     "--async-mapping; --realtime paces them)")
    br.add_argument("bag", nargs="+", help="a bag, or the parts of a split recording (read as one)")
    _bag_input_args(br)
    _runner_args(br, default_out="out/bag")
    br.set_defaults(func=commands.cmd_bag_run)
    bi = bsub.add_parser("info", help="what a bag holds and what `bag run` would take from it (topics by role, "
                                      "sensor, frames, settings, ground truth)")
    bi.add_argument("bag", nargs="+", help="a bag, or the parts of a split recording (read as one)")
    _bag_input_args(bi)
    bi.add_argument("--json", action="store_true", help="print it as JSON")
    bi.set_defaults(func=commands.cmd_bag_info)
    bt = bsub.add_parser("to-dataset", help="write a bag's frames as a dataset folder: RGB-D in TUM's layout, "
                                            "stereo and mono in KITTI's, with settings and ground truth")
    bt.add_argument("bag", nargs="+", help="a bag, or the parts of a split recording (read as one)")
    bt.add_argument("-o", "--output", required=True, metavar="DIR")
    _bag_input_args(bt)
    bt.add_argument("--ground-truth-max-gap", type=float, default=0.1, metavar="S",
                    help="KITTI poses: ground truth interpolated at the frame stamps across gaps up to this "
                         "(default 0.1 s)")
    bt.add_argument("--overwrite", action="store_true", help="replace DIR when it is not empty")
    bt.add_argument("--quiet", action="store_true")
    bt.set_defaults(func=commands.cmd_bag_to_dataset)

    c = sub.add_parser("config", help="write the settings derived from a dataset's calibration")
    c.add_argument("kind", choices=["tum", "kitti", "euroc"])
    c.add_argument("path")
    c.add_argument("-o", "--output", required=True)
    c.add_argument("--sensor", choices=["mono", "stereo", "rgbd"])
    c.set_defaults(func=commands.cmd_config)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return args.func(args) or 0
    except (ValueError, FileNotFoundError, FileExistsError, ConnectionError) as exc:  # InputError is a ValueError
        print(f"dynaorb {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
