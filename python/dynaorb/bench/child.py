"""One benchmark run of dynaorb in its own process: `python -m dynaorb.bench.child SPEC.json`.

SPEC.json holds RunOptions fields and "core", the fingerprint of the core
build the benchmark started with (build_info): a child that loads another
build stops with exit status 3 and says so, before it runs. The stats (as
run_dataset returns them, without the per-frame lists of the dynamic
filter) go to SPEC's "result" file. The parent measures this process's
peak memory (its VmHWM, process.run_child) and survives its crash.
"""
from __future__ import annotations

import json
import logging
import pathlib
import sys


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python -m dynaorb.bench.child SPEC.json", file=sys.stderr)
        return 2
    spec = json.loads(pathlib.Path(argv[0]).read_text())
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from dynaorb.bench.build_info import CoreChanged, check_core
    from dynaorb.runner import RunOptions, run_dataset

    result_file = pathlib.Path(spec.pop("result"))
    try:
        check_core(spec.pop("core", None))
    except CoreChanged as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    stats = run_dataset(RunOptions(**spec, progress=False))
    if stats.get("interrupted"):  # a partial run is no measurement
        print(f"error: interrupted after {stats['interrupted']['frames_run']} frames", file=sys.stderr)
        return 130
    dyn = stats.get("dynamic_filter")
    if dyn:
        dyn.pop("per_frame", None)
    from dynaorb.bench.process import self_peak_mb

    stats["peak_rss_mb_self"] = self_peak_mb()
    result_file.write_text(json.dumps(stats))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
