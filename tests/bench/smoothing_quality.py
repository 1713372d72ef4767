#!/usr/bin/env python3
"""Hessian-driven anisotropic smoothing (ifd) against what users have today.

Noisy inputs: bundled images plus Gaussian noise of sigma 0.05 (of the [0, 1]
range, seed 2026). Methods, at equal noise reduction:

- ifd smooth --scale S (per-pixel and dab modes). Its Gaussians keep
  sx * sy = S^2, so their white-noise gain sum k^2 = 1 / (4 pi S^2) equals an
  isotropic Gaussian of sigma S whatever the orientation and aspect.
- cv2.GaussianBlur with sigma = S (the equal-noise-reduction isotropic filter).
- cv2.ximgproc.anisotropicDiffusion (Perona-Malik; 8-bit 3-channel only), with
  the iteration count chosen so that its residual noise on a flat noisy image
  comes closest to the Gaussian's (it works on 8-bit data and its residual
  noise stalls around 0.01, so it cannot always reach it; the table says so).

Measured: PSNR against the clean image, and edge preservation = correlation of
Sobel gradient magnitudes with those of the clean image. The residual noise of
each method on a flat image (0.5 + noise) is reported to show the noise
reduction really is equal.

Usage: .venv/bin/python tests/bench/smoothing_quality.py [--ifd target/release/ifd] [--out docs/smoothing]
Writes a markdown table on stdout and side-by-side crops into --out.
"""

import argparse
import pathlib
import subprocess
import sys
import tempfile

import cv2
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
NOISE = 0.05
SEED = 2026


def grad_mag(img):
    gx = cv2.Sobel(img, cv2.CV_64F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_64F, 0, 1, ksize=3)
    return np.hypot(gx, gy)


def psnr(clean, x):
    return 10 * np.log10(1.0 / np.mean((clean - x) ** 2))


def edge_corr(clean, x):
    return float(np.corrcoef(grad_mag(clean).ravel(), grad_mag(x).ravel())[0, 1])


def ifd_smooth(ifd, tmp, noisy, scale, mode):
    src = tmp / "in.npy"
    out = tmp / "out.npy"
    np.save(src, noisy.astype(np.float32))
    subprocess.run([ifd, "smooth", str(src), "--scale", str(scale), "--mode", mode, "-o", str(out)], check=True, capture_output=True)
    return np.load(out).astype(np.float64)


def aniso_diffusion(noisy, niters, alpha=0.1, k=20.0 / 255):
    u8 = np.clip(noisy * 255 + 0.5, 0, 255).astype(np.uint8)
    rgb = cv2.merge([u8, u8, u8])
    out = cv2.ximgproc.anisotropicDiffusion(rgb, alpha, k * 255, niters)
    return out[..., 0].astype(np.float64) / 255


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd", default=str(ROOT / "target" / "release" / "ifd"))
    ap.add_argument("--scale", type=float, default=3.0)
    ap.add_argument("--out", default=str(ROOT / "docs" / "smoothing"))
    a = ap.parse_args()
    outdir = pathlib.Path(a.out)
    outdir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(SEED)
    s = a.scale
    rows = []
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        # Equal noise reduction: residual noise on a flat image.
        flat_clean = np.full((256, 256), 0.5)
        flat = flat_clean + rng.normal(0, NOISE, flat_clean.shape)
        g_flat = cv2.GaussianBlur(flat, (0, 0), s)
        res = {"gauss": np.std(g_flat - flat_clean), "ifd per-pixel": np.std(ifd_smooth(a.ifd, tmp, flat, s, "per-pixel") - flat_clean)}
        # Choose the anisotropic diffusion iteration count that matches the Gaussian's residual noise.
        best = None
        # Its state is 8-bit, so its residual noise stalls around 0.01 (updates
        # round to zero): when it cannot reach the target, take its lowest.
        for n in range(1, 41):
            r = np.std(aniso_diffusion(flat, n) - flat_clean)
            if best is None or abs(r - res["gauss"]) < abs(best[1] - res["gauss"]):
                best = (n, r)
        niters = best[0]
        res["anisotropicDiffusion"] = best[1]
        print(f"residual noise on a flat image (input {NOISE}): " + ", ".join(f"{k} {v:.4f}" for k, v in res.items()) + f" (anisotropicDiffusion with {niters} iterations)")
        print()
        print(f"| image | method (scale {s:g}) | PSNR [dB] | edge corr |")
        print("|---|---|---|---|")
        for name in ["camera.png", "astronaut.png", "brick.png", "coffee.png"]:
            img = cv2.imread(str(ROOT / "testdata" / name), cv2.IMREAD_GRAYSCALE).astype(np.float64) / 255
            noisy = img + rng.normal(0, NOISE, img.shape)
            results = {
                "noisy input": noisy,
                "cv2.GaussianBlur": cv2.GaussianBlur(noisy, (0, 0), s),
                f"cv2.ximgproc.anisotropicDiffusion ({niters} it.)": aniso_diffusion(noisy, niters),
                "ifd smooth per-pixel": ifd_smooth(a.ifd, tmp, noisy, s, "per-pixel"),
                "ifd smooth dab": ifd_smooth(a.ifd, tmp, noisy, s, "dab"),
            }
            for m, x in results.items():
                p, e = psnr(img, x), edge_corr(img, x)
                rows.append((name, m, p, e))
                print(f"| {name} | {m} | {p:.2f} | {e:.3f} |")
            if name == "camera.png":
                crops = [np.clip(results[k][80:336, 120:376], 0, 1) for k in ["noisy input", "cv2.GaussianBlur", f"cv2.ximgproc.anisotropicDiffusion ({niters} it.)", "ifd smooth per-pixel"]]
                cv2.imwrite(str(outdir / "side_by_side.png"), (np.hstack(crops) * 255 + 0.5).astype(np.uint8))
    return 0


if __name__ == "__main__":
    sys.exit(main())
