"""Image I/O against NumPy and OpenCV readers/writers (issue: foundation)."""

import numpy as np
import cv2
import pytest

from conftest import TESTDATA


def test_npy_written_by_ifd_reads_in_numpy(run_ifd, tmp_path):
    out = tmp_path / "cam.npy"
    run_ifd("convert", TESTDATA / "camera.png", out)
    arr = np.load(out)
    ref = cv2.imread(str(TESTDATA / "camera.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 255
    assert arr.dtype == np.float32 and arr.shape == (512, 512)
    assert np.array_equal(arr, ref)


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8, np.uint16])
@pytest.mark.parametrize("order", ["C", "F"])
def test_numpy_arrays_read_exactly(run_ifd, tmp_path, dtype, order):
    rng = np.random.default_rng(3)
    a = (rng.random((13, 17, 3)) * (200 if dtype in (np.uint8, np.uint16) else 1)).astype(dtype)
    a = np.asfortranarray(a) if order == "F" else np.ascontiguousarray(a)
    src = tmp_path / "a.npy"
    np.save(src, a)
    out = tmp_path / "b.npy"
    run_ifd("convert", src, out)
    b = np.load(out)
    assert b.shape == a.shape
    assert np.allclose(b, a.astype(np.float32), rtol=0, atol=1e-7)


def test_sixteen_bit_png_and_tiff_match_opencv(run_ifd, tmp_path):
    rng = np.random.default_rng(5)
    a = rng.random((20, 30, 3)).astype(np.float32)
    np.save(tmp_path / "a.npy", a)
    for ext in ("png", "tif"):
        out = tmp_path / f"a16.{ext}"
        run_ifd("convert", tmp_path / "a.npy", out, "--sixteen-bit")
        got = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
        assert got.dtype == np.uint16
        got = got[..., ::-1].astype(np.float64) / 65535  # OpenCV is BGR
        assert np.abs(got - a).max() <= 0.5 / 65535 + 1e-7, ext


def test_eight_bit_clipping_reported(run_ifd, tmp_path):
    a = np.array([[-0.5, 0.25, 1.5, 1.0]] * 3, dtype=np.float32)
    np.save(tmp_path / "a.npy", a)
    p = run_ifd("convert", tmp_path / "a.npy", tmp_path / "a.png")
    assert "clipped 6 of 12 values" in p.stderr
    got = cv2.imread(str(tmp_path / "a.png"), cv2.IMREAD_UNCHANGED)
    assert got.tolist()[0] == [0, 64, 255, 255]


def test_exr_and_hdr_read_by_opencv(run_ifd, tmp_path):
    import os

    os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"
    rng = np.random.default_rng(9)
    a = (rng.random((16, 24, 3)) * 50).astype(np.float32)
    np.save(tmp_path / "a.npy", a)
    run_ifd("convert", tmp_path / "a.npy", tmp_path / "a.hdr")
    hdr = cv2.imread(str(tmp_path / "a.hdr"), cv2.IMREAD_UNCHANGED)[..., ::-1]
    # RGBE keeps 8 bits of mantissa per pixel: relative error below 1/128 of the largest component.
    assert np.all(np.abs(hdr - a) <= a.max(axis=2, keepdims=True) / 128 + 1e-6)
    run_ifd("convert", tmp_path / "a.npy", tmp_path / "a.exr")
    back = tmp_path / "back.npy"
    run_ifd("convert", tmp_path / "a.exr", back)
    assert np.array_equal(np.load(back), a)


def test_dwab_exr_reads(run_json):
    info = run_json("info", TESTDATA / "forest_dwab.exr", "--json")
    assert (info["width"], info["height"]) == (1024, 512)
    assert info["format"] == "OpenEXR" and info["integer_bits"] is None
    assert max(info["max"][:3]) > 10  # HDR: the sun is far above 1
