"""Dataset runner: DataProvider -> System -> trajectory files and stats.json."""

from dynaorb.runner.run import DYNAMIC_MODES, RunOptions, dynamic_presets, resolve_dynamic, run_dataset

__all__ = ["DYNAMIC_MODES", "RunOptions", "dynamic_presets", "resolve_dynamic", "run_dataset"]
