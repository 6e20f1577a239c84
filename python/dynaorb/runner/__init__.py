"""Dataset runner: DataProvider -> System -> trajectory files and stats.json."""

from dynaorb.runner.run import DYNAMIC_MODES, RunOptions, run_dataset

__all__ = ["DYNAMIC_MODES", "RunOptions", "run_dataset"]
