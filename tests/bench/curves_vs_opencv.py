#!/usr/bin/env python3
"""Time against accuracy: ifd against its peers -- a steerable basis, bins
with the image spectrum computed once, and binned cv2.filter2D -- as curves.

What it measures. A spatially varying anisotropic filter, the 8:1 Gaussian
`gauss:sx=32,sy=4,theta=0` (extent 257 px at scale 1), rotated per pixel by a
swirl angle field ("angle" case) and also scaled per pixel by a radial scale
field in [0.5, 1] ("angle+scale" case; `--scale-range 0.25` or `0.125` for
[0.25, 1] or [0.125, 1], the wide regimes), on several 1024x1024 grayscale
images (camera.png and astronaut.png upscaled with INTER_CUBIC, and a smooth
synthetic image). Each method has a knob that trades time for accuracy, so
every method is a curve of points (PSNR, time) rather than one point:

* ifd: the decomposition tolerance (`ifd decompose --tol T`, fewer or more
  terms), crossed with the evaluation's interpolation (`ifd filter --interp
  linear|auto`) and, with `--eval-budgets`, the evaluation's error budget
  (`ifd filter --eval-budget`, as a multiple of the fit's tolerance; the
  default plans for a third of it on white noise, which natural images,
  with less energy at high frequencies, rarely need); optionally the scalar loop too (`--scalar-too`, series
  "... scalar") and a second build (`--ifd-b`, series "ifd (B) ...") that
  filters with the same decompositions.
* the steerable basis (series "steerable", knob K, `--steerable-k` and
  `--steerable-k-scaled`): tests/bench/steerable.py, whose docstring has the
  method -- the family sampled at 90 angles (x 8 log-spaced scales over the
  scale range), its SVD weighted by a natural-image spectrum 1/(f^2 + f0^2),
  K basis kernels applied through one spectrum product and inverse DFT each
  with the one forward DFT of the padded image, per-pixel weights from
  truncated Fourier series in 2 theta and splines in log scale, the output
  divided by the basis' DC gain. Its fit (the SVD, shared by every K of a
  case, and the weights) and its kernels' spectra at the image size are
  excluded from the times and reported as the fit time.
* bins with the image spectrum computed once (series "bins (spectrum
  once)", knob the bins, `--fft-bins` and `--fft-bins-scaled` as ANGLExSCALE):
  the kernel rotated (and scaled) into bins, each applied through one
  spectrum product and inverse DFT with the one forward DFT of the padded
  image, blended per pixel linearly between the two nearest angle bins
  (wrapping) and bilinearly over the 2x2 nearest angle x log-scale bins
  (tests/bench/steerable.py too; the bins' kernels and spectra are the fit).
  These two are the strongest peers; `--peers` picks the peers to run.
* OpenCV's filter2D (series "OpenCV filter2D bins, RULE"), which has no
  per-pixel kernel: the usual workaround, the kernel
  rotated (and scaled) into bins, cv2.filter2D (float32, BORDER_REFLECT_101,
  its DFT path) once per bin, and a per-pixel selection among the bin
  outputs. The knob is the number of angle bins K (`--bins`); with the scale
  varying too, max(2, K // 4) scale bins spaced evenly in log scale over
  [0.5, 1] (and K <= `--max-bins-scaled`, 64 by default: 96x24 bins take
  minutes a run). Two selection rules, each its own series: "nearest" (the
  nearest angle bin, the nearest log-scale bin) and "blend" (linear weights
  between the two nearest angle bins, which wrap around since the Gaussian
  has period 180 degrees, and, with the scale varying, bilinear weights over
  the 2x2 nearest angle x log-scale bins; the weighted bin outputs are
  accumulated into one buffer, out += w_b(x) * f_b). The kernel of a bin at
  scale s is cropped to radius ceil(128 s), as a scaled decomposition is.

Accuracy: PSNR against exact per-pixel correlation (float64, the kernel
rotated and scaled at each pixel, on its 257x257 window, normalised to sum
1, reflect-101 borders), evaluated on a random sample of `--samples` pixels
(the same sample for every method of an image and case; the exact result
over a whole image would take hours). The peak of the PSNR is the range of
the exact values on the sample. The kernel's own fit error (relative L2) is
recorded for every ifd point too.

Timing: one thread each (cv2.setNumThreads(1); RAYON_NUM_THREADS=1 for ifd;
scipy.fft with workers=1 and one BLAS thread for the Python peers).
ifd's time is its planning (the evaluation plan's estimate), prefiltering
and filtering as `ifd filter --verbose` reports them (the "prefilter" column
includes the planning; not process start-up or file I/O, recorded apart as
wall_ms); the decompositions are fitted once beforehand (`--cache DIR` keeps
them between runs) and the fit time is excluded. OpenCV's time is the
per-pixel selection plus every cv2.filter2D call and the copy/accumulation
of its output; building the bins' kernels is excluded, as the fit is. The
steerable basis' and the spectrum-once bins' time is their apply call:
padding, the forward DFT, every spectrum product and inverse DFT, the
per-pixel weights and the accumulation. Every
configuration of an image and case runs `--runs` times (5 by default),
interleaved: one round of every configuration, then the next round; the
median and the min-max range are reported.

Output: a line per configuration (stdout) and a progress line per round
(stderr); `--json FILE` with every point; a plot (`--plot`, by default the
`--markdown` or `--json` path with `.png`, else in the temp folder): a panel per image and case, PSNR
against time (log scale), a line per series; and a markdown summary (stdout,
and `--markdown FILE`): for every series the time it needs to reach 40, 45,
50, 55 and 60 dB, interpolating log(time) linearly in PSNR between the neighbouring
points of the series' lower envelope (its Pareto front), each series' fit
time, the CPU's name, and the ratio of the best peer (the fastest of every
non-ifd series) to ifd's best series at 45, 50, 55 and 60 dB; then the
same ratio computed round by round from each round's times ("paired": every
round runs every point once, so the machine's drift between rounds cancels),
its median and range. A time marked "<=" is the series' cheapest point, which
is already past the target.

Full run (roughly an hour on one core of a 2020s x86 machine, most of it
OpenCV's angle+scale bins and ifd's finest tolerances; add `--peers
steerable,bins` to leave OpenCV's filter2D bins out; the progress lines on
stderr estimate what is left):

    .venv/bin/python tests/bench/curves_vs_opencv.py --ifd target/release/ifd --runs 5 \\
        --json docs/bench/ifd-vs-opencv-curves.json --markdown docs/bench/ifd-vs-opencv-curves.md

Smoke test: `--quick` (320x320: ifd refuses images narrower than the
kernel's 257 px; OpenCV bins 4,8,16, steerable K 4,8,12 (angle+scale
4,8,16), spectrum-once bins 4,8,16 (8x2,16x3), tols 0.02,0.01, 2 runs, 300
samples, one image; about a minute, most of it the angle+scale SVD).
`--replot FILE.json` redraws the plot and the summary from an earlier
`--json` without running anything.
"""

import argparse
import datetime
import json
import math
import os
import pathlib
import platform
import re
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

# Run as a script: one thread for BLAS too, before numpy loads it (the
# steerable basis' SVD, its fit, uses it; nothing timed does). Imported (by a
# test), the environment is left alone.
if __name__ == "__main__":
    for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_v, "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

import steerable as st  # noqa: E402
from ifd_paths import ROOT, ifd_binary  # noqa: E402

SX, SY = 32.0, 4.0  # 8:1
R = 128  # kernel radius at scale 1: extent 257
SPEC = "gauss:sx=32,sy=4,theta=0"
SMIN, SMAX = 0.5, 1.0  # the scale field's range (--scale-range sets SMIN)
TARGETS = (40.0, 45.0, 50.0, 55.0, 60.0)
RATIO_TARGETS = (45.0, 50.0, 55.0, 60.0)
IMAGES = ("camera", "astronaut", "smooth")
CASES = ("angle", "angle+scale")
RULES = ("nearest", "blend")
PEERS = ("steerable", "bins", "cv2")
PEER_SERIES = {"steerable": "steerable", "fftbins": "bins (spectrum once)"}


# ---------------------------------------------------------------------------
# inputs


def image_path(name):
    """The file of an image name: a bundled testdata/NAME.png, else a path."""
    bundled = ROOT / "testdata" / f"{name}.png"
    return bundled if bundled.exists() else pathlib.Path(name)


def image_label(name):
    """An image's name in the outputs: a path's file stem."""
    return pathlib.Path(name).stem if "/" in name else name


def load_image(name, n):
    """A grayscale float32 image in [0, 1], n x n: `smooth` (synthetic), a
    bundled testdata/NAME.png, or any image file's path."""
    if name != "smooth":
        path = image_path(name)
        im = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if im is None:
            raise SystemExit(f"cannot read {path}")
        return cv2.resize(im.astype(np.float32) / 255, (n, n), interpolation=cv2.INTER_CUBIC)
    if name == "smooth":
        # A few low-frequency plane waves (at most ~5.5 cycles per image) and a
        # soft radial bump, rescaled to [0, 1]; resolution independent.
        v, u = (np.mgrid[0:n, 0:n].astype(np.float64) + 0.5) / n
        f = (
            0.30 * np.sin(2 * np.pi * (1.3 * u + 0.4 * v) + 0.3)
            + 0.25 * np.sin(2 * np.pi * (0.7 * u - 1.9 * v) + 1.1)
            + 0.15 * np.cos(2 * np.pi * (2.6 * u + 1.7 * v))
            + 0.10 * np.sin(2 * np.pi * (4.5 * u - 3.2 * v) + 2.0)
            + 0.45 * np.exp(-((u - 0.42) ** 2 + (v - 0.58) ** 2) / (2 * 0.28**2))
        )
        f = (f - f.min()) / (f.max() - f.min())
        return f.astype(np.float32)
    raise SystemExit(f"unknown image {name!r}")


def fields(n):
    """The swirl angle field (degrees, [0, 180)) and the radial scale field
    ([0.5, 1]), float32: every method reads these same values."""
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    angles = (np.degrees(np.arctan2(-(yy - n / 2), xx - n / 2)) + 90.0) % 180.0
    scales = SMIN + (SMAX - SMIN) * np.hypot(xx - n / 2, yy - n / 2) / np.hypot(n / 2, n / 2)
    return angles.astype(np.float32), scales.astype(np.float32)


def gauss(sx, sy, theta_deg, r):
    """The rotated Gaussian on a (2r+1)^2 window, normalised to sum 1
    (y is the row offset, downwards; theta counter-clockwise on screen)."""
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    t = np.deg2rad(theta_deg)
    c, s = np.cos(t), np.sin(t)
    u, v = c * x - s * y, s * x + c * y
    k = np.exp(-0.5 * (u / sx) ** 2 - 0.5 * (v / sy) ** 2)
    return k / k.sum()


# ---------------------------------------------------------------------------
# exact reference


def exact_reference(img, pys, pxs, angles, scales, batch=24, sx=SX, sy=SY, r=R):
    """Exact correlation (float64) at the sampled pixels: the (2r+1)^2 kernel
    (by default the 257x257 gauss:sx=32,sy=4) rotated and scaled for each
    pixel, times the reflect-101 padded patch."""
    pad = np.pad(img.astype(np.float64), r, mode="reflect")  # numpy's "reflect" is reflect-101
    win = np.lib.stride_tricks.sliding_window_view(pad, (2 * r + 1, 2 * r + 1))
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    out = np.empty(len(pys))
    for b0 in range(0, len(pys), batch):
        py, px = pys[b0 : b0 + batch], pxs[b0 : b0 + batch]
        t = np.deg2rad(angles[py, px].astype(np.float64))[:, None, None]
        s = scales[py, px].astype(np.float64)[:, None, None]
        c, sn = np.cos(t), np.sin(t)
        u = (c * x - sn * y) / (sx * s)
        v = (sn * x + c * y) / (sy * s)
        k = np.exp(-0.5 * (u * u + v * v))
        patch = win[py, px]  # (B, 257, 257) copy
        out[b0 : b0 + batch] = np.einsum("bij,bij->b", k, patch) / k.sum(axis=(1, 2))
    return out


# ---------------------------------------------------------------------------
# OpenCV: binned cv2.filter2D


def bin_scale(j, ks):
    if ks == 1:
        return 1.0
    return math.exp(math.log(SMIN) + (math.log(SMAX) - math.log(SMIN)) * j / (ks - 1))


def bin_kernel(i, j, ka, ks):
    s = bin_scale(j, ks)
    return gauss(SX * s, SY * s, i * 180.0 / ka, max(1, math.ceil(R * s - 1e-9))).astype(np.float32)


def group(keys, nkeys):
    """Pixel indices grouped by key, and where each key's group starts."""
    # a stable sort of small integers is a radix sort in numpy: linear time
    order = np.argsort(keys.astype(np.int16 if nkeys < 32768 else np.int32), kind="stable")
    starts = np.zeros(nkeys + 1, np.int64)
    np.cumsum(np.bincount(keys, minlength=nkeys), out=starts[1:])
    return order, starts


def selection(angles, scales, ka, ks, rule):
    """The per-pixel selection, computed once a run. Angle bin i is at angle
    i * 180 / ka, scale bin j at log scale log(0.5) + j / (ks - 1) log(2).

    nearest: pixels grouped by their bin b = i * ks + j.
    blend: pixels grouped by their cell, the bins (i0, j0) below them
    (c = i0 * (ks - 1) + j0, or i0 without scale bins), with their fractional
    positions (wa, ws) past that corner; a pixel of cell (i0, j0) reads bins
    i0 and i0 + 1 (mod ka), j0 and j0 + 1 with bilinear weights."""
    p = angles.ravel() * np.float32(ka / 180.0)
    if ks > 1:
        q = (np.log(scales.ravel()) - np.float32(math.log(SMIN))) * np.float32(
            (ks - 1) / (math.log(SMAX) - math.log(SMIN))
        )
    if rule == "nearest":
        b = (np.rint(p).astype(np.int32) % ka) * ks
        if ks > 1:
            b += np.clip(np.rint(q), 0, ks - 1).astype(np.int32)
        order, starts = group(b, ka * ks)
        return {"order": order, "starts": starts}
    f0 = np.floor(p)
    c = f0.astype(np.int32) % ka  # wraps: period 180 degrees
    wa = p - f0
    ws = None
    if ks > 1:
        j0 = np.clip(np.floor(q), 0, ks - 2)
        ws = np.clip(q - j0, 0, 1)
        c = c * (ks - 1) + j0.astype(np.int32)
    order, starts = group(c, ka * max(ks - 1, 1))
    return {"order": order, "starts": starts, "wa": wa[order], "ws": None if ws is None else ws[order]}


def blend_parts(sel, i, j, ka, ks):
    """The pixel groups that read bin (i, j) under the blend rule: (slice of
    sel["order"], angle side, scale side), where a side is 0 for the corner
    (weight 1 - w) and 1 for the next bin (weight w)."""
    parts = []
    for di, a_side in ((0, 0), (1, 1)):
        ci = (i - di) % ka
        if ks == 1:
            parts.append((ci, a_side, None))
            continue
        for dj, s_side in ((0, 0), (1, 1)):
            cj = j - dj
            if 0 <= cj <= ks - 2:
                parts.append((ci * (ks - 1) + cj, a_side, s_side))
    st = sel["starts"]
    return [(slice(st[c], st[c + 1]), a, s) for c, a, s in parts if st[c + 1] > st[c]]


def cv2_binned(img, angles, scales, ka, ks, rule):
    """The binned workaround. Returns the output and the time (ms) of the
    selection and the filtering, kernel construction excluded."""
    t0 = time.perf_counter()
    sel = selection(angles, scales, ka, ks, rule)
    busy = time.perf_counter() - t0
    out = np.zeros(img.size, np.float32)
    order, starts = sel["order"], sel["starts"]
    for i in range(ka):
        for j in range(ks):
            if rule == "nearest":
                b = i * ks + j
                if starts[b + 1] == starts[b]:
                    continue
            else:
                parts = blend_parts(sel, i, j, ka, ks)
                if not parts:
                    continue
            k = bin_kernel(i, j, ka, ks)
            t0 = time.perf_counter()
            f = cv2.filter2D(img, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT_101).ravel()
            if rule == "nearest":
                px = order[starts[b] : starts[b + 1]]
                out[px] = f[px]
            else:  # every part holds distinct pixels: no repeated indices
                for sl, a_side, s_side in parts:
                    px = order[sl]
                    wa = sel["wa"][sl]
                    w = wa if a_side else 1 - wa
                    if s_side is not None:
                        ws = sel["ws"][sl]
                        w = w * (ws if s_side else 1 - ws)
                    out[px] += w * f[px]
            busy += time.perf_counter() - t0
    return out.reshape(img.shape), busy * 1e3


# ---------------------------------------------------------------------------
# ifd


# ---------------------------------------------------------------------------
# the strongest peers: tests/bench/steerable.py


def fit_peers(cases, peers, steer_k, fft_bins, n, budget_mb):
    """Fit the steerable bases (one weighted SVD per case, shared by every
    K) and the spectrum-once bins of every case, and their kernels' spectra
    at n x n (kept while they fit in `budget_mb`, else recomputed before each
    run, outside the timings). Returns {case: {(method, knob): fit}}; a fit
    holds the model, its spectra (or None), its display fields and params
    with the fit time (the model's fit plus the spectra at this size)."""
    kernel_at = st.gauss_kernel_at(SX, SY, R)
    fits, used = {}, 0.0
    for case in cases:
        sr = (SMIN, SMAX) if case == "angle+scale" else None
        fs = {}
        if "steerable" in peers:
            svd = st.family_svd(kernel_at, scale_range=sr)
            print(
                f"[{case}] steerable: weighted SVD of {svd['fam'].shape[0]} kernels in {svd['seconds']:.1f} s "
                "(shared by every K; in each K's fit time)",
                flush=True,
            )
            for i, k in enumerate(steer_k[case]):
                m = st.fit_steerable(kernel_at, k, svd=svd)
                fs[("steerable", k)] = {
                    "model": m, "order": i, "note": f"{k}", "name": f"steerable, K = {k}",
                    "params": {
                        "k": k, "svd_seconds": m.svd_seconds, "terms": len(m.pairs), "harmonics": max(m.harmonics),
                        "weighted_rel_error": math.sqrt(m.truncation_error),
                        "n_angles": m.n_angles, "n_scales": m.n_scales,
                    },
                }
            del svd
        if "bins" in peers:
            for i, (ka, ks) in enumerate(fft_bins[case]):
                b = st.fit_bins(kernel_at, ka, ks if sr else 1, scale_range=sr)
                note = f"{ka}x{b.ks}" if sr else f"{ka}"
                fs[("fftbins", note)] = {
                    "model": b, "order": i, "note": note,
                    "name": f"bins (spectrum once), {ka} angle" + (f" x {b.ks} scale bins" if sr else " bins"),
                    "params": {"bins_angle": ka, "bins_scale": b.ks, "bins": ka * b.ks},
                }
        for f in fs.values():
            t0 = time.perf_counter()
            spectra = st.prepare(f["model"], (n, n))
            prep = time.perf_counter() - t0
            mb = spectra.nbytes / 2**20
            f["spectra"] = spectra if used + mb <= budget_mb else None
            used += mb if f["spectra"] is not None else 0.0
            f["params"].update(prepare_seconds=prep, fit_seconds=f["model"].seconds + prep)
        if fs:
            print(
                f"[{case}] peers fitted: "
                + "; ".join(f"{f['name']} {f['params']['fit_seconds']:.2f} s" for f in fs.values())
                + f" (excluded from the timings; spectra kept: {used:.0f} MB)",
                flush=True,
            )
        fits[case] = fs
    return fits


def fail(what, p):
    sys.stderr.write(p.stderr or "")
    sys.stderr.write(f"\n{what} failed (exit {p.returncode}): {shlex.join(map(str, p.args))}\n")
    raise SystemExit(p.returncode or 1)


def has_scalar_flag(binary):
    p = subprocess.run([str(binary), "filter", "--help"], capture_output=True, text=True)
    if p.returncode:
        fail("ifd filter --help", p)
    return re.search(r"--scalar\b", p.stdout) is not None


def decompose(binary, tol, cache):
    """Fit (or reuse from `cache`) the decomposition at tolerance `tol`;
    returns its path and `ifd decompose --json`'s report."""
    stem = re.sub(r"[^A-Za-z0-9.]+", "_", SPEC) + f"_tol{tol:g}"
    path, rep = cache / f"{stem}.json", cache / f"{stem}.report.json"
    if path.exists() and rep.exists():
        return path, dict(json.loads(rep.read_text()), cached=True)
    args = [str(binary), "decompose", SPEC, "--tol", f"{tol:g}", "-o", str(path), "--json"]
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode:
        fail("ifd decompose", p)
    d = json.loads(p.stdout)
    rep.write_text(json.dumps(d, indent=2))
    return path, dict(d, cached=False)


def run_ifd(binary, img_npy, decomp, angle_npy, scale_npy, interp, scalar, extra, out_npy):
    """One `ifd filter` run: the output, planning plus prefiltering and
    filtering (ms, as reported by --verbose), the process's wall time (ms)
    and its notes."""
    args = [binary, "filter", img_npy, "--decomp", decomp, "--angle-map", angle_npy]
    if scale_npy is not None:
        args += ["--scale-map", scale_npy]
    args += ["-o", out_npy, "--verbose", "--interp", interp]
    if scalar:
        args.append("--scalar")
    args += extra
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    t0 = time.perf_counter()
    p = subprocess.run(list(map(str, args)), capture_output=True, text=True, env=env)
    wall = (time.perf_counter() - t0) * 1e3
    if p.returncode:
        fail("ifd filter", p)
    m, planning = None, 0.0
    for line in p.stderr.splitlines():
        mm = re.search(r"prefiltering ([0-9.]+) ms.*, filtering ([0-9.]+) ms", line)
        if mm:
            m = mm
            # Builds from before 2026-12-06 do not print their planning (a
            # bound: microseconds).
            mp = re.search(r"planning ([0-9.]+) ms", line)
            planning = float(mp.group(1)) if mp else 0.0
    if m is None:
        fail("ifd filter (no timing line in its --verbose output)", p)
    notes = [l.strip() for l in p.stderr.splitlines() if l.startswith(("evaluation:", "per-pixel lookups:"))]
    out = np.load(out_npy)
    if out.ndim == 3 and out.shape[2] == 1:
        out = out[:, :, 0]
    return out.astype(np.float32), planning + float(m.group(1)), float(m.group(2)), wall, notes


# ---------------------------------------------------------------------------
# curves: lower envelope, time to reach a PSNR


def front(points):
    """The lower envelope of (psnr, ms) points: sorted by PSNR, the points
    no slower than any point of higher PSNR (increasing in both)."""
    pts = sorted(((p, t) for p, t in points if math.isfinite(p)), key=lambda q: (q[0], -q[1]))
    keep, best = [], math.inf
    for p, t in reversed(pts):
        if t <= best:
            keep.append((p, t))
            best = t
    return keep[::-1]


def time_at(env, target):
    """(ms, how) to reach `target` dB on the envelope: how is "interp", "le"
    (the cheapest point already exceeds it) or None (not reached)."""
    if not env or env[-1][0] < target:
        return None, None
    if target <= env[0][0]:
        return env[0][1], "le"
    for (p0, t0), (p1, t1) in zip(env, env[1:]):
        if p0 <= target <= p1:
            if p1 == p0:
                return min(t0, t1), "interp"
            f = (target - p0) / (p1 - p0)
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0))), "interp"
    return None, None


def fmt_ms(ms, how=None):
    if ms is None:
        return "not reached"
    s = f"{ms:.0f} ms" if ms >= 10 else f"{ms:.1f} ms"
    return ("<= " + s) if how == "le" else s


METHOD_RANK = {"ifd": 0, "steerable": 1, "fftbins": 2, "cv2": 3}


def series_order(points):
    """Series names in a stable display order: ifd first, then the peers:
    the steerable basis, the bins with the spectrum once, OpenCV's bins."""
    seen, rank = [], {}
    for q in points:
        if q["series"] not in seen:
            seen.append(q["series"])
            rank[q["series"]] = METHOD_RANK.get(q["method"], 9)
    return sorted(seen, key=lambda s: (rank[s], seen.index(s)))


def fit_cell(sp):
    """The fit time of a series' points (s; a range), '-' when not recorded."""
    fs = [q["params"].get("fit_seconds") for q in sp]
    fs = [f for f in fs if f is not None]
    if not fs:
        return "-"
    lo, hi = min(fs), max(fs)
    return f"{lo:.2g} s" if hi - lo < 0.05 * hi + 0.01 else f"{lo:.2g}-{hi:.2g} s"


def summary(points, meta):
    lines = ["# ifd against its peers (steerable basis, bins with the spectrum once, OpenCV filter2D bins): "
             "time to reach a PSNR", ""]
    m = meta
    lines.append(f"CPU: **{m['cpu']}** (every time below: one thread, this CPU).")
    lines.append("")
    lines.append(
        f"{m['size']}x{m['size']} images, `{m['spec']}` (extent 257 px at scale 1), scale field over "
        f"[{m.get('scale_min', SMIN):g}, {SMAX:g}] in the angle+scale case, one thread each, "
        f"median of {m['runs']} interleaved runs; PSNR on {m['samples']} sampled pixels against exact "
        f"per-pixel correlation. OpenCV {m['opencv']}, numpy {m.get('numpy', '?')}, scipy {m.get('scipy', '?')}"
        + (f"; extra filter arguments `{m['ifd_extra']}`" if m.get("ifd_extra") else "")
        + "."
    )
    if m.get("command"):
        # the command as run, from the repository root (the binaries by the
        # paths given on its command line)
        lines += ["", f"Command: `.venv/bin/python {m['command']}`"]
    lines.append("")
    lines.append(
        "Times interpolate log(time) linearly in PSNR on each series' lower envelope; "
        "\"<=\" marks a series whose cheapest point is already past the target. "
        "The fit column is each point's one-off cost, outside the times: ifd's decomposition, the "
        "steerable basis' weighted SVD and weights plus its kernels' spectra at this image size, the "
        "bins' kernels and spectra (OpenCV's bins: not measured)."
    )
    panels = []
    for q in points:
        if (q["image"], q["case"]) not in panels:
            panels.append((q["image"], q["case"]))
    ratios = []
    for image, case in panels:
        pts = [q for q in points if q["image"] == image and q["case"] == case]
        lines += ["", f"## {image}, {case}", ""]
        hdr = "| series | " + " | ".join(f"{t:.0f} dB" for t in TARGETS) + " | points: PSNR range, time range | fit |"
        lines += [hdr, "|---" * (len(TARGETS) + 3) + "|"]
        at = {}
        for s in series_order(pts):
            sp = [q for q in pts if q["series"] == s]
            env = front([(q["psnr"], q["ms"]) for q in sp])
            at[s] = {t: time_at(env, t) for t in TARGETS}
            ps = [q["psnr"] for q in sp]
            ts = [q["ms"] for q in sp]
            cells = [fmt_ms(*at[s][t]) for t in TARGETS]
            lines.append(
                f"| {s} | " + " | ".join(cells)
                + f" | {len(sp)}: {min(ps):.1f}-{max(ps):.1f} dB, {min(ts):.0f}-{max(ts):.0f} ms | {fit_cell(sp)} |"
            )
        method_of = {q["series"]: q["method"] for q in pts}
        cv_series = [s for s in at if method_of[s] != "ifd"]  # every peer
        opencv_series = [s for s in at if method_of[s] == "cv2"]
        ifd_groups = {}
        for q in pts:
            if q["method"] == "ifd":
                ifd_groups.setdefault(q["binary_label"], [])
                if q["series"] not in ifd_groups[q["binary_label"]]:
                    ifd_groups[q["binary_label"]].append(q["series"])
        lines.append("")
        for blabel, iseries in ifd_groups.items():
            parts = []
            paired = paired_ratios(pts, iseries, cv_series)
            for t in RATIO_TARGETS:
                # (ms, how, series) of the fastest series that reaches t
                best_i = min(((*at[s][t], s) for s in iseries if at[s][t][0] is not None), default=None)
                best_c = min(((*at[s][t], s) for s in cv_series if at[s][t][0] is not None), default=None)
                best_o = min(((*at[s][t], s) for s in opencv_series if at[s][t][0] is not None), default=None)
                r = None
                if best_i and best_c:
                    r = best_c[0] / best_i[0]
                    parts.append(
                        f"at {t:.0f} dB, {best_c[2]} {fmt_ms(best_c[0], best_c[1])} / "
                        f"{best_i[2]} {fmt_ms(best_i[0], best_i[1])} "
                        f"= **{r:.1f}x**"
                    )
                elif best_i:
                    parts.append(f"at {t:.0f} dB, no peer reached it ({best_i[2]} {fmt_ms(best_i[0], best_i[1])})")
                elif best_c:
                    parts.append(f"at {t:.0f} dB, {blabel} not reached ({best_c[2]} {fmt_ms(best_c[0], best_c[1])})")
                else:
                    parts.append(f"at {t:.0f} dB, neither reached")
                rec = {
                    "image": image,
                    "case": case,
                    "binary": blabel,
                    "psnr": t,
                    "ratio": r,
                    "peer": best_c and {"series": best_c[2], "ms": best_c[0], "upper_bound": best_c[1] == "le"},
                    "opencv": best_o and {"series": best_o[2], "ms": best_o[0], "upper_bound": best_o[1] == "le"},
                    "ifd": best_i and {"series": best_i[2], "ms": best_i[0], "upper_bound": best_i[1] == "le"},
                }
                if paired:
                    rec["paired"] = paired.get(t)
                ratios.append(rec)
            lines.append(f"Best peer / {blabel} best: " + "; ".join(parts) + ".")
            if paired:
                cells = []
                for t in RATIO_TARGETS:
                    rs = paired.get(t)
                    cells.append(
                        f"{t:.0f} dB {statistics.median(rs):.1f}x ({min(rs):.1f}-{max(rs):.1f})"
                        if rs else f"{t:.0f} dB -"
                    )
                lines.append("")
                lines.append(
                    f"Paired, the median (range) over the rounds of each round's best peer / {blabel} best "
                    "(each round ran every point once, so the machine's drift between rounds cancels): "
                    + "; ".join(cells) + "."
                )
            lines.append("")
        while lines[-1] == "":
            lines.pop()
    return "\n".join(lines) + "\n", ratios


def paired_ratios(pts, iseries, cv_series, targets=RATIO_TARGETS):
    """For each target PSNR (the ratio targets unless given), the ratio best
    peer / ifd best computed round by round (each point's time in that
    round, the envelopes and the interpolation as in `summary`); targets
    either side misses in some round are left out. Empty when the points
    carry no per-round times."""
    runs = min((len(q.get("times_ms") or []) for q in pts), default=0)
    out = {}
    for r in range(runs):
        at = {}
        for s in set(iseries) | set(cv_series):
            env = front([(q["psnr"], q["times_ms"][r]) for q in pts if q["series"] == s])
            at[s] = {t: time_at(env, t) for t in targets}
        for t in targets:
            bi = [at[s][t][0] for s in iseries if at[s][t][0] is not None]
            bc = [at[s][t][0] for s in cv_series if at[s][t][0] is not None]
            if bi and bc:
                out.setdefault(t, []).append(min(bc) / min(bi))
    return {t: v for t, v in out.items() if len(v) == runs}


# ---------------------------------------------------------------------------
# plot


def style(q):
    """Colour, marker, line style and fill for a point's series."""
    if q["method"] == "cv2":
        return {"nearest": ("#d62728", "s"), "blend": ("#ff7f0e", "D")}.get(
            q["params"]["rule"], ("#8c564b", "v")
        ) + ("-", True)
    if q["method"] == "steerable":
        return "#9467bd", "P", "-", True
    if q["method"] == "fftbins":
        return "#8c564b", "X", "-", True
    colour = {"linear": "#1f77b4", "auto": "#2ca02c", "cubic": "#9467bd"}.get(q["params"]["interp"], "#17becf")
    b = q.get("binary_index", 0)
    # a budget series (`--eval-budgets`): a marker per multiple of --tol and a dash-dot line
    budget = q["params"].get("eval_budget") is not None
    multiple = round(q["params"]["eval_budget"] / q["params"]["tol"], 3) if budget else None
    marker = ({None: "o", 1: "s", 2: "D", 3: "v"}.get(multiple, "P") if b == 0 else "^")
    line = ":" if q["params"]["scalar"] else ("-." if budget else ("-" if b == 0 else "--"))
    return colour, marker, line, not q["params"]["scalar"]


def plot(points, meta, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    images = []
    cases = []
    for q in points:
        if q["image"] not in images:
            images.append(q["image"])
        if q["case"] not in cases:
            cases.append(q["case"])
    fig, axes = plt.subplots(
        len(images), len(cases), figsize=(6.2 * len(cases), 4.4 * len(images)), squeeze=False
    )
    for r, image in enumerate(images):
        for c, case in enumerate(cases):
            ax = axes[r][c]
            pts = [q for q in points if q["image"] == image and q["case"] == case]
            ax.set_title(f"{image}, {case}", fontsize=10)
            for t in TARGETS:
                ax.axvline(t, color="0.85", lw=0.8, zorder=0)
            for s in series_order(pts):
                sp = [q for q in pts if q["series"] == s]
                sp.sort(key=lambda q: q["order"])
                colour, marker, ls, filled = style(sp[0])
                xs = [q["psnr"] for q in sp]
                ys = [q["ms"] for q in sp]
                ax.plot(
                    xs, ys, ls=ls, marker=marker, color=colour, ms=4.5, lw=1.3,
                    mfc=colour if filled else "none", label=s,
                )
                lo = [q["ms"] - q["ms_min"] for q in sp]
                hi = [q["ms_max"] - q["ms"] for q in sp]
                ax.errorbar(xs, ys, yerr=[lo, hi], fmt="none", ecolor=colour, elinewidth=0.6, alpha=0.6)
                for q in sp:
                    dy = 5 if q["method"] == "ifd" else -9
                    ax.annotate(
                        q["note"], (q["psnr"], q["ms"]), textcoords="offset points", xytext=(3, dy),
                        fontsize=6, color=colour, alpha=0.75,
                    )
            ax.set_yscale("log")
            plain = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")
            ax.yaxis.set_major_formatter(plain)
            lo, hi = ax.get_ylim()
            some = matplotlib.ticker.FuncFormatter(
                lambda v, _: f"{v:g}" if v > 0 and round(v / 10 ** math.floor(math.log10(v) + 1e-9)) in (2, 3, 5) else ""
            )
            ax.yaxis.set_minor_formatter(some if hi / lo < 30 else matplotlib.ticker.NullFormatter())
            ax.tick_params(axis="y", which="minor", labelsize=7)
            ax.set_xlabel("PSNR (dB)")
            ax.set_ylabel("time (ms)")
            ax.grid(True, which="both", lw=0.3, alpha=0.5)
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(
        f"{meta['spec']} rotated (and scaled) per pixel,{' ' if len(cases) > 1 else chr(10)}"
        f"{meta['size']}x{meta['size']}, one thread, "
        f"median of {meta['runs']} runs, {meta['cpu']}\nlabels: ifd terms, steerable K, bins angle (x scale)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0, 1, (0.96 if len(images) > 1 else 0.92) - (0.02 if len(cases) == 1 else 0)))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)


# ---------------------------------------------------------------------------


def floats(s):
    return [float(v) for v in s.split(",") if v.strip()]


def ints(s):
    return [int(v) for v in s.split(",") if v.strip()]


def names(s):
    return [v.strip() for v in s.split(",") if v.strip()]


def amd_core(family, model):
    """The AMD core generation of a /proc/cpuinfo family and model, or None."""
    if family == 23:
        return "Zen 2" if model >= 0x30 else "Zen / Zen+"
    if family == 25:
        return "Zen 4" if 0x10 <= model <= 0x1F or 0x60 <= model <= 0xAF else "Zen 3"
    if family == 26:
        return "Zen 5"
    return None


def cpu_name():
    """The CPU's model name (/proc/cpuinfo), with its family and model, the
    AMD core generation they mean, the logical CPU count and AVX-512 when
    present: a virtual machine may show only "AMD EPYC"."""
    try:
        info = {}
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if ":" in line:
                k, v = line.split(":", 1)
                info.setdefault(k.strip(), v.strip())
        name = info.get("model name") or platform.processor() or platform.machine()
        extra = []
        if "cpu family" in info and "model" in info:
            fam, mod = int(info["cpu family"]), int(info["model"])
            core = amd_core(fam, mod) if info.get("vendor_id") == "AuthenticAMD" else None
            extra.append(f"family {fam} model {mod}" + (f", {core}" if core else ""))
        extra.append(f"{os.cpu_count()} logical CPUs")
        if "avx512f" in info.get("flags", "").split():
            extra.append("AVX-512")
        return f"{name} ({'; '.join(extra)})"
    except (OSError, ValueError):
        return platform.processor() or platform.machine()


def write_outputs(points, meta, a):
    if a.json:
        p = pathlib.Path(a.json)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(json.dumps({"meta": meta, "points": points}, indent=1))
    md, ratios = summary(points, meta)
    if a.plot:
        plot(points, meta, pathlib.Path(a.plot))
    if a.markdown:
        p = pathlib.Path(a.markdown)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(md)
    return md, ratios


def main():
    global SMIN  # --scale-range
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ifd", help="the ifd binary (default target/release/ifd, else target/debug/ifd)")
    ap.add_argument("--ifd-b", help="a second ifd binary, series 'ifd (B) ...', same decompositions")
    ap.add_argument("--label-b", default="ifd (B)", help="series prefix of --ifd-b (default 'ifd (B)')")
    ap.add_argument("--ifd-extra", default="", help="extra arguments for every `ifd filter` call (one string)")
    ap.add_argument("--scalar-too", action="store_true", help="also time `ifd filter --scalar` (separate series)")
    ap.add_argument("--size", type=int, help="image size N (N x N; default 1024)")
    ap.add_argument("--images", help=f"comma-separated: {','.join(IMAGES)}, other testdata/NAME.png or image paths (default {','.join(IMAGES)})")
    ap.add_argument("--cases", help=f"comma-separated subset of {','.join(CASES)} (default both)")
    ap.add_argument("--tols", help="ifd decompose --tol values (default 0.02,0.01,0.005,0.0025)")
    ap.add_argument("--interps", help="ifd filter --interp values (default linear,auto)")
    ap.add_argument("--eval-budgets", default="default",
                    help="ifd filter --eval-budget values as multiples of each fit's --tol, comma-separated; "
                    "'default' leaves it to ifd (a third of the fit's error); each its own series (default: default)")
    ap.add_argument("--bins", help="OpenCV filter2D angle bins (default 8,12,16,24,32,48,64,96)")
    ap.add_argument("--peers", default=",".join(PEERS),
                    help="peers to run: steerable (the steerable basis), bins (blended bins, spectrum once), "
                    "cv2 (OpenCV filter2D bins) (default all)")
    ap.add_argument("--steerable-k", help="steerable basis sizes K, angle case (default 4,6,8,10,12,14,16,20,24)")
    ap.add_argument("--steerable-k-scaled", help="steerable basis sizes K, angle+scale case (default 4,6,8,12,16,20,24,32,40,48)")
    ap.add_argument("--fft-bins", help="angle bins of the bins with the spectrum once, angle case (default 8,12,16,24,32,48)")
    ap.add_argument("--fft-bins-scaled",
                    help="angle x scale bins of the bins with the spectrum once, angle+scale case "
                    "(default 8x2,12x2,16x2,16x3,24x3,32x3,32x4,48x4)")
    ap.add_argument("--scale-range", type=float, default=SMIN, metavar="SMIN",
                    help=f"the scale field's smallest scale: [SMIN, 1] (default {SMIN:g}; 0.25, 0.125: the wide regimes)")
    ap.add_argument("--spectra-mb", type=float, default=1500,
                    help="memory for the peers' kernel spectra kept between runs (MB; beyond it they are recomputed "
                    "before each run, untimed; default 1500)")
    ap.add_argument("--max-bins-scaled", type=int, default=64, help="most angle bins in the angle+scale case (64)")
    ap.add_argument("--rules", default="nearest,blend", help="OpenCV selection rules (default nearest,blend)")
    ap.add_argument("--runs", type=int, help="timed runs of every configuration (default 5)")
    ap.add_argument("--samples", type=int, help="sampled pixels for the PSNR (default 2000)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the pixel sample")
    ap.add_argument("--cache", help="directory keeping the decompositions between runs (default: a temp dir)")
    ap.add_argument("--json", help="write every point here")
    ap.add_argument("--plot", help="the plot (default: beside --markdown, else --json, as .png; else in the temp folder; '' for none)")
    ap.add_argument("--markdown", help="write the summary here too")
    ap.add_argument("--replot", metavar="JSON", help="redraw plot and summary from an earlier --json; run nothing")
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: 320 px, bins 4,8,16, steerable K 4,8,12 (angle+scale 4,8,16), spectrum-once "
                    "bins 4,8,16 (8x2,16x3), tols 0.02,0.01, 2 runs, 300 samples, one image")
    a = ap.parse_args()

    q = a.quick
    if a.plot is None:
        # beside the summary or the points when written, else in the temp
        # folder: never over a committed figure unless asked for by name
        beside = a.markdown or a.json
        if beside and not q:
            a.plot = str(pathlib.Path(beside).with_suffix(".png"))
        else:
            name = "ifd-vs-opencv-curves-quick.png" if q else "ifd-vs-opencv-curves.png"
            a.plot = str(pathlib.Path(tempfile.gettempdir()) / name)

    if a.replot:
        d = json.loads(pathlib.Path(a.replot).read_text())
        md, _ = write_outputs(d["points"], d["meta"], argparse.Namespace(json=None, plot=a.plot, markdown=a.markdown))
        print(md, end="")
        if a.plot:
            print(f"plot: {a.plot}", file=sys.stderr)
        return 0

    n = a.size or (320 if q else 1024)
    images = names(a.images) if a.images else (["camera"] if q else list(IMAGES))
    cases = names(a.cases) if a.cases else list(CASES)
    tols = floats(a.tols) if a.tols else ([0.02, 0.01] if q else [0.02, 0.01, 0.005, 0.0025])
    interps = names(a.interps) if a.interps else ["linear", "auto"]
    bins = ints(a.bins) if a.bins else ([4, 8, 16] if q else [8, 12, 16, 24, 32, 48, 64, 96])
    peers = names(a.peers)
    for pname in peers:
        if pname not in PEERS:
            raise SystemExit(f"unknown peer {pname!r} (known: {', '.join(PEERS)})")
    steer_k = {
        "angle": ints(a.steerable_k) if a.steerable_k else ([4, 8, 12] if q else [4, 6, 8, 10, 12, 14, 16, 20, 24]),
        "angle+scale": ints(a.steerable_k_scaled) if a.steerable_k_scaled
        else ([4, 8, 16] if q else [4, 6, 8, 12, 16, 20, 24, 32, 40, 48]),
    }
    fft_bins = {
        "angle": [(k, 1) for k in ints(a.fft_bins)] if a.fft_bins else [(k, 1) for k in ([4, 8, 16] if q else [8, 12, 16, 24, 32, 48])],
        "angle+scale": [tuple(int(v) for v in b.split("x")) for b in names(a.fft_bins_scaled)] if a.fft_bins_scaled
        else ([(8, 2), (16, 3)] if q else [(8, 2), (12, 2), (16, 2), (16, 3), (24, 3), (32, 3), (32, 4), (48, 4)]),
    }
    if not 0 < a.scale_range < SMAX:
        raise SystemExit(f"--scale-range: in (0, {SMAX:g})")
    SMIN = a.scale_range
    rules = names(a.rules)
    runs = a.runs or (2 if q else 5)
    ns = a.samples or (300 if q else 2000)
    extra = shlex.split(a.ifd_extra)
    eval_budgets = [None if b.strip() == "default" else float(b) for b in a.eval_budgets.split(",")]
    if any(b is not None for b in eval_budgets) and "--eval-budget" in extra:
        sys.exit("--eval-budgets and an --eval-budget in --ifd-extra: give one of them")
    if n < 2 * R + 1:
        raise SystemExit(f"--size: at least {2 * R + 1} (ifd refuses a kernel wider than the image)")
    for c in cases:
        if c not in CASES:
            raise SystemExit(f"unknown case {c!r} (known: {', '.join(CASES)})")
    for r in rules:
        if r not in RULES:
            raise SystemExit(f"unknown rule {r!r} (known: {', '.join(RULES)})")
    if any(k < 2 for k in bins):
        raise SystemExit("--bins: at least 2 angle bins")

    ifd_a = ifd_binary(a.ifd)
    binaries = [("ifd", ifd_a)]
    if a.ifd_b:
        binaries.append((a.label_b, pathlib.Path(a.ifd_b)))
    for _, b in binaries:
        if not b.exists():
            raise SystemExit(f"no ifd binary at {b}")
    scalar_for = {}
    for i, (label, b) in enumerate(binaries):
        ok = a.scalar_too and has_scalar_flag(b)
        if a.scalar_too and not ok:
            if i == 0:
                raise SystemExit(f"--scalar-too: {b} has no `ifd filter --scalar`")
            print(f"note: {b} has no `ifd filter --scalar`; no scalar series for {label}", file=sys.stderr)
        scalar_for[label] = ok

    cv2.setNumThreads(1)
    angles, scales = fields(n)
    ones = np.ones_like(scales)
    rng = np.random.default_rng(a.seed)
    pys, pxs = rng.integers(0, n, ns), rng.integers(0, n, ns)

    meta = {
        "spec": SPEC,
        "size": n,
        "images": images,
        "cases": cases,
        "tols": tols,
        "interps": interps,
        "bins": bins,
        "max_bins_scaled": a.max_bins_scaled,
        "peers": peers,
        "steerable_k": steer_k,
        "fft_bins": {c: [f"{ka}x{ks}" for ka, ks in v] for c, v in fft_bins.items()},
        "scale_min": SMIN,
        "rules": rules,
        "runs": runs,
        "samples": ns,
        "seed": a.seed,
        "ifd": str(ifd_a),
        "ifd_b": a.ifd_b,
        "label_b": a.label_b if a.ifd_b else None,
        "ifd_extra": a.ifd_extra,
        "eval_budgets": a.eval_budgets,
        "scalar_too": a.scalar_too,
        "opencv": cv2.__version__,
        "numpy": np.__version__,
        "scipy": __import__("scipy").__version__,
        "cpu": cpu_name(),
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "command": shlex.join(sys.argv),
    }
    points = []
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        cache = pathlib.Path(a.cache) if a.cache else tmp / "decompositions"
        cache.mkdir(parents=True, exist_ok=True)
        decomps = []
        for tol in tols:
            path, rep = decompose(ifd_a, tol, cache)
            decomps.append((tol, path, rep))
            print(
                f"decomposition --tol {tol:g}: {rep['terms']} terms, kernel rel. L2 error "
                f"{100 * rep['rel_l2_error']:.2f}%, DC error {100 * rep.get('dc_error', math.nan):.3f}%, fit {rep['seconds']:.1f} s"
                + (" (cached)" if rep["cached"] else "")
                + " (excluded from the timings)",
                flush=True,
            )
        meta["decompositions"] = [
            {
                "tol": tol,
                "terms": rep["terms"],
                "rel_l2_error": rep["rel_l2_error"],
                "dc_error": rep.get("dc_error"),
                "fit_seconds": rep["seconds"],
            }
            for tol, _, rep in decomps
        ]
        fits = fit_peers(cases, peers, steer_k, fft_bins, n, a.spectra_mb)
        meta["peer_fits"] = {
            case: {f"{key[0]} {key[1]}": dict(f["params"]) for key, f in fs.items()} for case, fs in fits.items()
        }
        np.save(tmp / "angle.npy", angles)
        np.save(tmp / "scale.npy", scales)
        out_npy = tmp / "out.npy"

        for image in images:
            img = load_image(image, n)
            label = image_label(image)
            img_npy = tmp / f"{label}.npy"
            np.save(img_npy, img)
            for case in cases:
                scaled = case == "angle+scale"
                sc = scales if scaled else ones
                tag = f"[{label} | {case}]"
                t0 = time.perf_counter()
                exact = exact_reference(img, pys, pxs, angles, sc)
                peak = float(exact.max() - exact.min())
                print(f"{tag} exact reference on {ns} pixels: {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)

                def psnr(out):
                    mse = float(np.mean((out[pys, pxs].astype(np.float64) - exact) ** 2))
                    return 10 * math.log10(peak**2 / mse) if mse > 0 else math.inf

                configs = []
                for bi, (blabel, binary) in enumerate(binaries):
                    for interp, budget in [(i, b) for i in interps for b in eval_budgets]:
                        for scalar in [False, True] if scalar_for[blabel] else [False]:
                            for k, (tol, path, rep) in enumerate(decomps):
                                series = (
                                    f"{blabel} {interp}"
                                    + (f", eval budget {budget:g} tol" if budget is not None else "")
                                    + (" scalar" if scalar else "")
                                )
                                own = [] if budget is None else ["--eval-budget", f"{budget * tol:.6g}"]
                                configs.append(
                                    {
                                        "method": "ifd",
                                        "series": series,
                                        "binary_label": blabel,
                                        "binary_index": bi,
                                        "binary": str(binary),
                                        "order": k,
                                        "note": f"{rep['terms']}",
                                        "name": f"{series}, tol {tol:g} ({rep['terms']} terms)",
                                        "params": {
                                            "tol": tol,
                                            "terms": rep["terms"],
                                            "kernel_rel_l2_error": rep["rel_l2_error"],
                                            "kernel_dc_error": rep.get("dc_error"),
                                            "fit_seconds": rep["seconds"],
                                            "interp": interp,
                                            "scalar": scalar,
                                            "extra": a.ifd_extra,
                                            "eval_budget": None if budget is None else budget * tol,
                                        },
                                        "_run": (binary, path, interp, scalar, own),
                                    }
                                )
                for key, f in fits.get(case, {}).items():
                    method = key[0]
                    configs.append(
                        {
                            "method": method,
                            "series": PEER_SERIES[method],
                            "order": f["order"],
                            "note": f["note"],
                            "name": f["name"],
                            "params": f["params"],
                            "_fit": f,
                        }
                    )
                for rule in rules if "cv2" in peers else []:
                    for k, ka in enumerate(bins):
                        if scaled and ka > a.max_bins_scaled:
                            continue
                        ks = max(2, ka // 4) if scaled else 1
                        configs.append(
                            {
                                "method": "cv2",
                                "series": f"OpenCV filter2D bins, {rule}",
                                "order": k,
                                "note": f"{ka}x{ks}" if scaled else f"{ka}",
                                "name": f"OpenCV filter2D bins, {rule}, {ka} angle x {ks} scale bins",
                                "params": {"rule": rule, "bins_angle": ka, "bins_scale": ks, "bins": ka * ks},
                                "_run": (ka, ks, rule),
                            }
                        )
                for c in configs:
                    c.update(times=[], pre=[], filt=[], wall=[], psnr=None, notes=None)

                t_case = time.perf_counter()
                for rnd in range(runs):
                    t_round = time.perf_counter()
                    for c in configs:
                        if c["method"] == "ifd":
                            binary, path, interp, scalar, own = c["_run"]
                            out, pre, filt, wall, notes = run_ifd(
                                binary, img_npy, path, tmp / "angle.npy", tmp / "scale.npy" if scaled else None,
                                interp, scalar, extra + own, out_npy,
                            )
                            c["times"].append(pre + filt)
                            c["pre"].append(pre)
                            c["filt"].append(filt)
                            c["wall"].append(wall)
                            c["notes"] = notes
                        elif c["method"] in ("steerable", "fftbins"):
                            f = c["_fit"]
                            spectra = f["spectra"] if f["spectra"] is not None else st.prepare(f["model"], img.shape)
                            apply = st.apply_steerable if c["method"] == "steerable" else st.apply_bins
                            t0 = time.perf_counter()
                            out = apply(f["model"], spectra, img, angles, sc if scaled else None)
                            c["times"].append((time.perf_counter() - t0) * 1e3)
                            del spectra
                        else:
                            ka, ks, rule = c["_run"]
                            out, ms = cv2_binned(img, angles, sc, ka, ks, rule)
                            c["times"].append(ms)
                        c["psnr"] = psnr(out)
                        if rnd == runs - 1:
                            ms = float(np.median(c["times"]))
                            line = f"{tag} {c['name']}: {ms:.0f} ms [{min(c['times']):.0f}-{max(c['times']):.0f}]"
                            if c["method"] == "ifd":
                                line += f" (prefilter {np.median(c['pre']):.0f}, filter {np.median(c['filt']):.0f})"
                            print(line + f", PSNR {c['psnr']:.1f} dB", flush=True)
                    now = time.perf_counter()
                    left = (now - t_case) / (rnd + 1) * (runs - rnd - 1)
                    print(
                        f"{tag} round {rnd + 1}/{runs}: {now - t_round:.1f} s"
                        + (f", about {left:.0f} s left for this case" if left else "")
                        + f" (elapsed {now - t_start:.0f} s)",
                        file=sys.stderr,
                        flush=True,
                    )

                for c in configs:
                    p = {
                        "image": label,
                        "case": case,
                        "method": c["method"],
                        "series": c["series"],
                        "order": c["order"],
                        "note": c["note"],
                        "params": c["params"],
                        "ms": float(np.median(c["times"])),
                        "ms_min": float(min(c["times"])),
                        "ms_max": float(max(c["times"])),
                        "times_ms": [float(v) for v in c["times"]],
                        "psnr": c["psnr"],
                    }
                    if c["method"] == "ifd":
                        p.update(
                            binary_label=c["binary_label"],
                            binary_index=c["binary_index"],
                            binary=c["binary"],
                            prefilter_ms=float(np.median(c["pre"])),
                            filter_ms=float(np.median(c["filt"])),
                            wall_ms=float(np.median(c["wall"])),
                            ifd_notes=c["notes"],
                        )
                    points.append(p)
                meta["elapsed_s"] = time.perf_counter() - t_start
                write_outputs(points, meta, a)  # after every panel: an interrupted run keeps what it has

    md, ratios = write_outputs(points, meta, a)
    if a.json:  # with the ratios, for whoever reads the JSON
        pathlib.Path(a.json).write_text(json.dumps({"meta": meta, "points": points, "ratios": ratios}, indent=1))
    print()
    print(md, end="")
    if a.plot:
        print(f"plot: {a.plot}", file=sys.stderr)
    print(f"total {time.perf_counter() - t_start:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
