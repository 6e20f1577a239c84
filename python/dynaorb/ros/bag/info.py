"""`dynaorb bag info`: what a bag holds and what `bag run` / `to-dataset` would
take from it (topics by role, sensor, frames, settings and ground-truth
sources), so that a user can see which `--topic` or `--config` to give."""
from __future__ import annotations

import collections

from dynaorb.ros.bag import messages as m
from dynaorb.ros.bag.poses import POSE_TYPES
from dynaorb.ros.bag.read import BagProvider


def bag_info(bags, config=None, **provider_options) -> dict:
    """Topics with their types, counts and time spans; then, when the bag can
    be read as a sequence, the provider's choice (roles, sensor, frames, rate,
    settings source, ground truth); otherwise the reason it cannot. config:
    a settings YAML, as `bag run --config`; the rest as BagProvider takes them."""
    paths = m.bag_paths(bags)
    topics = collections.OrderedDict()
    with m.open_bags(paths) as reader:
        for c in sorted(reader.connections, key=lambda c: c.topic):
            t = topics.setdefault(c.topic, {"type": c.msgtype, "messages": 0})
            t["messages"] += c.msgcount
        start, end = reader.start_time * 1e-9, reader.end_time * 1e-9
    out = {"files": [str(p) for p in paths], "start": start, "end": end, "duration": end - start,
           "topics": dict(topics)}
    out["pose_topics"] = [name for name, t in topics.items() if t["type"] in POSE_TYPES]
    out["tf_topics"] = [name for name, t in topics.items() if t["type"] in m.TF_TYPES]
    try:
        provider = BagProvider(paths, settings=config, **provider_options)
    except (ValueError, FileNotFoundError) as exc:
        out["sequence"] = {"error": str(exc)}
        return out
    try:
        n = len(provider)
        seq = {"sensor": provider.sensor, "topics": dict(provider.topics), "frames": n,
               "settings": ("camera_info" if provider.settings_from_camera_info else
                            provider.default_settings().source), "warnings": list(provider.warnings)}
        if n > 1:
            seq["rate_hz"] = (n - 1) / (provider.stamp(n - 1) - provider.stamp(0))
        seq["ground_truth_poses"] = int(len(provider.ground_truth()[0]))
        out["sequence"] = seq
    finally:
        provider.close()
    return out


def format_info(info: dict) -> str:
    lines = [f"{', '.join(info['files'])}: {info['duration']:.2f} s ({info['start']:.6f} - {info['end']:.6f})"]
    width = max((len(t) for t in info["topics"]), default=0)
    for name, t in info["topics"].items():
        lines.append(f"  {name:<{width}}  {t['messages']:>6}  {t['type']}")
    seq = info["sequence"]
    if "error" in seq:
        lines.append(f"not readable as a sequence: {seq['error']}")
        return "\n".join(lines)
    roles = ", ".join(f"{role} {topic}" for role, topic in seq["topics"].items())
    rate = f" at {seq['rate_hz']:.1f} Hz" if "rate_hz" in seq else ""
    lines.append(f"sequence: {seq['sensor']}, {seq['frames']} frames{rate}; {roles}")
    lines.append(f"settings: {seq['settings']}")
    gt = f"{seq['ground_truth_poses']} poses" if seq["ground_truth_poses"] else "none"
    hints = []
    if info["pose_topics"]:
        hints.append("--ground-truth-topic " + " | ".join(info["pose_topics"]))
    if info["tf_topics"]:
        hints.append("--ground-truth-tf PARENT:CHILD (" + ", ".join(info["tf_topics"]) + ")")
    lines.append(f"ground truth: {gt}" + (f" (or {'; '.join(hints)})" if hints else ""))
    lines += [f"warning: {w}" for w in seq["warnings"]]
    return "\n".join(lines)
