#!/usr/bin/env python3
"""Per-pixel anisotropic Gaussians (a sigma map): ifd against the steerable basis.

The planar guide's example: the structure tensor of `testdata/camera.png` (512x512) steers a
Gaussian of footprint S = sqrt(major minor) px along the edges, aspect 1 + 7 coherence (1 to
8), angle along the edge. Every pixel has its own angle and aspect, so the family a steerable
basis must span has two parameters: angle (90 samples over 180 degrees) times aspect (8
log-spaced samples over [1, 8]), the basis' second parameter interpolated by a cubic spline in
log aspect (`tests/bench/steerable.py`, whose "scale" axis is the aspect here).

- ifd: `ifd filter IMAGE --kernel gauss --sigma-map M.npy --tol T -v`, one thread, for each bank
  tolerance T of --tols (the relative L2 error each entry of the aspect bank is fitted to; 1% is
  the shared bank of `ifd smooth`); its "filtering" time (the stack, the bank lookups and the
  directly sampled small footprints; the bank is loaded from the cache, fitted beforehand) and the
  whole process.
- steerable: its per-image work (one forward DFT, per basis kernel a spectrum product, an
  inverse DFT, its per-pixel weight, the accumulation, the DC division), one thread, for K
  from --ks; its fit (the weighted SVD of the family and the basis) is reported apart.

Accuracy: PSNR against exact per-pixel correlation (float64) with each pixel's sampled
Gaussian within 5 standard deviations normalised to sum 1 (ifd's definition of a sigma-map
filter), reflect-101 borders, on --samples random pixels; the peak is the range of the exact
values. The table gives, per footprint, ifd's PSNR and time, and the first K whose PSNR reaches
ifd's with its time, medians of --runs interleaved runs.

    .venv/bin/python tests/bench/bench_sigma_map.py --ifd target/release/ifd --runs 5 [--tols 0.01,0.05]
"""

import argparse
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "bench"))
import curves_vs_opencv as cvo  # noqa: E402
import steerable as st  # noqa: E402

MAX_ASPECT = 8.0


def sigma_map(img, footprint):
    """The guide's structure-tensor map: (H, W, 3) float32 major, minor, angle."""
    def blur(a, s):
        return cv2.GaussianBlur(a, (0, 0), s, borderType=cv2.BORDER_REFLECT_101)

    gy, gx = np.gradient(blur(img, 1.0))
    jxx, jxy, jyy = (blur(p, 3.0) for p in (gx * gx, gx * gy, gy * gy))
    across = 0.5 * np.arctan2(2 * jxy, jxx - jyy)
    angle = -np.degrees(across + np.pi / 2)
    coherence = np.sqrt((jxx - jyy) ** 2 + 4 * jxy**2) / (jxx + jyy + 1e-4)
    aspect = np.minimum(1 + 7 * coherence, MAX_ASPECT)
    return np.stack([footprint * np.sqrt(aspect), footprint / np.sqrt(aspect), angle], axis=-1).astype(np.float32)


def exact(img, m, pys, pxs):
    """Each sampled pixel's sampled Gaussian within 5 sigma (Mahalanobis), sum 1, reflect-101."""
    out = np.empty(len(pys))
    r = int(np.ceil(5 * m[..., 0].max())) + 1
    pad = np.pad(img.astype(np.float64), r, mode="reflect")
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    for n, (py, px) in enumerate(zip(pys, pxs)):
        sa, sb, th = (float(v) for v in m[py, px])
        t = np.radians(th)
        c, s = np.cos(t), np.sin(t)
        u = (c * x - s * y) / sa
        v = (s * x + c * y) / sb
        d2 = u * u + v * v
        k = np.where(d2 <= 25.0, np.exp(-0.5 * d2), 0.0)
        out[n] = (k * pad[py : py + 2 * r + 1, px : px + 2 * r + 1]).sum() / k.sum()
    return out


def psnr(got, want):
    peak = want.max() - want.min()
    return 10 * np.log10(peak * peak / np.mean((got - want) ** 2))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ifd", default=str(ROOT / "target" / "release" / "ifd"))
    ap.add_argument("--footprints", default="3,8")
    ap.add_argument("--tols", default="0.01", help="aspect-bank tolerances (ifd filter --tol), comma-separated")
    ap.add_argument("--ks", default="4,6,8,10,12,16,20,24,32")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--samples", type=int, default=600)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    img = cv2.imread(str(ROOT / "testdata" / "camera.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
    h, w = img.shape
    rng = np.random.default_rng(1)
    pys, pxs = rng.integers(0, h, a.samples), rng.integers(0, w, a.samples)
    print(f"CPU: {cvo.cpu_name()}; one thread each; camera.png {w}x{h}; medians of {a.runs} runs", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        np.save(tmp / "img.npy", img)
        for s in (float(v) for v in a.footprints.split(",")):
            m = sigma_map(img.astype(np.float64), s)
            np.save(tmp / "M.npy", m)
            want = exact(img, m, pys, pxs)
            tols = [float(v) for v in a.tols.split(",")]
            cmds, p_ifd = {}, {}
            for tol in tols:
                cmds[tol] = [a.ifd, "filter", tmp / "img.npy", "--kernel", "gauss", "--sigma-map", tmp / "M.npy",
                             "--tol", tol, "-o", tmp / "out.npy", "-v"]
                subprocess.run(list(map(str, cmds[tol])), env=env, check=True, capture_output=True)  # the bank, cached
                got = np.load(tmp / "out.npy")
                p_ifd[tol] = psnr(got[pys, pxs].astype(np.float64), want)
            best = max(p_ifd.values())
            # the steerable basis over angle x aspect, on the window of the widest Gaussian
            r = int(np.ceil(5 * s * np.sqrt(MAX_ASPECT))) + 1

            def family(theta, aspect, s=s, r=r):
                return st.gauss_kernel_at(s * np.sqrt(aspect), s / np.sqrt(aspect), r)(theta, 1.0)

            family.r = r
            t0 = time.perf_counter()
            svd = st.family_svd(family, scale_range=(1.0, MAX_ASPECT))
            svd_s = time.perf_counter() - t0
            angles = m[..., 2]
            aspects = np.clip(m[..., 0] / m[..., 1], 1.0, MAX_ASPECT)
            models = {}
            for k in (int(v) for v in a.ks.split(",")):
                model = st.fit_steerable(family, k, svd=svd)
                spectra = st.prepare(model, img.shape)
                out = st.apply_steerable(model, spectra, img, angles, aspects)
                models[k] = (model, spectra, psnr(out[pys, pxs].astype(np.float64), want))
                if models[k][2] >= best:
                    break
            times = {**{("ifd", t): [] for t in tols}, **{("wall", t): [] for t in tols}, **{k: [] for k in models}}
            for _ in range(a.runs):
                for tol in tols:
                    t0 = time.perf_counter()
                    p = subprocess.run(list(map(str, cmds[tol])), env=env, check=True, capture_output=True, text=True)
                    times[("wall", tol)].append(1e3 * (time.perf_counter() - t0))
                    times[("ifd", tol)].append(float(re.search(r"filtering ([\d.]+) ms", p.stderr)[1]))
                for k, (model, spectra, _) in models.items():
                    t0 = time.perf_counter()
                    st.apply_steerable(model, spectra, img, angles, aspects)
                    times[k].append(1e3 * (time.perf_counter() - t0))
            med = {k: statistics.median(v) for k, v in times.items()}
            print(f"\nS = {s:g} px: steerable SVD {svd_s:.1f} s", flush=True)
            for tol in tols:
                print(f"  ifd, bank tol {tol:g}: {p_ifd[tol]:.1f} dB, filtering {med[('ifd', tol)]:.0f} ms "
                      f"(whole process {med[('wall', tol)]:.0f} ms)", flush=True)
            for k, (model, _, pk) in models.items():
                print(f"  steerable K = {k}: {pk:.1f} dB, {med[k]:.0f} ms (fit {model.seconds:.1f} s)", flush=True)
            for tol in tols:
                reach = [k for k, (_, _, pk) in models.items() if pk >= p_ifd[tol]]
                rows.append((s, tol, p_ifd[tol], med[("ifd", tol)], med[("wall", tol)], reach[0] if reach else None,
                             models[reach[0]][2] if reach else max(v[2] for v in models.values()),
                             med[reach[0]] if reach else None))
    print("\n| footprint | bank tol | ifd PSNR | ifd filtering (ms) | ifd whole process (ms) | steerable K at ifd's PSNR | its PSNR | its time (ms) | steerable / ifd |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s, tol, p, ti, tw, k, pk, tk in rows:
        if k is None:
            print(f"| {s:g} px | {tol:g} | {p:.1f} dB | {ti:.0f} | {tw:.0f} | not reached (best {pk:.1f} dB) | | | |")
        else:
            print(f"| {s:g} px | {tol:g} | {p:.1f} dB | {ti:.0f} | {tw:.0f} | {k} | {pk:.1f} dB | {tk:.0f} | {tk / ti:.2f}x |")


if __name__ == "__main__":
    main()
