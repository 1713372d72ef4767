#!/usr/bin/env python3
"""Several filters of different shapes on one image, each for its own
region: ifd (one stack for all, `ifd filter --decomp A --decomp B ...
--filter-map labels.npy`) against the steerable basis (one basis per shape:
a steerable basis is needed per family), time against PSNR.

The job: a 1024x1024 photograph, every pixel filtered by one of three
kernels rotated along the swirl of `curves_vs_opencv.fields` (and, with
`--scale-range SMIN`, scaled by its radial map over [SMIN, 1]): the label map
is the image's own tone, smoothed (Gaussian, 8 px) and cut at its terciles
(dark, middle, light regions: a filter per material, the regions spread over
the whole image, so that cropping a region to filter it saves the basis
nothing). The shapes (each normalised to sum 1 on the 257x257 window):

- streak: gauss:sx=32,sy=4 (the standard case's 8:1 Gaussian),
- blob:   gauss:sx=16,sy=8 (2:1),
- comet:  a Gaussian of sigmas 16 and 3 px centred 20 px along its axis
          (not point-symmetric: its steerable basis needs the period 360).

ifd fits each shape once (`ifd decompose`; the comet as a kernel file) at
each `--tols` value, all three at the same tolerance, and filters with the
three through one stack, crossed with `--interp` and `--eval-budgets` (the
default, or 1 or 3 times `--tol`), one thread. The peer: per shape the
steerable basis of `steerable.py` (the weighted SVD of the family over 90
angles, 180 for the comet), its K chosen per shape for an equal weighted
truncation error `eps` (the SVD's relative error on natural-image spectra;
swept), the image's forward DFT computed once for all shapes (the same
radius), per basis kernel one spectrum product, one inverse DFT and its
weighting accumulated only over the shape's pixels (cv2 masks). PSNR against
exact float64 correlation with each sampled pixel's own rotated kernel on
`--samples` pixels; medians and paired ratios over `--runs` interleaved
rounds, as `curves_vs_opencv.py`.

Usage:
  RAYON_NUM_THREADS=1 .venv/bin/python tests/bench/bench_shapes.py --ifd target/release/ifd \\
      --images camera,PATH --runs 3 --json docs/bench/ifd-shapes.json --markdown docs/bench/ifd-shapes.md
"""

import argparse
import json
import math
import os
import pathlib
import platform
import random
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import curves_vs_opencv as cv  # noqa: E402
import steerable as st  # noqa: E402

R = 128  # every shape's window radius: one forward DFT serves them all
SHAPES = {
    # name: (sx, sy, offset along the axis, period of the family, ifd spec or None)
    "streak": (32.0, 4.0, 0.0, 180.0, "gauss:sx=32,sy=4"),
    "blob": (16.0, 8.0, 0.0, 180.0, "gauss:sx=16,sy=8"),
    "comet": (16.0, 3.0, 20.0, 360.0, None),
}
COMET_FILE_RADIUS = 90  # the comet's kernel file for ifd: 181x181 (reaches 20 + 4.4 sigma)
TARGETS = (45.0, 50.0, 55.0, 60.0)


def kernel(sx, sy, dx, theta_deg, s, y, x):
    """The shape rotated by theta (counter-clockwise on screen; y the row
    offset, downwards) and scaled by s, on the window y, x; not normalised."""
    t = math.radians(theta_deg)
    c, sn = math.cos(t), math.sin(t)
    u = (c * x - sn * y) / s - dx
    v = (sn * x + c * y) / s
    return np.exp(-0.5 * (u / sx) ** 2 - 0.5 * (v / sy) ** 2)


def kernel_at(shape):
    """`steerable.py`'s family function for a shape: (theta, s) -> window,
    sum 1."""
    sx, sy, dx, _, _ = SHAPES[shape]
    y, x = np.mgrid[-R : R + 1, -R : R + 1].astype(np.float64)

    def at(theta_deg, s=1.0):
        k = kernel(sx, sy, dx, theta_deg, s, y, x)
        return k / k.sum()

    at.r = R
    return at


def labels_of(img):
    """The label map: the image smoothed by 8 px, cut at its terciles."""
    import cv2

    sm = cv2.GaussianBlur(img, (0, 0), 8)
    q = np.quantile(sm, [1 / 3, 2 / 3])
    return ((sm > q[0]).astype(np.int32) + (sm > q[1])).astype(np.int32)


def exact(img, pys, pxs, angles, scales, labels, shapes):
    """Exact correlation (float64) at the sampled pixels, each with its own
    shape rotated and scaled, normalised to sum 1 on the window."""
    pad = np.pad(img.astype(np.float64), R, mode="reflect")  # reflect-101
    win = np.lib.stride_tricks.sliding_window_view(pad, (2 * R + 1, 2 * R + 1))
    y, x = np.mgrid[-R : R + 1, -R : R + 1].astype(np.float64)
    out = np.empty(len(pys))
    for i, (py, px) in enumerate(zip(pys, pxs)):
        sx, sy, dx, _, _ = SHAPES[shapes[labels[py, px]]]
        k = kernel(sx, sy, dx, float(angles[py, px]), float(scales[py, px]), y, x)
        out[i] = float((k * win[py, px]).sum() / k.sum())
    return out


def psnr(got, want):
    mse = float(np.mean((np.asarray(got, np.float64) - want) ** 2))
    return 10 * math.log10(1.0 / mse) if mse > 0 else math.inf


def decompose(binary, shape, tol, cache):
    """The shape's decomposition at `tol` (fitted once, kept in `cache`):
    its path, terms and fit seconds."""
    path = cache / f"{shape}_tol{tol:g}.json"
    rep = cache / f"{shape}_tol{tol:g}.report.json"
    if path.exists() and rep.exists():
        d = json.loads(rep.read_text())
        return path, d
    sx, sy, dx, _, spec = SHAPES[shape]
    if spec is None:
        r = COMET_FILE_RADIUS
        y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
        k = kernel(sx, sy, dx, 0.0, 1.0, y, x)
        spec = str(cache / f"{shape}.npy")
        np.save(spec, (k / k.sum()).astype(np.float32))
    args = [str(binary), "decompose", spec, "--tol", f"{tol:g}", "-o", str(path), "--json"]
    t0 = time.perf_counter()
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode:
        cv.fail("ifd decompose", p)
    d = json.loads(p.stdout)
    d["fit_seconds_wall"] = time.perf_counter() - t0
    rep.write_text(json.dumps(d))
    return path, d


def run_ifd(binary, files, decomps, interp, budget, out_npy):
    """One `ifd filter` run with the three decompositions and the label
    map: (output, planning + prefiltering, filtering, wall) in ms."""
    args = [str(binary), "filter", files["img"]]
    for d in decomps:
        args += ["--decomp", str(d)]
    args += ["--filter-map", files["labels"], "--angle-map", files["angle"]]
    if files.get("scale"):
        args += ["--scale-map", files["scale"]]
    args += ["-o", out_npy, "-v", "--interp", interp]
    if budget is not None:
        args += ["--eval-budget", f"{budget:g}"]
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    t0 = time.perf_counter()
    p = subprocess.run(args, capture_output=True, text=True, env=env)
    wall = (time.perf_counter() - t0) * 1e3
    if p.returncode:
        cv.fail("ifd filter", p)
    m = re.search(r"planning ([0-9.]+) ms, prefiltering ([0-9.]+) ms.*, filtering ([0-9.]+) ms", p.stderr)
    if m is None:
        cv.fail("ifd filter (no timing line in its -v output)", p)
    out = np.load(out_npy)
    if out.ndim == 3:
        out = out[:, :, 0]
    plan = float(m.group(1)) + float(m.group(2))
    notes = [l.strip() for l in p.stderr.splitlines() if l.startswith(("evaluation:", "filter "))]
    return out, plan, float(m.group(3)), wall, notes, float(m.group(1))


def fit_peer(shapes, eps_list, scale_range):
    """Per shape the weighted SVD and, per eps, the smallest K whose
    weighted truncation error is at most eps (capped at `max_k`): the
    models of every distinct K tuple, with their spectra at 1024^2 made by
    the caller. Returns ({shape: svd seconds}, [(eps, {shape: model})])."""
    svds, secs = {}, {}
    for s in shapes:
        period = SHAPES[s][3]
        svd = st.family_svd(kernel_at(s), scale_range=scale_range, n_angles=int(period / 2), period=period)
        svds[s], secs[s] = svd, svd["seconds"]
        print(f"steerable {s}: weighted SVD of {svd['fam'].shape[0]} kernels in {svd['seconds']:.1f} s", flush=True)
    configs, seen, models = [], set(), {}
    for eps in eps_list:
        ks = {}
        for s in shapes:
            lam = svds[s]["lam"]
            total = lam.sum()
            tail = np.concatenate([np.cumsum(lam[::-1])[::-1], [0.0]])  # tail[k] = sum lam[k:]
            ks[s] = next((k for k in range(1, len(lam) + 1) if math.sqrt(tail[k] / total) <= eps), len(lam))
        key = tuple(ks[s] for s in shapes)
        if key in seen:
            continue
        seen.add(key)
        ms = {}
        for s in shapes:
            if (s, ks[s]) not in models:
                models[(s, ks[s])] = st.fit_steerable(kernel_at(s), ks[s], svd=svds[s])
            ms[s] = models[(s, ks[s])]
        configs.append((eps, ms))
    return secs, configs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ifd", required=True)
    ap.add_argument("--images", default="camera")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--scale-range", type=float, help="SMIN: a radial scale map over [SMIN, 1] (default: angle only)")
    ap.add_argument("--tols", default="0.3,0.2,0.15,0.1,0.07,0.05,0.04,0.03,0.02,0.015,0.01")
    ap.add_argument("--interps", default="linear,auto")
    ap.add_argument("--eval-budgets", default="default,1,3")
    ap.add_argument("--eps", default="0.2,0.17,0.15,0.13,0.11,0.1,0.09,0.08,0.07,0.06,0.05,0.042,0.035,0.03,0.025,0.021,0.018,0.015,0.013,0.011,0.009,0.0075,0.006,0.005,0.004,0.003,0.002")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--samples", type=int, default=600)
    ap.add_argument("--json")
    ap.add_argument("--markdown")
    ap.add_argument("--quick", action="store_true", help="smoke test: 512 px, three tolerances, three eps")
    a = ap.parse_args()
    import cv2

    cv2.setNumThreads(1)  # one thread each: ifd runs with RAYON_NUM_THREADS=1
    n = 512 if a.quick else a.size
    tols = [0.3, 0.1, 0.03] if a.quick else cv.floats(a.tols)
    eps_list = [0.1, 0.03, 0.01] if a.quick else cv.floats(a.eps)
    interps = cv.names(a.interps)
    budgets = [None if b == "default" else float(b) for b in cv.names(a.eval_budgets)]
    shapes = list(SHAPES)
    scale_range = (a.scale_range, 1.0) if a.scale_range else None
    binary = pathlib.Path(a.ifd).resolve()
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="ifd-shapes-"))
    cache = tmp / "fits"
    cache.mkdir()

    # fits (outside the timings)
    decomps = {}
    for tol in tols:
        decomps[tol] = [decompose(binary, s, tol, cache) for s in shapes]
        print(f"ifd --tol {tol:g}: " + ", ".join(f"{s} {d[1]['terms']} terms" for s, d in zip(shapes, decomps[tol])),
              flush=True)
    t0 = time.perf_counter()
    svd_secs, peer = fit_peer(shapes, eps_list, scale_range)
    print(f"steerable: {len(peer)} K tuples in {time.perf_counter() - t0:.1f} s", flush=True)

    cv.SMIN = a.scale_range or cv.SMIN
    angles, scales_map = cv.fields(n)
    scales = scales_map if scale_range else np.ones_like(angles)
    points, meta = [], {"cpu": cv.cpu_name(), "size": n, "shapes": {s: SHAPES[s][:4] for s in shapes},
                        "scale_range": scale_range, "runs": a.runs, "samples": a.samples,
                        "python": platform.python_version(), "cv2_threads": cv2.getNumThreads()}
    for name in cv.names(a.images):
        label = cv.image_label(name)
        img = cv.load_image(name, n)
        labels = labels_of(img)
        files = {"img": str(tmp / "img.npy"), "labels": str(tmp / "labels.npy"), "angle": str(tmp / "angle.npy")}
        np.save(files["img"], img)
        np.save(files["labels"], labels.astype(np.float32))
        np.save(files["angle"], angles)
        if scale_range:
            files["scale"] = str(tmp / "scale.npy")
            np.save(files["scale"], scales)
        rng = np.random.default_rng(7)
        pys, pxs = rng.integers(0, n, a.samples), rng.integers(0, n, a.samples)
        t0 = time.perf_counter()
        want = exact(img, pys, pxs, angles, scales, labels, shapes)
        print(f"[{label}] exact reference on {a.samples} pixels in {time.perf_counter() - t0:.0f} s; "
              f"labels {np.bincount(labels.ravel()).tolist()}", flush=True)
        masks = [(labels == i).astype(np.uint8) for i in range(len(shapes))]
        # the peer's spectra for this size (outside the timings)
        spectra = {}
        for _, ms in peer:
            for s, m in ms.items():
                if (s, m.k) not in spectra:
                    spectra[(s, m.k)] = st.prepare(m, (n, n))
        jobs = []
        for tol in tols:
            for interp in interps:
                for b in budgets:
                    jobs.append(("ifd", (tol, interp, b)))
        for eps, ms in peer:
            jobs.append(("steerable", (eps, ms)))
        img_pts = {}
        for rnd in range(a.runs):
            order = list(range(len(jobs)))
            random.Random(rnd).shuffle(order)
            for j in order:
                kind, cfg = jobs[j]
                if kind == "ifd":
                    tol, interp, b = cfg
                    budget = None if b is None else b * tol
                    out, plan, filt, wall, notes, planning = run_ifd(
                        binary, files, [d[0] for d in decomps[tol]], interp, budget, str(tmp / "out.npy"))
                    ms_ = plan + filt
                    key = ("ifd", tol, interp, b)
                    series = f"ifd {interp}" + ("" if b is None else f", budget {b:g} x tol")
                    params = {"tol": tol, "interp": interp, "eval_budget": b, "planning_ms": planning,
                              "terms": [d[1]["terms"] for d in decomps[tol]],
                              "fit_seconds": sum(d[1].get("fit_seconds_wall", 0.0) for d in decomps[tol]),
                              "notes": notes}
                else:
                    eps, models = cfg
                    t1 = time.perf_counter()
                    x = st._forward(img, R)
                    out = np.zeros((n, n), np.float32)
                    for i, s in enumerate(shapes):
                        m = models[s]
                        o = st.apply_steerable(m, spectra[(s, m.k)], img, angles,
                                               scales if scale_range else None, x=x, mask=masks[i])
                        np.copyto(out, o, where=masks[i].astype(bool))
                    ms_ = (time.perf_counter() - t1) * 1e3
                    wall = ms_
                    key = ("steerable", eps)
                    series = "steerable"
                    params = {"eps": eps, "k": {s: models[s].k for s in shapes},
                              "fit_seconds": sum(svd_secs.values())}
                got = out[pys, pxs]
                q = img_pts.setdefault(key, {"image": label, "series": series, "method": key[0], "params": params,
                                             "psnr": psnr(got, want), "times_ms": [], "wall_ms": []})
                q["times_ms"].append(ms_)
                q["wall_ms"].append(wall)
            print(f"[{label}] round {rnd + 1}/{a.runs} done", flush=True)
        for q in img_pts.values():
            q["ms"] = float(np.median(q["times_ms"]))
            points.append(q)
    text = report(points, meta)
    print(text)
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps({"meta": meta, "points": points}, indent=1))
    if a.markdown:
        pathlib.Path(a.markdown).write_text(text)


def report(points, meta):
    """Per image: each side's cheapest time to reach 45-60 dB (medians) and
    the paired ratio steerable / ifd (median and range over the rounds)."""
    scale = meta["scale_range"]
    lines = [
        f"# Three shapes on one image: ifd (one stack) against a steerable basis per shape",
        "",
        f"CPU: {meta['cpu']}; {meta['size']}x{meta['size']}, one thread each; "
        + (f"angle map and scale over [{scale[0]:g}, 1]" if scale else "angle map")
        + f"; {meta['samples']} pixels against exact correlation; {meta['runs']} rounds.",
        "",
        "| image | target | steerable (K per shape) | ifd (terms per shape; plan) | steerable / ifd |",
        "|---|---|---|---|---|",
    ]
    for img in dict.fromkeys(q["image"] for q in points):
        pts = [q for q in points if q["image"] == img]
        iseries = sorted({q["series"] for q in pts if q["method"] == "ifd"})
        ratios = cv.paired_ratios(pts, iseries, ["steerable"], TARGETS)
        for t in TARGETS:
            def cheapest(pred):
                ok = [q for q in pts if pred(q) and q["psnr"] >= t]
                return min(ok, key=lambda q: q["ms"]) if ok else None
            s = cheapest(lambda q: q["method"] == "steerable")
            i = cheapest(lambda q: q["method"] == "ifd")
            sc = (f"{s['ms']:.0f} ms ({'/'.join(str(k) for k in s['params']['k'].values())}; {s['psnr']:.1f} dB)"
                  if s else "not reached")
            ic = (f"{i['ms']:.0f} ms ({'/'.join(map(str, i['params']['terms']))}; --tol {i['params']['tol']:g}, "
                  f"{i['series'][4:]}; {i['psnr']:.1f} dB)" if i else "not reached")
            r = ratios.get(t)
            rc = f"{np.median(r):.1f}x ({min(r):.1f}-{max(r):.1f})" if r else "-"
            lines.append(f"| {img} | {t:g} dB | {sc} | {ic} | {rc} |")
        best = max((q["psnr"] for q in pts if q["method"] == "steerable"), default=None)
        if best is not None:
            lines.append(f"| {img} | peer's best | {best:.1f} dB | ifd's best: "
                         f"{max(q['psnr'] for q in pts if q['method'] == 'ifd'):.1f} dB | |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
