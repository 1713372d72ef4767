"""`ifd compare` against scikit-image's PSNR and SSIM (issue: foundation)."""

import numpy as np
import pytest
import scipy.ndimage as ndi
import skimage.metrics as skm

from conftest import TESTDATA, load_gray, save_npy


def _pairs(tmp_path):
    rng = np.random.default_rng(7)
    cam = load_gray("camera.png")
    astro = load_gray("astronaut.png")
    brick = load_gray("brick.png")
    pairs = [
        ("camera+noise", cam, np.clip(cam + rng.normal(0, 0.05, cam.shape), 0, 1), 1.0),
        ("astronaut blurred (RGB)", astro, ndi.gaussian_filter(astro, (2, 2, 0)), 1.0),
        ("brick shifted, HDR range", brick * 7.0, np.roll(brick, 3, axis=1) * 7.0 + 0.1, 7.1),
        ("camera vs brick", cam, brick, 1.0),
    ]
    out = []
    for i, (name, a, b, rng_) in enumerate(pairs):
        # The tool reads float32: compare skimage on exactly those values.
        a32 = a.astype(np.float32)
        b32 = b.astype(np.float32)
        pa = save_npy(tmp_path / f"a{i}.npy", a32)
        pb = save_npy(tmp_path / f"b{i}.npy", b32)
        out.append((name, pa, pb, a32.astype(np.float64), b32.astype(np.float64), rng_))
    return out


def _sk_ssim(a, b, r):
    return skm.structural_similarity(
        a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=r,
        channel_axis=-1 if a.ndim == 3 else None,
    )


@pytest.mark.parametrize("crop", [0, 7])
def test_psnr_ssim_match_skimage(tmp_path, run_json, crop):
    for name, pa, pb, a, b, r in _pairs(tmp_path):
        got = run_json("compare", pa, pb, "--json", "--data-range", r, "--crop-border", crop)
        if crop:
            a = a[crop:-crop, crop:-crop]
            b = b[crop:-crop, crop:-crop]
        psnr = skm.peak_signal_noise_ratio(a, b, data_range=r)
        ssim = _sk_ssim(a, b, r)
        assert abs(got["psnr"] - psnr) < 1e-4, (name, got["psnr"], psnr)
        assert abs(got["ssim"] - ssim) < 1e-4, (name, got["ssim"], ssim)
        assert abs(got["max_abs"] - np.abs(a - b).max()) < 1e-6, name
        assert abs(got["mean_abs"] - np.abs(a - b).mean()) < 1e-6, name
        chans = a.shape[2] if a.ndim == 3 else 1
        assert len(got["channels"]) == chans
        for c in range(chans):
            ac = a[..., c] if a.ndim == 3 else a
            bc = b[..., c] if b.ndim == 3 else b
            assert abs(got["channels"][c]["psnr"] - skm.peak_signal_noise_ratio(ac, bc, data_range=r)) < 1e-4
            assert abs(got["channels"][c]["ssim"] - _sk_ssim(ac, bc, r)) < 1e-4


def test_png_inputs_default_range(run_json):
    """8-bit files map to [0, 1]; the default data range is then 1."""
    got = run_json("compare", TESTDATA / "camera.png", TESTDATA / "brick.png", "--json")
    a, b = load_gray("camera.png"), load_gray("brick.png")
    assert got["data_range"] == 1.0
    assert abs(got["psnr"] - skm.peak_signal_noise_ratio(a, b, data_range=1.0)) < 1e-4
    assert abs(got["ssim"] - _sk_ssim(a, b, 1.0)) < 1e-4


def test_mismatched_shapes_exit_2(run_ifd):
    p = run_ifd("compare", TESTDATA / "camera.png", TESTDATA / "astronaut.png", check=False)
    assert p.returncode == 2
    assert "512x512 with 1 channels" in p.stderr and "3 channels" in p.stderr
