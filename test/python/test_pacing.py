"""--realtime: frames delivered at the recording's rate (runner/pacing.py)."""
from __future__ import annotations

import math

import pytest

from dynaorb.runner import RunOptions, run_dataset
from dynaorb.runner.pacing import Pacer


class FakeClock:
    def __init__(self):
        self.t = 100.0
        self.sleeps = []

    def __call__(self):
        return self.t

    def sleep(self, s):
        self.sleeps.append(s)
        self.t += s


def test_frames_are_held_until_their_stamp_at_the_rate():
    clock = FakeClock()
    p = Pacer(2.0, clock=clock, sleep=clock.sleep)
    p.wait(10.0)             # the first frame sets the origin: no wait
    clock.t += 0.01          # 10 ms of tracking
    p.wait(10.1)             # due 0.05 s after the first at 2x
    assert clock.sleeps == [pytest.approx(0.04)]
    clock.t += 0.2           # tracking fell behind
    p.wait(10.2)             # due at origin + 0.1 s, now at + 0.25 s: handed over at once
    assert len(clock.sleeps) == 1
    assert p.late_frames == 1 and p.max_late_ms == pytest.approx(150.0)
    assert p.summary()["frames"] == 3 and p.waited_s == pytest.approx(0.04)


def test_stamps_that_cannot_be_paced_are_counted_not_waited_on():
    clock = FakeClock()
    p = Pacer(1.0, clock=clock, sleep=clock.sleep)
    p.wait(math.nan)         # before any origin: counted
    p.wait(5.0)
    p.wait(4.0)              # before the first stamp
    p.wait(math.inf)
    assert clock.sleeps == [] and p.unpaced_frames == 3 and p.frames == 4
    p.wait(5.5)
    p.wait(5.2)              # before the last one paced: not counted as late
    assert p.unpaced_frames == 4 and p.late_frames == 0 and clock.sleeps == [pytest.approx(0.5)]


@pytest.mark.parametrize("rate", [0.0, -1.0, math.nan, math.inf])
def test_a_bad_rate_is_refused(rate):
    with pytest.raises(ValueError, match="realtime rate"):
        Pacer(rate)


def test_run_at_the_recording_rate_only_delays_the_frames(tmp_path, synth_rgbd):
    """With synchronous mapping the result is the unpaced run's; the run
    takes at least the recording's span divided by the rate."""
    plain = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "plain"), progress=False))
    stamps = [float(l.split()[0]) for l in (synth_rgbd / "rgb.txt").read_text().splitlines()
              if l and not l.startswith("#")]
    # At most a quarter of the recording's speed, and slow enough that the
    # paced span is 4x the unpaced run however busy the machine is: pacing,
    # not tracking, sets the time.
    rate = min(0.25, (stamps[-1] - stamps[0]) / (4 * plain["wall_s"]))
    paced = run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "paced"), progress=False,
                                   realtime=rate))
    assert plain["realtime"] is None
    r = paced["realtime"]
    assert r["rate"] == rate and r["frames"] == 8 and r["unpaced_frames"] == 0 and r["waited_s"] > 0
    span = (stamps[-1] - stamps[0]) / rate
    assert paced["wall_s"] >= span - 0.01
    assert (tmp_path / "paced" / "trajectory.tum").read_text() == (tmp_path / "plain" / "trajectory.tum").read_text()
    with pytest.raises(ValueError, match="realtime rate"):
        run_dataset(RunOptions(kind="tum", path=str(synth_rgbd), out=str(tmp_path / "bad"), progress=False,
                               realtime=-2.0))
