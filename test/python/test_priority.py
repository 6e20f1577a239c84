"""Lowering a whole process's priority while its threads start more threads
(rospy's, after init_node): every thread ends at the one target nice."""
import subprocess
import sys
import textwrap

import pytest

# Run in a child: a process cannot raise its priority back.
CHILD = textwrap.dedent("""
    import os, threading
    from dynaorb.segmentation.priority import lower_process_priority

    stop = threading.Event()

    def idle():
        stop.wait()

    def spawner():
        # Starts long-lived threads as fast as it can, before, during and after
        # the lowering: those it starts before it is lowered itself keep its
        # priority unless a later pass finds them.
        for _ in range(400):
            threading.Thread(target=idle, daemon=True).start()

    def nice_of(tid):
        try:
            return os.getpriority(os.PRIO_PROCESS, int(tid))
        except ProcessLookupError:  # a spawner joined but not yet gone
            return None

    base = os.getpriority(os.PRIO_PROCESS, 0)
    spawners = [threading.Thread(target=spawner, daemon=True) for _ in range(4)]
    for s in spawners:
        s.start()
    refused = lower_process_priority(7)
    for s in spawners:
        s.join()
    nices = [n for n in map(nice_of, os.listdir("/proc/self/task")) if n is not None]
    print(refused, base, len(nices), sorted(set(nices)))
    stop.set()
""")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice is Linux's")
def test_lowering_reaches_threads_started_meanwhile():
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    refused, base, count, nices = out.stdout.split(" ", 3)
    assert refused == "None"
    assert int(count) > 1000  # the spawners' threads are all alive
    assert nices.strip() == f"[{min(19, int(base) + 7)}]"


def test_zero_lowers_nothing():
    from dynaorb.segmentation.priority import lower_process_priority

    assert lower_process_priority(0) is None
