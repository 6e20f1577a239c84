"""`dynaorb vocab`: training on images, and the self-built default vocabulary on real clips."""
from __future__ import annotations

import numpy as np
import pytest

from dynaorb import core
from dynaorb.cli.main import main


def test_train_writes_binary_and_orbvoc_text(tmp_path, data, capsys):
    images = str(data / "kitti" / "sequences" / "06" / "image_0")
    assert main(["vocab", "train", images, "-k", "8", "-L", "3", "-o", str(tmp_path / "v.bin"),
                 "--max-images", "10", "--quiet"]) == 0
    assert main(["vocab", "train", images, "-k", "8", "-L", "3", "-o", str(tmp_path / "v.txt"),
                 "--max-images", "10", "--quiet"]) == 0
    binary, text = core().Vocabulary.load(tmp_path / "v.bin"), core().Vocabulary.load(tmp_path / "v.txt")
    assert (binary.k, binary.L) == (8, 3) and 100 < binary.size <= 8 ** 3
    assert text.size == binary.size
    assert (tmp_path / "v.txt").read_text().startswith("8 3 0 0")   # ORB-SLAM2's header: k L scoring weighting
    d = core().extract_orb(_first_image(data), _settings())[1]
    assert binary.transform(d) == text.transform(d)
    assert main(["vocab", "train", str(tmp_path / "nothing"), "-o", str(tmp_path / "x.bin")]) == 2
    assert "no such image or folder" in capsys.readouterr().err


def _settings():
    from dynaorb.vocab.train import DEFAULT_CONFIG

    return core().Settings.load(str(DEFAULT_CONFIG))


def _first_image(data):
    import cv2

    return cv2.imread(str(sorted((data / "kitti" / "sequences" / "06" / "image_0").glob("*.png"))[0]),
                      cv2.IMREAD_GRAYSCALE)


def test_default_vocabulary_relocalises_a_real_clip(data):
    """The default vocabulary is trained on rendered rooms only; it must still
    find a real EuRoC clip again after 20 black frames. Measured: relocalised
    on frame 60, the first after the blackout; ATE 0.0009 m. (KITTI 06 with 2
    or 5 black frames: relocalised on the first frame after, ATE 0.065 / 0.061 m.)"""
    from dynaorb.vocab import build_default

    vocabulary = core().Vocabulary.load(build_default())
    assert vocabulary.size > 100000
    provider = core().open_dataset("euroc", str(data / "euroc" / "V1_01_easy_micro"))
    system = core().System(provider.default_settings(), provider.sensor, synchronous_mapping=True,
                           vocabulary=vocabulary)
    states = []
    for i in range(len(provider)):
        f = provider.load(i)
        r = (system.track_stereo(np.zeros_like(f.image), np.zeros_like(f.right), f.stamp) if 40 <= i < 60
             else system.track_frame(f))
        states.append((r.state, r.method))
    assert all(s == "LOST" for s, _ in states[40:60])
    assert states[60] == ("OK", "relocalization")
    assert all(s == "OK" for s, _ in states[60:])
    assert system.counters()["initializations"] == 1
