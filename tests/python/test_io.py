"""Image I/O against NumPy and OpenCV readers/writers (issue: foundation).

Files are written by ifd and read by NumPy/OpenCV, and written by NumPy/OpenCV
and read by ifd (`ifd convert X out.npy` exposes exactly the float32 values ifd
decoded).
"""

import json
import os
import pathlib

import numpy as np
import cv2
import pytest

from conftest import ROOT, TESTDATA



def _ifd_values(run_ifd, src, tmp_path):
    """What ifd reads from `src`, as a float32 array."""
    out = tmp_path / (pathlib.Path(src).name + ".npy")
    run_ifd("convert", src, out)
    return np.load(out)


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


def test_numpy_hxw_float64_reads_exactly(run_ifd, tmp_path):
    rng = np.random.default_rng(11)
    a = rng.normal(0, 3, (19, 23))  # float64, HxW, negative values included
    np.save(tmp_path / "a.npy", a)
    got = _ifd_values(run_ifd, tmp_path / "a.npy", tmp_path)
    assert got.dtype == np.float32 and got.shape == (19, 23)
    assert np.array_equal(got, a.astype(np.float32))
    info = json.loads(run_ifd("info", tmp_path / "a.npy", "--json").stdout)
    assert (info["width"], info["height"], info["channels"]) == (23, 19, 1)


@pytest.mark.parametrize("ext", ["png", "tif"])
def test_sixteen_bit_written_by_opencv_reads_exactly(run_ifd, tmp_path, ext):
    rng = np.random.default_rng(13)
    rgb = rng.integers(0, 65536, (21, 34, 3), dtype=np.uint16)
    rgb[0, 0] = [0, 65535, 1]  # both ends of the range
    cv2.imwrite(str(tmp_path / f"rgb.{ext}"), rgb[..., ::-1])  # OpenCV writes BGR
    got = _ifd_values(run_ifd, tmp_path / f"rgb.{ext}", tmp_path)
    assert got.shape == rgb.shape
    assert np.array_equal(got, rgb.astype(np.float32) / 65535), ext
    gray = rgb[..., 1]
    cv2.imwrite(str(tmp_path / f"gray.{ext}"), gray)
    got = _ifd_values(run_ifd, tmp_path / f"gray.{ext}", tmp_path)
    assert got.shape == gray.shape
    assert np.array_equal(got, gray.astype(np.float32) / 65535), ext
    info = json.loads(run_ifd("info", tmp_path / f"gray.{ext}", "--json").stdout)
    assert info["integer_bits"] == 16 and info["channels"] == 1


# JPEG decoders may legitimately differ: the standard fixes the IDCT only to an
# accuracy (one level either way after rounding), and leaves chroma upsampling
# to the decoder. So: gray, one level; 4:4:4 colour, where the YCbCr-to-RGB
# conversion adds up the luma and chroma rounding (R = Y + 1.402 Cr), three
# levels; 4:2:0 colour, where OpenCV's libjpeg-turbo upsamples chroma with its
# own ("fancy") filter, eight levels at colour edges and 0.5 on average.
# Measured here: 1 / 3 / 4 levels max, 0.006 / 0.010 / 0.17 mean.
@pytest.mark.parametrize(
    "name,sampling,max_levels,mean_levels",
    [
        ("gray", None, 1, 0.05),
        ("rgb444", "444", 3, 0.05),
        ("rgb420", "420", 8, 0.5),
    ],
)
def test_jpeg_written_by_opencv_matches_opencv_decode(
    run_ifd, tmp_path, name, sampling, max_levels, mean_levels
):
    if name == "gray":
        img = cv2.imread(str(TESTDATA / "camera.png"), cv2.IMREAD_GRAYSCALE)
        params = []
    else:
        img = cv2.imread(str(TESTDATA / "astronaut.png"), cv2.IMREAD_COLOR)
        factor = {
            "444": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444,
            "420": cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420,
        }[sampling]
        params = [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, factor]
    p = tmp_path / f"{name}.jpg"
    assert cv2.imwrite(str(p), img, [cv2.IMWRITE_JPEG_QUALITY, 90, *params])
    ref = cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.float64)
    if ref.ndim == 3:
        ref = ref[..., ::-1]
    got = _ifd_values(run_ifd, p, tmp_path).astype(np.float64) * 255
    assert got.shape == ref.shape
    # Linear mapping v / 255 (no gamma): back to integers exactly.
    assert np.abs(got - np.round(got)).max() < 1e-3
    d = np.abs(np.round(got) - ref)
    assert d.max() <= max_levels, (name, d.max())
    assert d.mean() <= mean_levels, (name, d.mean())
    # And the content is the image, not a shifted or transposed copy.
    assert d.mean() < 0.1 * np.abs(ref - ref.mean()).mean()


def _rgbe_round_trip(v):
    """Radiance RGBE encoding by truncation (Ward's float2rgbe) and decoding as
    OpenCV does (rgbe2float: mantissa * 2^(e - 136), no half-step offset)."""
    m = v.max(axis=2)
    mant, ex = np.frexp(m)
    scale = np.where(m > 1e-32, mant * 256.0 / np.where(m > 0, m, 1), 0.0)
    q = np.minimum(np.floor(v * scale[..., None]), 255)
    return np.where(m[..., None] > 1e-32, q * np.ldexp(1.0, ex - 8)[..., None], 0.0), m


def test_dwab_exr_matches_the_radiance_version_of_the_same_map(run_ifd, tmp_path):
    """`forest_dwab.exr` (DWAB, lossy) decoded by ifd (the `exr` crate) against
    `forest.hdr`, the same map converted to RGBE by another decoder and read
    here by OpenCV. OpenCV's own EXR reader cannot decode DWAB, so the RGBE file
    is the independent reference.

    RGBE stores a shared exponent and an 8-bit mantissa per pixel: with
    2^(e-1) <= max component < 2^e, a component is stored as
    floor(v * 256 / 2^e), so it loses less than one step 2^e / 256 <= max / 128.
    Negative values (the map has a few, down to -0.0016) are clamped to 0.
    Hence the bound |dwab - hdr| <= max component / 128 for every pixel; and,
    stronger, re-encoding ifd's decode to RGBE must give the file's bins
    (measured: every sample; a different DWAB decode would move samples that sit
    near a bin edge, so a few are allowed).
    """
    # Both files are bundled (copied from the shared test data).
    hdr_path = TESTDATA / "forest.hdr"
    exr_path = TESTDATA / "forest_dwab.exr"
    ref = cv2.imread(str(hdr_path), cv2.IMREAD_UNCHANGED)
    assert ref is not None and ref.dtype == np.float32
    ref = ref[..., ::-1].astype(np.float64)  # BGR -> RGB
    got = _ifd_values(run_ifd, exr_path, tmp_path)
    assert got.shape[:2] == ref.shape[:2] == (512, 1024) and got.shape[2] >= 3
    dwab = np.clip(got[..., :3].astype(np.float64), 0, None)
    assert dwab.max() > 500  # the sun: an HDR map, not clamped to [0, 1]

    m = dwab.max(axis=2, keepdims=True)
    assert np.all(np.abs(dwab - ref) <= m / 128 + 1e-30)
    rgbe, _ = _rgbe_round_trip(dwab)
    same_bin = np.isclose(rgbe, ref, rtol=1e-6, atol=0)
    assert same_bin.mean() >= 0.999, same_bin.mean()


def _srgb_encode(v):
    v = np.clip(v, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


@pytest.mark.parametrize("command", ["filter", "smooth", "convert"])
def test_shared_output_options_encode_alike(run_ifd, tmp_path, command):
    """Every command that writes an image takes the same -o/--sixteen-bit/
    --srgb-out options with the same meaning: the 16-bit sRGB PNG equals the
    command's float output, clipped, sRGB-encoded and rounded."""
    rng = np.random.default_rng(11)
    src = tmp_path / "src.npy"
    np.save(src, (rng.random((40, 48)) * 0.9 + 0.05).astype(np.float32))
    if command == "filter":
        d = tmp_path / "d.json"
        run_ifd("decompose", "gauss:sx=3,sy=1.5", "-o", d)
        args = ["filter", src, "--decomp", d, "--angle", "30"]
    elif command == "smooth":
        args = ["smooth", src, "--sigma", "1"]
    else:
        args = ["convert", src]
    out_flag = [] if command == "convert" else ["-o"]
    run_ifd(*args, *out_flag, tmp_path / "f.npy")
    run_ifd(*args, *out_flag, tmp_path / "f.png", "--sixteen-bit", "--srgb-out")
    want = np.round(_srgb_encode(np.load(tmp_path / "f.npy").astype(np.float64)) * 65535)
    got = cv2.imread(str(tmp_path / "f.png"), cv2.IMREAD_UNCHANGED)
    assert got.dtype == np.uint16 and got.shape == want.shape
    assert np.abs(got.astype(np.float64) - want).max() <= 1, command
