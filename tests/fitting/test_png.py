"""The report's PNG writer: the pixels read back by Pillow (an independent decoder) are the
ones written, opaque pages are stored as RGB, and the file records the resolution."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from are_stats.fitting._png import write_png


@pytest.mark.parametrize("shape", [(1, 1), (7, 3), (40, 65)])
def test_pixels_read_back_by_pillow(tmp_path, shape):
    rng = np.random.default_rng(0)
    rgba = rng.integers(0, 256, (*shape, 4), dtype=np.uint8)
    path = tmp_path / "a.png"
    write_png(path, rgba, dpi=110)
    with Image.open(path) as img:
        img.load()  # checks every chunk's CRC and the zlib stream
        assert img.mode == "RGBA"
        assert np.array_equal(np.asarray(img), rgba)
        assert img.info["dpi"] == pytest.approx((110, 110), abs=0.01)


def test_opaque_image_is_stored_as_rgb(tmp_path):
    rng = np.random.default_rng(1)
    rgba = rng.integers(0, 256, (20, 30, 4), dtype=np.uint8)
    rgba[:, :, 3] = 255
    path = tmp_path / "b.png"
    write_png(path, rgba)
    with Image.open(path) as img:
        assert img.mode == "RGB" and "dpi" not in img.info
        assert np.array_equal(np.asarray(img), rgba[:, :, :3])
    write_png(path, rgba[:, :, :3])  # RGB in: the same file
    with Image.open(path) as img:
        assert np.array_equal(np.asarray(img), rgba[:, :, :3])


_BAD = [np.zeros((4, 4, 4), np.float32), np.zeros((4, 4), np.uint8), np.zeros((0, 4, 3), np.uint8)]


@pytest.mark.parametrize("bad", _BAD)
def test_bad_image_is_refused(tmp_path, bad):
    with pytest.raises(ValueError, match="image: expected an"):
        write_png(tmp_path / "c.png", bad)
