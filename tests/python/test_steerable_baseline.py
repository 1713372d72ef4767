"""The baselines of tests/bench/steerable.py (issue 53) against exact correlation.

The steerable basis and the blended bins (both with the image spectrum computed
once) must converge to exact per-pixel correlation as their K grows, with the
angle map alone and with the scale map too, and be close at the largest K: on a
160x160 photograph with a small 8:1 Gaussian (gauss sx=8, sy=2 on a 65x65
window) along the swirl angle field (and the radial scale field over [0.5, 1])
of tests/bench/curves_vs_opencv.py, PSNR on a sample of pixels against that
script's exact float64 correlation (reflect-101 borders).
"""

import math
import sys

import numpy as np
import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "tests" / "bench"))
import curves_vs_opencv as cv  # noqa: E402
import steerable as st  # noqa: E402

N = 160
SX, SY, R = 8.0, 2.0, 32
SAMPLES = 400


@pytest.fixture(scope="module")
def setup():
    img = cv.load_image("camera", N)
    angles, scales = cv.fields(N)
    rng = np.random.default_rng(3)
    pys, pxs = rng.integers(0, N, SAMPLES), rng.integers(0, N, SAMPLES)
    exact = {}
    for case in ("angle", "angle+scale"):
        sc = scales if case == "angle+scale" else np.ones_like(scales)
        exact[case] = cv.exact_reference(img, pys, pxs, angles, sc, sx=SX, sy=SY, r=R)
    kernel_at = st.gauss_kernel_at(SX, SY, R)
    svd = {case: st.family_svd(kernel_at, scale_range=(cv.SMIN, cv.SMAX) if case == "angle+scale" else None)
           for case in ("angle", "angle+scale")}
    return {"img": img, "angles": angles, "scales": scales, "pys": pys, "pxs": pxs, "exact": exact,
            "kernel_at": kernel_at, "svd": svd}


def psnr(s, case, out):
    ex = s["exact"][case]
    mse = float(np.mean((out[s["pys"], s["pxs"]].astype(np.float64) - ex) ** 2))
    return 10 * math.log10((ex.max() - ex.min()) ** 2 / mse)


def run(s, case, model):
    spectra = st.prepare(model, s["img"].shape)
    scales = s["scales"] if case == "angle+scale" else None
    apply = st.apply_steerable if model.kind == "steerable" else st.apply_bins
    return apply(model, spectra, s["img"], s["angles"], scales)


def assert_converges(ps, what):
    print(what, ", ".join(f"{k}: {p:.1f} dB" for k, p in ps))
    for (k0, p0), (k1, p1) in zip(ps, ps[1:]):
        assert p1 > p0 + 1.0, f"{what}: PSNR {p0:.1f} dB at {k0} -> {p1:.1f} dB at {k1}"
    assert ps[-1][1] > 45.0, f"{what}: {ps[-1][1]:.1f} dB at {ps[-1][0]}"


@pytest.mark.parametrize("case,ks", [("angle", (2, 4, 8, 12)), ("angle+scale", (4, 8, 16, 24))])
def test_steerable_basis_converges_to_exact_correlation(setup, case, ks):
    sr = (cv.SMIN, cv.SMAX) if case == "angle+scale" else None
    svd = setup["svd"][case]  # the weighted SVD, shared by every K
    ps = []
    for k in ks:
        m = st.fit_steerable(setup["kernel_at"], k, svd=svd)
        ps.append((k, psnr(setup, case, run(setup, case, m))))
    assert_converges(ps, f"steerable, {case}")


@pytest.mark.parametrize("case,bins", [("angle", ((4, 1), (8, 1), (16, 1))), ("angle+scale", ((4, 2), (8, 2), (16, 3)))])
def test_blended_bins_converge_to_exact_correlation(setup, case, bins):
    sr = (cv.SMIN, cv.SMAX) if case == "angle+scale" else None
    ps = []
    for ka, ks in bins:
        b = st.fit_bins(setup["kernel_at"], ka, ks, scale_range=sr)
        ps.append((f"{ka}x{ks}", psnr(setup, case, run(setup, case, b))))
    assert_converges(ps, f"bins, {case}")


@pytest.mark.parametrize("case", ["angle", "angle+scale"])
def test_both_reproduce_a_constant_image(setup, case):
    """The steerable output is divided by its DC gain, the bins' weights are
    a partition of unity: a constant image comes out unchanged."""
    s = dict(setup, img=np.full((N, N), 0.7, np.float32))
    sr = (cv.SMIN, cv.SMAX) if case == "angle+scale" else None
    for model in (st.fit_steerable(s["kernel_at"], 5, svd=s["svd"][case]), st.fit_bins(s["kernel_at"], 6, 2, scale_range=sr)):
        out = run(s, case, model)
        assert np.abs(out - 0.7).max() < 1e-5, model.kind


def test_a_basis_per_shape_on_its_region_matches_exact_correlation():
    """tests/bench/bench_shapes.py's peer: a basis per shape (the comet is
    not point-symmetric: period 360), the forward DFT shared, each basis
    accumulated over its region's pixels only; with K near the family's
    size it matches exact correlation with each pixel's own shape, and the
    shared DFT and masks give what each basis alone gives on its region."""
    import bench_shapes as bs

    n, r = 160, 32
    img = cv.load_image("camera", n)
    angles, _ = cv.fields(n)
    labels = bs.labels_of(img)
    assert sorted(np.unique(labels).tolist()) == [0, 1, 2]
    small = {"streak": (8.0, 2.0, 0.0, 180.0, None), "blob": (6.0, 3.0, 0.0, 180.0, None),
             "comet": (6.0, 1.5, 8.0, 360.0, None)}
    old = (bs.SHAPES, bs.R)
    bs.SHAPES, bs.R = small, r
    try:
        shapes = list(small)
        models = {}
        for s in shapes:
            period = small[s][3]
            svd = st.family_svd(bs.kernel_at(s), n_angles=int(period / 2), period=period)
            models[s] = st.fit_steerable(bs.kernel_at(s), 40, svd=svd)
        x = st._forward(img, r)
        out = np.zeros((n, n), np.float32)
        for i, s in enumerate(shapes):
            mask = (labels == i).astype(np.uint8)
            spectra = st.prepare(models[s], (n, n))
            o = st.apply_steerable(models[s], spectra, img, angles, x=x, mask=mask)
            alone = st.apply_steerable(models[s], spectra, img, angles)
            assert np.allclose(o[mask == 1], alone[mask == 1], rtol=1e-5, atol=1e-6)
            assert np.all(o[mask == 0] == 0)
            np.copyto(out, o, where=mask.astype(bool))
        rng = np.random.default_rng(5)
        pys, pxs = rng.integers(0, n, SAMPLES), rng.integers(0, n, SAMPLES)
        want = bs.exact(img, pys, pxs, angles, np.ones_like(angles), labels, shapes)
        got = out[pys, pxs]
        assert bs.psnr(got, want) > 55.0, bs.psnr(got, want)
    finally:
        bs.SHAPES, bs.R = old
