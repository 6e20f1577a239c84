"""Labels from a network behind the camera (`dynaorb run --labels-delay`), end to end.

The synthetic RGB-D room with 3 movers (seed 0), `full` preset, synchronous:
with each frame's own labels the ATE is 2.8 mm. A network 5 frames behind
(each frame gets labels 5-9 frames old): as they are, the filter's
candidates miss the movers and the ATE is 207 mm; moved onto each frame by
the chained optical flow (the core's LiveLabels, as the ROS node's live
labels and `--segment` are) 3.1 mm. Seeds 1-3, labels as they are / moved /
exact: 291 / 3.5 / 2.9, 17.4 / 2.7 / 2.5, 22.4 / 2.7 / 2.4 mm.
"""
import pytest

from dynaorb.runner import RunOptions, run_dataset
from dynaorb.runner.label_delay import DelayedLabels


def test_the_emulated_network_delivers_frames_it_finished():
    d = DelayedLabels(3, max_age=30)
    # Frame 0 waits for its own labels; then the network finishes frame 0 at
    # frame 3, frame 3 at frame 6, ...
    assert [d.source_frame(t) for t in range(10)] == [0, 0, 0, 0, 0, 0, 3, 3, 3, 6]
    for bad in (0, -2, 2.5, True):
        with pytest.raises(ValueError, match="labels delay"):
            DelayedLabels(bad)
    with pytest.raises(ValueError, match="exceeds the labels' maximum age"):
        DelayedLabels(40, max_age=30)


def test_labels_delay_needs_a_label_folder(synth_scenes, tmp_path):
    seq = synth_scenes[("rgbd", 3)]
    with pytest.raises(ValueError, match="--labels-delay emulates a network on a label folder"):
        run_dataset(RunOptions(kind="tum", path=str(seq), sensor="rgbd", dynamic="full", labels_delay=5,
                               out=str(tmp_path), progress=False, vocabulary="none"))


def test_propagation_gives_back_what_a_lagging_network_costs(synth_scenes, tmp_path):
    seq = synth_scenes[("rgbd", 3)]
    ate = {}
    for name, delay, propagate in (("exact", 0, True), ("moved", 5, True), ("as_is", 5, False)):
        stats = run_dataset(RunOptions(kind="tum", path=str(seq), sensor="rgbd", dynamic="full",
                                       labels=str(seq / "labels"), labels_delay=delay, propagate_labels=propagate,
                                       out=str(tmp_path / name), progress=False))
        assert stats["tracked_fraction"] == 1.0
        ate[name] = stats["ate"]["rmse"]
        if delay:
            s = stats["labels_delay"]
            kind = "propagated" if propagate else "as_is"
            assert s["frames"] == {"fresh": 1, kind: 59} and s["age_median"] == 7 and s["age_max"] == 9
            assert (s["propagate_ms_median"] is not None) == propagate
            # The tracking thread's time for each frame's labels, and the track call with it.
            assert len(stats["labels_ms"]) == len(stats["track_call_ms"]) == 60
            assert stats["track_call_plus_labels_ms_median"] >= stats["track_call_ms_median"]
        else:
            assert stats["labels_ms"] is None and stats["track_call_plus_labels_ms_median"] is None
    # What the lag costs, and how much of it propagation gives back. Measured,
    # exact / moved / as-is labels: 2.12 / 2.94 / 150 mm (moved / exact 1.38,
    # 99.4 % of the cost given back); seeds 1 / 2 (not run here) 1.08 / 1.04
    # and 99.9 / 99.4 %. With plain least squares in motion-only BA's last
    # round (TrackerOptions::pose_final_huber 0) 2.45 / 2.88 / 205 mm (1.17):
    # the kernel helps the exact labels' run most, so the ratio, held to 1.3
    # before, is 1.5 now.
    assert ate["moved"] <= 1.5 * ate["exact"], ate
    assert ate["as_is"] >= 3 * ate["exact"], ate       # the problem the flow solves
    given_back = (ate["as_is"] - ate["moved"]) / (ate["as_is"] - ate["exact"])
    assert given_back >= 0.97, ate
