"""dynaorb: visual SLAM for scenes that move.

The compiled core lives in ``dynaorb._core`` (pybind11); the Python modules
around it run datasets (:mod:`dynaorb.runner`), evaluate trajectories with evo
(:mod:`dynaorb.evaluation`) and render synthetic dynamic sequences
(:mod:`dynaorb.synth`).
"""

__version__ = "0.1.0"


def core():
    """The compiled module, with a clear message when it has not been built."""
    try:
        from dynaorb import _core
    except ImportError as exc:  # pragma: no cover - depends on the build
        raise ImportError(
            "dynaorb._core is not built: run `make build` (or `make test`) in the "
            f"repository first ({exc})") from exc
    return _core
