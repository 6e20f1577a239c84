"""dynaorb.image_files: the image writer every sequence and cache writer calls (synth, segment,
run --save-masks, bag to-dataset)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from dynaorb.image_files import write_image


def test_an_image_is_written_and_a_failed_write_names_the_file(tmp_path):
    image = np.arange(12, dtype=np.uint8).reshape(3, 4)
    write_image(tmp_path / "a.png", image)
    assert np.array_equal(cv2.imread(str(tmp_path / "a.png"), cv2.IMREAD_UNCHANGED), image)
    # A folder that is not there: cv2.imwrite answers False, not an exception.
    with pytest.raises(OSError, match=r"gone/b\.png: cannot write the label image"):
        write_image(tmp_path / "gone" / "b.png", image, "label image")
