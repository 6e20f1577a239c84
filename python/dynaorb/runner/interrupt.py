"""Ctrl-C during a run: stop between frames and keep what was done.

A run interrupted with Ctrl-C (SIGINT) stops after the frame it is on, and
the runner writes its outputs for the frames so far (trajectory, map points,
stats.json with "interrupted"), as it does at the end of a sequence. A second
Ctrl-C quits at once (KeyboardInterrupt). Signals can only be caught in the
main thread: a run started from another thread is interrupted as before.
The handler goes in over whatever was there, SIG_IGN included (a run started
in the background of a shell without job control, where SIGINT starts
ignored, still stops cleanly on `kill -INT`), and that handler is handed back.
"""
from __future__ import annotations

import logging
import signal
import threading

log = logging.getLogger(__name__)


class StopOnInterrupt:
    """install() before the frame loop, restore() after it (and on the way out
    of an exception: restoring twice is harmless); `requested` once Ctrl-C came."""

    def __init__(self):
        self.requested = False
        self._previous = None
        self._installed = False

    def install(self) -> None:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)
            self._installed = True

    def restore(self) -> None:
        if self._installed:
            signal.signal(signal.SIGINT, self._previous)
            self._installed = False

    def _handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        log.warning("interrupted: the run stops after this frame and writes its outputs for the frames so far "
                    "(Ctrl-C again to quit at once, without them)")
