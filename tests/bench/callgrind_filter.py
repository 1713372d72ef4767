#!/usr/bin/env python3
"""Instruction counts of `ifd filter`'s per-pixel evaluation (callgrind).

Wall-clock times on this shared 2-core VM vary by 20-30% between runs, so
close calls between two evaluation paths are backed by instruction counts,
which do not depend on the machine's load: each configuration runs once
under `valgrind --tool=callgrind`, collecting only inside the per-pixel
evaluation (`--toggle-collect` on `Filter::per_pixel`, whose rows the rayon
closure runs; prefiltering, file I/O and start-up are not counted), and the
count is divided by the term evaluations (pixels x terms). With `--cache-sim`
callgrind also simulates the caches (valgrind's model of this machine's L1
data cache and last-level cache, not the real Zen 4 hierarchy: an indication
of whether the lookups miss, where `perf` has no hardware counters, as in
this VM) and the misses per term evaluation are reported too.

Cases: a `--size` x `--size` upscaled camera.png (default 512), the 8:1
Gaussian `gauss:sx=32,sy=4` (51 terms at the default tolerance; `--tol`
another fit), a swirl
angle field (constant scale 1: one lookup per term) and angle + scale maps
(scale 0.5..1: two lookups per term), each with the vector gathers (the
default) and with `--scalar`; `--interp linear`. One thread.

Usage: .venv/bin/python tests/bench/callgrind_filter.py [--ifd target/release/ifd] [--size 512] [--tol T]
"""

import argparse
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

import cv2
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd", default=str(ROOT / "target" / "release" / "ifd"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--json", help="write the counts here")
    ap.add_argument("--cache-sim", action="store_true", help="also simulate the caches (slower)")
    ap.add_argument("--tol", type=float, help="the fit's `--tol` (default: `ifd decompose`'s)")
    a = ap.parse_args()
    if shutil.which("valgrind") is None:
        sys.exit("valgrind is not installed (Debian: apt-get install valgrind)")
    n = a.size
    cam = cv2.imread(str(ROOT / "testdata" / "camera.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
    img = cv2.resize(cam, (n, n), interpolation=cv2.INTER_CUBIC)
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    angle = ((np.degrees(np.arctan2(-(yy - n / 2), xx - n / 2)) + 90.0) % 180.0).astype(np.float32)
    scale = (0.5 + 0.5 * np.hypot(xx - n / 2, yy - n / 2) / np.hypot(n / 2, n / 2)).astype(np.float32)
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    rows = []
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        np.save(tmp / "img.npy", img)
        np.save(tmp / "angle.npy", angle)
        np.save(tmp / "scale.npy", scale)
        d = tmp / "d.json"
        tol = [] if a.tol is None else ["--tol", str(a.tol)]
        p = subprocess.run([a.ifd, "decompose", "gauss:sx=32,sy=4,theta=0", *tol, "-o", str(d), "--json"], capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"ifd decompose failed:\n{p.stderr}")
        terms = json.loads(p.stdout)["terms"]
        cases = {
            "angle map, scale 1": ["--angle-map", tmp / "angle.npy"],
            "angle and scale maps": ["--angle-map", tmp / "angle.npy", "--scale-map", tmp / "scale.npy"],
        }
        print(f"{n}x{n}, {terms} terms, one thread; instructions (Ir) inside Filter::per_pixel")
        if a.cache_sim:
            print("| case | path | Ir | Ir per term evaluation | data reads per term evaluation | L1 data read misses per term evaluation | last-level data read misses per term evaluation |")
            print("|---|---|---|---|---|---|---|")
        else:
            print("| case | path | Ir | Ir per term evaluation |")
            print("|---|---|---|---|")
        for name, extra in cases.items():
            for path, flags in [("avx2 gathers", []), ("scalar loop", ["--scalar"])]:
                out = tmp / "cg.out"
                sim = ["--cache-sim=yes"] if a.cache_sim else []
                args = ["valgrind", "--tool=callgrind", *sim, f"--callgrind-out-file={out}", "--toggle-collect=*Filter::per_pixel*",
                        a.ifd, "filter", tmp / "img.npy", "--decomp", d, *extra, "--interp", "linear", *flags, "-o", tmp / "o.npy"]
                p = subprocess.run(list(map(str, args)), capture_output=True, text=True, env=env)
                if p.returncode != 0:
                    sys.exit(f"callgrind run failed:\n{p.stderr[-3000:]}")
                m = re.search(r"Collected\s*:\s*([\d ]+)", p.stderr)
                events = re.search(r"^events:\s*(.*)$", out.read_text(), re.M)
                if not m or not events:
                    sys.exit(f"no counts in callgrind's output:\n{p.stderr[-2000:]}")
                counts = dict(zip(events[1].split(), map(int, m[1].split())))
                ir = counts["Ir"]
                evals = n * n * terms
                row = {"case": name, "path": path, "size": n, "terms": terms, **{k: v for k, v in counts.items()}}
                row["ir_per_term"] = ir / evals
                rows.append(row)
                if a.cache_sim:
                    print(f"| {name} | {path} | {ir:,} | {ir / evals:.1f} | {counts['Dr'] / evals:.2f} | {counts['D1mr'] / evals:.3f} | {counts['DLmr'] / evals:.4f} |", flush=True)
                else:
                    print(f"| {name} | {path} | {ir:,} | {ir / evals:.1f} |", flush=True)
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
