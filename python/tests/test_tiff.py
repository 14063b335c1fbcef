"""TIFFs as numpy: a round trip is exact, and a read hands over the
library's buffer without a copy."""

import numpy as np
import pytest

import xgauge


def test_import_from_the_build_tree():
    assert xgauge.__version__.count(".") == 2
    assert xgauge._xgauge.__file__.endswith(".so")


def test_float32_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(1)
    image = rng.normal(0.5, 0.2, size=(37, 53)).astype(np.float32)
    xgauge.write_tiff(tmp_path / "a.tif", image)
    back = xgauge.read_tiff(tmp_path / "a.tif")
    assert back.dtype == np.float32 and back.shape == (37, 53)
    assert np.array_equal(back, image)


def test_read_is_a_view_of_the_library_image(tmp_path):
    xgauge.write_tiff(tmp_path / "a.tif", np.ones((8, 4), np.float32))
    image = xgauge.read_tiff(tmp_path / "a.tif")
    # Not a copy: numpy does not own the pixels, a capsule holding the
    # library's Image does.
    assert not image.flags.owndata
    assert type(image.base).__name__ == "PyCapsule"


def test_u16_rounds_and_clamps(tmp_path):
    image = np.array([[-3.0, 0.4, 0.6, 70000.0]], np.float64)  # converted to float32
    xgauge.write_tiff(tmp_path / "u.tif", image, format="u16")
    assert xgauge.read_tiff(tmp_path / "u.tif").tolist() == [[0.0, 0.0, 1.0, 65535.0]]


def test_errors_name_the_file(tmp_path):
    with pytest.raises(xgauge.Error, match="nope.tif"):
        xgauge.read_tiff(tmp_path / "nope.tif")
    with pytest.raises(ValueError, match="2-D"):
        xgauge.write_tiff(tmp_path / "b.tif", np.ones(5, np.float32))


def test_read_radiograph_reads_raw_with_a_sidecar(tmp_path):
    image = (np.arange(12).reshape(3, 4) * 1000).astype(">u2")
    (tmp_path / "a.raw").write_bytes(b"HDR" + image.tobytes())
    (tmp_path / "a.raw.ini").write_text(
        "[raw]\nwidth = 4\nheight = 3\ntype = uint16\nbyte_order = big\noffset = 3\n")
    back, frames, fmt = xgauge.read_radiograph(tmp_path / "a.raw")
    assert fmt == "raw" and frames == 1
    assert np.array_equal(back, image.astype(np.float32))
    # read_tiff reads every format too.
    assert np.array_equal(xgauge.read_tiff(tmp_path / "a.raw"), back)
    with pytest.raises(xgauge.Error, match="did you mean 'width'"):
        (tmp_path / "a.raw.ini").write_text("[raw]\nwidht = 4\n")
        xgauge.read_radiograph(tmp_path / "a.raw")
