"""Running one benchmark run in a child process: its own peak memory, a crash recorded, a time limit."""
from __future__ import annotations

import dataclasses
import os
import pathlib
import signal
import subprocess
import time


@dataclasses.dataclass
class ChildResult:
    returncode: int | None    # None: killed at the time limit
    peak_rss_mb: float | None # the child's peak resident memory (VmHWM after its exec), MiB
    wall_s: float
    timed_out: bool
    log: str                  # file with the child's stdout and stderr

    @property
    def ok(self) -> bool:
        return self.returncode == 0

    def failure(self) -> str | None:
        if self.timed_out:
            return f"killed after {self.wall_s:.0f} s (time limit)"
        if self.returncode is None or self.returncode == 0:
            return None
        if self.returncode < 0:
            return f"died of signal {signal.Signals(-self.returncode).name}"
        return f"exit status {self.returncode}"

    def log_tail(self, lines: int = 15) -> str:
        try:
            text = pathlib.Path(self.log).read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(text[-lines:])


def child_env() -> dict:
    """The environment of a `python -m dynaorb...` child: this one, with the package's folder first on
    PYTHONPATH (a source checkout that is not installed runs the same code)."""
    package_root = str(pathlib.Path(__file__).resolve().parents[2])
    return dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in [package_root, os.environ.get("PYTHONPATH", "")]
                                                       if p))


def run_child(cmd: list[str], log: pathlib.Path, timeout_s: float, env: dict | None = None,
              cwd: str | None = None) -> ChildResult:
    """Runs cmd to completion (or kills it at timeout_s), sampling its peak resident memory.

    The peak is /proc/PID/status VmHWM, the high-water mark of the process's
    own address space since its exec, read every 50 ms (it only grows, so
    the last reading misses at most the final 50 ms). Not ru_maxrss: Linux
    carries over the forking parent's resident size into the child's
    ru_maxrss, so every child would report at least this process's size."""
    log.parent.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with open(log, "wb") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env, cwd=cwd,
                                start_new_session=True)
        timed_out = False
        peak_kb = 0
        while True:
            peak_kb = max(peak_kb, _vm_hwm_kb(proc.pid))
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid != 0:
                break
            if time.perf_counter() - start > timeout_s:
                timed_out = True
                os.killpg(proc.pid, signal.SIGKILL)
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
    proc.returncode = os.waitstatus_to_exitcode(status)  # Popen must not wait for it again
    wall = time.perf_counter() - start
    return ChildResult(returncode=None if timed_out else proc.returncode,
                       peak_rss_mb=peak_kb / 1024.0 if peak_kb else None,
                       wall_s=wall, timed_out=timed_out, log=str(log))


def _vm_hwm_kb(pid: int) -> int:
    """VmHWM of a live process in KiB; 0 when it cannot be read (exited, not Linux)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


def self_peak_mb() -> float | None:
    """This process's own VmHWM in MiB (what a child reports about itself at its end)."""
    kb = _vm_hwm_kb(os.getpid())
    return kb / 1024.0 if kb else None
