"""Which build of dynaorb a benchmark measures: the commit of the source checkout and a fingerprint of
the compiled core this process loaded (the pybind11 module and the core library it links).

Every run of a benchmark is a child process that loads the core anew. A rebuild while a benchmark
goes on would otherwise mix two builds in one table (or let a child load a half-written library:
"file too short"). So the benchmark writes the fingerprint it started with into every run's spec,
and the child refuses to run on a core whose fingerprint differs (`check_core`), naming both.
"""
from __future__ import annotations

import functools
import hashlib
import pathlib
import subprocess


class CoreChanged(RuntimeError):
    """The core this process loaded is not the build the benchmark started with."""


def core_files() -> list[str]:
    """The compiled core's files this process has loaded: dynaorb._core's shared object and, on Linux,
    every other dynaorb shared library mapped into the process (libdynaorb_core.so). A library replaced on
    disk after it was loaded is listed as Linux names it, "PATH (deleted)"."""
    from dynaorb import _core

    files = {str(pathlib.Path(_core.__file__).resolve())}
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                parts = line.split(maxsplit=5)  # address perms offset dev inode [path]
                path = parts[5].strip() if len(parts) == 6 else ""
                if pathlib.Path(path).name.startswith("libdynaorb") and ".so" in path:
                    files.add(path)
    except OSError:  # no /proc: the module alone
        pass
    return sorted(files)


def fingerprint(files: list[str]) -> str:
    """sha256 over the files' names and contents, in path order (the first 16 hex digits); a file that
    cannot be read (replaced since it was loaded) counts by its name alone, so it matches no build."""
    h = hashlib.sha256()
    for f in files:
        h.update(pathlib.Path(f).name.encode() + b"\0")
        try:
            with open(f, "rb") as data:
                for block in iter(lambda: data.read(1 << 20), b""):
                    h.update(block)
        except OSError:
            h.update(b"\0unreadable\0")
    return h.hexdigest()[:16]


@functools.lru_cache(maxsize=1)
def core_fingerprint() -> str:
    """This process's core fingerprint, taken when first asked (the benchmark asks before its first run)."""
    return fingerprint(core_files())


def check_core(expected: str | None) -> None:
    """Raises CoreChanged unless this process's core has the fingerprint `expected` (None: no check)."""
    if expected is None:
        return
    found = core_fingerprint()
    if found != expected:
        names = ", ".join(core_files())
        raise CoreChanged(f"the dynaorb core this run loaded ({names}: fingerprint {found}) is not the build the "
                          f"benchmark started with (fingerprint {expected}): it was rebuilt while the benchmark "
                          "ran; finish the build, then run the benchmark again (--resume keeps only runs of one "
                          "build)")


def source_commit() -> dict:
    """The git commit of the source checkout the package runs from, and whether tracked files differ from
    it ({"commit": None} outside a checkout or without git)."""
    root = pathlib.Path(__file__).resolve().parents[3]
    if not (root / "package.xml").is_file():  # an installed package: no checkout of its own
        return {"commit": None, "dirty": None}

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=20)
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return {"commit": None, "dirty": None}
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": commit, "dirty": bool(status) if status is not None else None}


def build() -> dict:
    """What results.json records of the build: the commit, whether the tree was dirty, the core fingerprint."""
    return {**source_commit(), "core": core_fingerprint()}
