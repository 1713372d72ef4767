"""Planar IFD against OpenCV and an independent numpy brute force (issue: planar IFD).

Kernels here are sampled in numpy from their formulas, independently of the
Rust kernel code: the IFD result must match direct correlation with them.
"""

import numpy as np
import cv2
import pytest

from conftest import TESTDATA, load_gray, save_npy


def psnr(ref, out):
    rng = float(ref.max() - ref.min())
    mse = float(np.mean((ref.astype(np.float64) - out.astype(np.float64)) ** 2))
    return 10 * np.log10(rng * rng / mse)


def gauss_kernel(sx, sy, theta_deg, r):
    """Normalised anisotropic Gaussian, rotated counter-clockwise on screen (y down)."""
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    t = np.deg2rad(theta_deg)
    c, s = np.cos(t), np.sin(t)
    # k_theta(d) = k0(R_{-theta} d), R_theta = [[c, s], [-s, c]] in (x right, y down).
    u = c * x - s * y
    v = s * x + c * y
    k = np.exp(-0.5 * (u / sx) ** 2 - 0.5 * (v / sy) ** 2)
    return k / k.sum()


def dgauss_kernel(order, sigma, r):
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    g = np.exp(-(x * x + y * y) / (2 * sigma**2)) / (2 * np.pi * sigma**2)
    if order == "xx":
        return (x * x / sigma**4 - 1 / sigma**2) * g
    if order == "xy":
        return x * y / sigma**4 * g
    raise ValueError(order)


def ifd_filter(run_ifd, tmp_path, spec, image, *extra):
    d = tmp_path / "d.json"
    run_ifd("decompose", spec, "-o", d)
    out = tmp_path / "out.npy"
    run_ifd("filter", image, "--decomp", d, "-o", out, *extra)
    return np.load(out)


@pytest.mark.parametrize(
    "spec,angle,scale,kernel",
    [
        ("gauss:sx=12,sy=3,theta=30", 0, 1, lambda: gauss_kernel(12, 3, 30, 48)),
        ("gauss:sx=12,sy=3,theta=30", 45, 1.5, lambda: gauss_kernel(18, 4.5, 75, 72)),
        ("gauss:sx=24,sy=3,theta=0", -20, 1, lambda: gauss_kernel(24, 3, -20, 96)),
        ("dgauss:order=xx,sigma=4", 0, 1, lambda: dgauss_kernel("xx", 4, 16)),
        ("dgauss:order=xy,sigma=4", 0, 1, lambda: dgauss_kernel("xy", 4, 16)),
    ],
)
def test_constant_filter_matches_cv2_filter2d(run_ifd, tmp_path, spec, angle, scale, kernel):
    img = load_gray("camera.png").astype(np.float32)
    ref = cv2.filter2D(img, cv2.CV_32F, kernel().astype(np.float32), borderType=cv2.BORDER_REFLECT_101)
    out = ifd_filter(run_ifd, tmp_path, spec, TESTDATA / "camera.png", "--angle", angle, "--scale", scale)
    p = psnr(ref, out)
    print(f"{spec} angle {angle} scale {scale}: PSNR {p:.1f} dB vs cv2.filter2D")
    assert p >= 40.0, p


def brute_force_varying(img, sx, sy, angles, scales, r):
    """Spatially varying correlation: pixel p uses gauss(s sx, s sy, theta(p)), reflect-101 border."""
    h, w = img.shape
    pad = np.pad(img.astype(np.float64), r, mode="reflect")  # numpy 'reflect' == BORDER_REFLECT_101
    t = np.deg2rad(angles)
    c, s = np.cos(t), np.sin(t)
    out = np.zeros((h, w))
    norm = np.zeros((h, w))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            u = (c * dx - s * dy) / scales
            v = (s * dx + c * dy) / scales
            k = np.exp(-0.5 * (u / sx) ** 2 - 0.5 * (v / sy) ** 2)
            out += k * pad[r + dy : r + dy + h, r + dx : r + dx + w]
            norm += k
    return out / norm


def test_spatially_varying_angle_matches_brute_force(run_ifd, tmp_path):
    img = load_gray("camera.png")[96:224, 160:288].copy()
    h, w = img.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    angles = 120.0 * xx / (w - 1) + 60.0 * np.sin(yy / 20.0)  # smooth, spans > 180 degrees
    pin = save_npy(tmp_path / "in.npy", img)
    pa = save_npy(tmp_path / "angle.npy", angles)
    ref = brute_force_varying(img, 8, 2, angles, np.ones_like(angles), 32)
    out = ifd_filter(run_ifd, tmp_path, "gauss:sx=8,sy=2,theta=0", pin, "--angle-map", pa)
    p = psnr(ref, out)
    print(f"varying angle: PSNR {p:.1f} dB vs numpy brute force")
    assert p >= 40.0, p


def test_spatially_varying_angle_and_scale_matches_brute_force(run_ifd, tmp_path):
    img = load_gray("astronaut.png")[..., 1][200:328, 180:308].copy()
    h, w = img.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    angles = 90.0 * np.cos(xx / 30.0) + 45.0 * yy / h
    scales = 0.75 + 1.0 * yy / (h - 1)
    pin = save_npy(tmp_path / "in.npy", img)
    pa = save_npy(tmp_path / "angle.npy", angles)
    ps = save_npy(tmp_path / "scale.npy", scales)
    ref = brute_force_varying(img, 6, 1.5, angles, scales, 42)
    out = ifd_filter(run_ifd, tmp_path, "gauss:sx=6,sy=1.5,theta=0", pin, "--angle-map", pa, "--scale-map", ps)
    p = psnr(ref, out)
    print(f"varying angle and scale: PSNR {p:.1f} dB vs numpy brute force")
    assert p >= 40.0, p


@pytest.mark.parametrize("border,cv_border", [("replicate", cv2.BORDER_REPLICATE), ("constant", cv2.BORDER_CONSTANT), ("wrap", cv2.BORDER_WRAP)])
def test_border_modes_match_opencv(run_ifd, tmp_path, border, cv_border):
    img = load_gray("brick.png").astype(np.float32)[:160, :200].copy()
    pin = save_npy(tmp_path / "in.npy", img)
    k = gauss_kernel(10, 2.5, 15, 40).astype(np.float32)
    if cv_border == cv2.BORDER_WRAP:
        # cv2.filter2D does not support BORDER_WRAP: pad periodically, then crop.
        padded = np.pad(img, 40, mode="wrap")
        ref = cv2.filter2D(padded, cv2.CV_32F, k, borderType=cv2.BORDER_CONSTANT)[40:-40, 40:-40]
    else:
        ref = cv2.filter2D(img, cv2.CV_32F, k, borderType=cv2.BORDER_CONSTANT if cv_border == cv2.BORDER_CONSTANT else cv_border)
    out = ifd_filter(run_ifd, tmp_path, "gauss:sx=10,sy=2.5,theta=15", pin, "--border", border)
    p = psnr(ref, out)
    print(f"border {border}: PSNR {p:.1f} dB vs OpenCV")
    assert p >= 40.0, p
