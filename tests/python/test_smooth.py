"""`ifd smooth` end to end against a brute-force spatially varying anisotropic Gaussian.

`ifd smooth --field F.npy` writes the filter each pixel used (angle of the long
axis in degrees counter-clockwise on screen, sx along it, sy across). The
reference applies, at each checked pixel, that Gaussian integrated over every
pixel cell (the smoother's definition at every footprint scale, see
docs/smoothing.md), computed here independently of ifd: the cell integral is
the marginal along the axis of larger variance (a 64-point midpoint sum) times
the conditional normal CDF along the other (scipy's ndtr), normalised to sum 1,
with reflect-101 borders.

The edge is oblique (30 degrees): on a vertical or horizontal edge a sign error
of the angle would go unnoticed, here it does not (the test checks that the
reference with mirrored angles is far off).

Scales 0.5 and 1 take the direct path (tabulated pixel-integrated kernels),
scales 2, 3 and 6 the IFD path (decomposed bank on the cubic scale stack).
The errors are printed; with IFD_UPDATE_DOCS=1 they are written to
docs/smoothing-accuracy.csv, the table of docs/smoothing.md.
"""

import csv
import os

import numpy as np
import pytest
from scipy.special import ndtr

from conftest import ROOT, save_npy

RESULTS = []


@pytest.fixture(scope="module", autouse=True)
def write_table():
    yield
    if os.environ.get("IFD_UPDATE_DOCS") == "1" and RESULTS:
        with open(ROOT / "docs" / "smoothing-accuracy.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["scale", "path", "rms_error", "rms_change", "error_over_change", "mirrored_over_change"])
            w.writerows(sorted(RESULTS))

EDGE_DEG = 30.0


def covariance(theta, sx, sy):
    t = np.radians(theta)
    c, s = np.cos(t), np.sin(t)
    e1, e2 = np.array([c, -s]), np.array([s, c])  # long axis (y down), across
    return sx * sx * np.outer(e1, e1) + sy * sy * np.outer(e2, e2)


def integrated_kernel(theta, sx, sy, radius, nsub=64):
    """Weights of the Gaussian integrated over the cells of a (2r+1)^2 window, rows = y."""
    cov = covariance(theta, sx, sy)
    d = np.arange(-radius, radius + 1)
    X, Y = np.meshgrid(d, d)
    sxx, sxy, syy = cov[0, 0], cov[0, 1], cov[1, 1]
    if syy >= sxx:
        var, other, outer, inner = syy, sxx, Y, X
    else:
        var, other, outer, inner = sxx, syy, X, Y
    m = sxy / var
    c = np.sqrt((other * var - sxy * sxy) / var)
    u = (np.arange(nsub) + 0.5) / nsub - 0.5
    o = outer[..., None] + u
    marginal = np.exp(-0.5 * o * o / var) / np.sqrt(2 * np.pi * var)
    bracket = ndtr((inner[..., None] + 0.5 - m * o) / c) - ndtr((inner[..., None] - 0.5 - m * o) / c)
    k = (marginal * bracket).sum(-1) / nsub
    return k / k.sum()


def reflect101(i, n):
    p = 2 * (n - 1)
    i = np.mod(i, p)
    return np.where(i < n, i, p - i)


def brute_force(img, field, pixels, mirror=False):
    h, w = img.shape
    out = []
    for y, x in pixels:
        theta, sx, sy = field[y, x]
        if mirror:
            theta = -theta
        r = int(np.ceil(5 * np.hypot(sx, 0.3) + 1))
        k = integrated_kernel(theta, sx, sy, r)
        patch = img[np.ix_(reflect101(np.arange(y - r, y + r + 1), h), reflect101(np.arange(x - r, x + r + 1), w))]
        out.append(float((k * patch).sum()))
    return np.array(out)


def oblique_edge(n=80):
    """A step edge through the centre along 30 degrees (counter-clockwise on
    screen), mild texture and noise."""
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    t = np.radians(EDGE_DEG)
    # Signed distance across the edge, whose direction is (cos t, -sin t).
    d = (xx - n / 2) * np.sin(t) + (yy - n / 2) * np.cos(t)
    img = np.where(d > 0, 0.8, 0.2) + 0.05 * np.sin(xx / 5.0) * np.cos(yy / 7.0)
    img += np.random.default_rng(1).normal(0, 0.02, img.shape)
    return img.astype(np.float32).astype(np.float64), d


# (scale, rms error relative to the rms of the smoothing's own change): the
# direct path measured 0.1-0.15%, the IFD path 0.6-0.9% at scales 2-6 (its
# bank of 1% decompositions and their blend; docs/smoothing.md).
CASES = [(0.5, 0.005), (1.0, 0.005), (2.0, 0.015), (3.0, 0.015), (6.0, 0.015)]


@pytest.mark.parametrize("scale,tol", CASES)
def test_smooth_matches_brute_force_on_an_oblique_edge(run_ifd, tmp_path, scale, tol):
    img, dist = oblique_edge()
    src = save_npy(tmp_path / "in.npy", img.astype(np.float32))
    run_ifd("smooth", src, "--sigma", scale, "--max-aspect", 16, "-o", tmp_path / "o.npy", "--field", tmp_path / "f.npy")
    out = np.load(tmp_path / "o.npy").astype(np.float64)
    field = np.load(tmp_path / "f.npy").astype(np.float64)
    assert field.shape == img.shape + (3,)
    np.testing.assert_allclose(field[..., 1] * field[..., 2], scale * scale, rtol=1e-4)
    # The field follows the edge: along it, elongated.
    on_edge = (np.abs(dist) < 1.0) & (np.abs(np.mgrid[0:80, 0:80][0] - 40) < 20)
    ang = np.mod(field[..., 0][on_edge] - EDGE_DEG + 90.0, 180.0) - 90.0
    assert np.median(np.abs(ang)) < 5.0, f"filter angle on the edge off by {np.median(np.abs(ang)):.1f} deg"
    assert np.median(field[..., 1][on_edge] / field[..., 2][on_edge]) > 4.0
    pixels = [(y, x) for y in range(8, 72, 4) for x in range(8, 72, 4)]
    got = np.array([out[p] for p in pixels])
    want = brute_force(img, field, pixels)
    change = np.sqrt(np.mean((want - np.array([img[p] for p in pixels])) ** 2))
    err = np.sqrt(np.mean((got - want) ** 2))
    mirrored = brute_force(img, field, pixels, mirror=True)
    err_mirrored = np.sqrt(np.mean((got - mirrored) ** 2))
    path = "direct" if scale < 2 else "IFD bank"
    print(f"scale {scale} ({path}): rms error {err:.2e} = {err / change:.3%} of the change {change:.4f}; mirrored angles {err_mirrored / change:.1%}")
    RESULTS.append((scale, path, f"{err:.3e}", f"{change:.4f}", f"{err / change:.5f}", f"{err_mirrored / change:.4f}"))
    assert err <= tol * change, f"scale {scale}: rms error {err:.2e} = {err / change:.2%} of the change {change:.3f}"
    # The check sees the sign of the angle: mirrored filters are far off.
    assert err_mirrored > 5 * err + 0.05 * change


def test_smooth_scale_limits_and_field_format(run_ifd, tmp_path):
    img, _ = oblique_edge(32)
    src = save_npy(tmp_path / "in.npy", img.astype(np.float32))
    p = run_ifd("smooth", src, "--sigma", "0.4", "-o", tmp_path / "o.npy", check=False)
    assert p.returncode == 2 and "--sigma 0.4: outside the supported range" in p.stderr, p.stderr
    p = run_ifd("smooth", src, "--sigma", "1", "-o", tmp_path / "o.npy", "--field", tmp_path / "f.png", check=False)
    assert p.returncode == 2 and "--field" in p.stderr and ".npy" in p.stderr, p.stderr
    assert not (tmp_path / "o.npy").exists()
    p = run_ifd("smooth", src, "--sigma", "1", "--gpu", "-o", tmp_path / "o.npy", check=False)
    assert p.returncode == 2 and "CPU only" in p.stderr, p.stderr
