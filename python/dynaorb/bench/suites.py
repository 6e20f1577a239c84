"""The cases of `dynaorb bench --suite quick|full|long`: (sequence, sensor, dynamic preset).

Every sequence runs in `off` mode and with every preset of config/dynamic/
that has a stage for its sensor; pairs a preset cannot run (no stage for the
sensor, or a stage the sensor does not support) are listed with the reason,
not dropped. Synthetic sequences carry label images (PASCAL VOC ids, what a
segmentation network outputs) for the presets' semantic stage; the real
sequences have none, so there the semantic stage has nothing to mark and only
the presets' geometric stages act (said in the report).
"""
from __future__ import annotations

import dataclasses
import pathlib

from dynaorb.runner.run import dynamic_presets, resolve_dynamic

# Synthetic sequences of the suites: the same room and path (seed) without and
# with movers, as in the end-to-end tests (test/python/conftest.py synth_scenes).
SYNTH_FRAMES = 60
SYNTH_SEED = 0


@dataclasses.dataclass(frozen=True)
class Sequence:
    name: str                 # e.g. "euroc/V1_01_easy_micro", "synth/rgbd_m3"
    kind: str                 # dataset reader: euroc | kitti | tum
    path: str                 # what `dynaorb run KIND PATH` takes
    sensor: str               # mono | stereo | rgbd
    labels: str | None = None # label images for the semantic stage (synthetic only)
    synthetic: dict | None = None  # SynthConfig fields when rendered by the benchmark

    @property
    def key(self) -> str:
        return f"{self.name}:{self.sensor}"


@dataclasses.dataclass(frozen=True)
class Case:
    sequence: Sequence
    preset: str               # "off" or a preset name of config/dynamic/

    @property
    def key(self) -> str:
        return f"{self.sequence.key}:{self.preset}"


@dataclasses.dataclass
class Suite:
    name: str
    cases: list[Case]
    sequences: list[Sequence]
    not_run: list[dict]       # {"what", "reason"}: sequences and preset/sensor pairs left out


# (name, kind, relative path, sensors) of the real sequences in ../shared/data.
REAL = {
    "quick": [("euroc/V1_01_easy_micro", "euroc", "euroc/V1_01_easy_micro", ("stereo",)),
              ("kitti/06", "kitti", "kitti/sequences/06", ("stereo",))],
    "full": [("euroc/V1_01_easy_micro", "euroc", "euroc/V1_01_easy_micro", ("stereo", "mono")),
             ("euroc/MH_05_difficult_head", "euroc", "euroc/MH_05_difficult_head", ("stereo", "mono")),
             ("kitti/06", "kitti", "kitti/sequences/06", ("stereo",))],
}
# (sensor, movers) of the synthetic sequences.
SYNTH = {
    "quick": [("rgbd", 3), ("stereo", 3)],
    "full": [(s, m) for s in ("rgbd", "stereo", "mono") for m in (0, 3)],
}
TUM_FRAGMENT = "tum/rgbd_dataset_freiburg3_walking_xyz_fragment"
# The long suite: a 1500-frame synthetic stereo walk down a 62 m room (75 s,
# no movers), run as stereo and as monocular on its left images, for what the
# real clips here are too short to show (map growth, local BA windows, memory,
# drift, false loops; ../shared/data has nothing longer than 250 frames).
LONG_FRAMES = 1500
LONG_SEED = 4


def synth_sequence(sensor: str, movers: int, root: pathlib.Path, frames: int = SYNTH_FRAMES,
                   seed: int = SYNTH_SEED, width: int = 640, height: int = 480, fx: float | None = None) -> Sequence:
    """A synthetic sequence under root (rendered by `ensure_rendered`); fx None: the renderer's default."""
    folder = root / (f"{sensor}_m{movers}_f{frames}_s{seed}_{width}x{height}" + (f"_fx{fx:g}" if fx else ""))
    path = folder if sensor == "rgbd" else folder / "sequences" / "00"
    return Sequence(name=f"synth/{sensor}_m{movers}", kind="tum" if sensor == "rgbd" else "kitti",
                    path=str(path), sensor=sensor, labels=str(path / "labels"),
                    synthetic={"sensor": sensor, "movers": movers, "frames": frames, "seed": seed,
                               "width": width, "height": height, **({"fx": fx} if fx else {}), "out": str(folder)})


def ensure_rendered(seq: Sequence) -> None:
    """Renders a synthetic sequence once (its folder is the cache)."""
    if seq.synthetic is None:
        return
    spec = dict(seq.synthetic)
    out = pathlib.Path(spec.pop("out"))
    if (out / "synth.json").is_file():
        return
    from dynaorb.synth import SynthConfig, generate

    part = out.with_name(out.name + ".part")
    if part.exists():
        import shutil

        shutil.rmtree(part)
    generate(part, SynthConfig(**spec))
    part.rename(out)


def preset_applicability(preset: str, sensor: str) -> str | None:
    """None when the preset runs on this sensor, else why not."""
    from dynaorb import core

    options = core().DynamicFilterOptions.load(str(resolve_dynamic(preset)))
    try:
        options.validate(sensor)
    except Exception as exc:  # InputError naming the stage and the sensor
        return str(exc)
    if not options.enabled(sensor):
        return f"preset {preset} has no stage for {sensor}"
    return None


def sensor_unavailable(kind: str, path: pathlib.Path, sensor: str) -> str | None:
    """None when the dataset reader opens the sequence for this sensor, else its error (e.g. an EuRoC
    sequence shipped with cam0 only has no stereo)."""
    from dynaorb import core

    try:
        core().open_dataset(kind, str(path), sensor)
    except Exception as exc:  # InputError naming the sequence and what it lacks
        return str(exc)
    return None


def cases_for(sequences: list[Sequence], presets: tuple[str, ...] | None = None) -> tuple[list[Case], list[dict]]:
    """`off` and every applicable preset for each sequence; the pairs left out, with why."""
    presets = presets if presets is not None else tuple(p for p in dynamic_presets() if p != "off")
    cases, not_run = [], []
    for seq in sequences:
        cases.append(Case(seq, "off"))
        for preset in presets:
            why = preset_applicability(preset, seq.sensor)
            if why is None:
                cases.append(Case(seq, preset))
            else:
                not_run.append({"what": f"{seq.key}:{preset}", "reason": why})
    return cases, not_run


class SelectionError(ValueError):
    """`dynaorb bench --only / --presets` named what the suite does not have."""


def select(suite: Suite, only: tuple[str, ...] | None = None, presets: tuple[str, ...] | None = None) -> Suite:
    """The suite cut to some of its clips and presets, e.g. to run one clip with more runs: `only` names
    sequences as NAME (every sensor it runs with) or NAME:SENSOR, `presets` the presets kept beside `off`
    (always kept: the baseline of the preset table). SelectionError for a name that matches nothing,
    with what the suite has (or why the sequence is not run)."""
    sequences = suite.sequences
    if only:
        keep = []
        for name in only:
            hits = [s for s in sequences if name in (s.name, s.key)]
            if not hits:
                why = [n["reason"] for n in suite.not_run if n["what"] in (name, name.split(":")[0])]
                raise SelectionError(f"suite {suite.name} has no sequence {name!r}"
                                     + (f" to run ({why[0]})" if why else
                                        f" (it has: {', '.join(s.key for s in sequences)})"))
            keep += [s for s in hits if s not in keep]
        sequences = [s for s in sequences if s in keep]
    cases = [c for c in suite.cases if c.sequence in sequences]
    if presets:
        have = {c.preset for c in cases}
        unknown = [p for p in presets if p not in have]
        if unknown:
            raise SelectionError(f"no case of the selected sequences runs preset(s) {', '.join(unknown)} "
                                 f"(they run: {', '.join(sorted(have))})")
        cases = [c for c in cases if c.preset == "off" or c.preset in presets]
    # What is said about the clips kept, and about the names asked for (a sensor the data lacks).
    names = {s.key for s in sequences} | set(only or ())
    not_run = [n for n in suite.not_run
               if not only or any(n["what"] == k or n["what"].startswith(k + ":") for k in names)]
    return Suite(suite.name, cases, sequences, not_run)


def long_sequences(root: pathlib.Path) -> list[Sequence]:
    """The long suite's sequences: the stereo render, and its left images as monocular."""
    stereo = synth_sequence("stereo", 0, root, frames=LONG_FRAMES, seed=LONG_SEED)
    mono = dataclasses.replace(stereo, sensor="mono")
    return [dataclasses.replace(s, name=f"synth/long_{LONG_FRAMES}") for s in (stereo, mono)]


def build_suite(name: str, data: pathlib.Path, synth_root: pathlib.Path,
                presets: tuple[str, ...] | None = None) -> Suite:
    if name == "long":
        sequences = long_sequences(synth_root)
        cases, skipped = cases_for(sequences, presets if presets is not None else ("full",))
        return Suite(name, cases, sequences, skipped)
    if name not in REAL:
        raise ValueError(f"unknown suite {name!r} (quick, full, long)")
    sequences, not_run = [], []
    for seq_name, kind, rel, sensors in REAL[name]:
        path = data / rel
        if not path.is_dir():
            not_run.append({"what": seq_name, "reason": f"{path} not found"})
            continue
        for sensor in sensors:
            why = sensor_unavailable(kind, path, sensor)
            if why is None:
                sequences.append(Sequence(seq_name, kind, str(path), sensor))
            else:
                not_run.append({"what": f"{seq_name}:{sensor}", "reason": why})
    if (data / TUM_FRAGMENT).is_dir():
        # Listed in both suites: it is in ../shared/data but cannot be run.
        not_run.append({"what": TUM_FRAGMENT,
                        "reason": "2 frames 3 s apart: not a sequence (no tracking between them to measure)"})
    sequences += [synth_sequence(s, m, synth_root) for s, m in SYNTH[name]]
    cases, skipped = cases_for(sequences, presets)
    return Suite(name, cases, sequences, not_run + skipped)
