#!/usr/bin/env python3
"""Two builds of `ifd filter` side by side: per-pixel angle (constant scale 1
and 0.7) and angle + scale maps, on a 1024x1024 upscaled camera.png with a
swirl angle field and the 51-term 8:1 Gaussian `gauss:sx=32,sy=4` (extent
257), one thread each (RAYON_NUM_THREADS=1), runs interleaved, medians of
--runs. Times are the filtering step as `--verbose` reports it
(prefiltering excluded). Also prints the relative L2 difference of the two
outputs, so a speed-up that changed the result shows.

Usage: .venv/bin/python tests/bench/ab_filter.py --before OLD_IFD --after target/release/ifd [--runs 5]
       .venv/bin/python tests/bench/ab_filter.py --before target/release/ifd --before-args=--scalar \
           --after target/release/ifd --extra="--interp linear"   # one build, two evaluation paths
"""

import argparse
import os
import pathlib
import re
import statistics
import subprocess
import tempfile

import cv2
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", default=str(ROOT / "target" / "release" / "ifd"))
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--before-args", default="", help="extra ifd filter arguments of the first (e.g. --scalar)")
    ap.add_argument("--after-args", default="", help="extra ifd filter arguments of the second")
    ap.add_argument("--extra", default="", help="extra ifd filter arguments of both (e.g. --interp linear)")
    a = ap.parse_args()
    n = 1024
    cam = cv2.imread(str(ROOT / "testdata" / "camera.png"), cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255
    img = cv2.resize(cam, (n, n), interpolation=cv2.INTER_CUBIC)
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float64)
    angle = ((np.degrees(np.arctan2(-(yy - n / 2), xx - n / 2)) + 90.0) % 180.0).astype(np.float32)
    scale = (0.5 + 0.5 * np.hypot(xx - n / 2, yy - n / 2) / np.hypot(n / 2, n / 2)).astype(np.float32)
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        np.save(tmp / "img.npy", img)
        np.save(tmp / "angle.npy", angle)
        np.save(tmp / "scale.npy", scale)
        d = tmp / "d.json"
        subprocess.run([a.after, "decompose", "gauss:sx=32,sy=4,theta=0", "-o", d], check=True, capture_output=True)
        cases = {
            "angle map, scale 1": ["--angle-map", tmp / "angle.npy"],
            "angle map, scale 0.7": ["--angle-map", tmp / "angle.npy", "--scale", "0.7"],
            "angle and scale maps": ["--angle-map", tmp / "angle.npy", "--scale-map", tmp / "scale.npy"],
        }
        bins = {"before": (a.before, a.before_args.split()), "after": (a.after, a.after_args.split())}
        print("| case | before (ms) | after (ms) | before / after | rel. L2 difference |")
        print("|---|---|---|---|---|")
        for name, extra in cases.items():
            times = {k: [] for k in bins}
            for _ in range(a.runs):
                for k, (b, own) in bins.items():
                    args = [b, "filter", tmp / "img.npy", "--decomp", d, *extra, *a.extra.split(), *own, "-o", tmp / f"{k}.npy", "--verbose"]
                    p = subprocess.run(list(map(str, args)), capture_output=True, text=True, env=env, check=True)
                    times[k].append(float(re.search(r"filtering ([\d.]+) ms$", p.stderr.strip())[1]))
            x, y = np.load(tmp / "before.npy"), np.load(tmp / "after.npy")
            mb, ma = statistics.median(times["before"]), statistics.median(times["after"])
            diff = np.linalg.norm(x - y) / np.linalg.norm(x)
            print(f"| {name} | {mb:.0f} | {ma:.0f} | {mb / ma:.2f} | {diff:.1e} |")


if __name__ == "__main__":
    main()
