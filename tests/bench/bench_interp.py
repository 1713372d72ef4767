#!/usr/bin/env python3
"""Bilinear against cubic B-spline levels: `ifd filter --interp linear|cubic`
on a 1024x1024 upscaled astronaut.png, for an 8:1 Gaussian and a second
derivative of a Gaussian, at a constant angle and with a swirl angle map.
Prints the medians of `--runs` runs (prefiltering and filtering, from `-v`)
as a markdown table.

Usage: .venv/bin/python tests/bench/bench_interp.py [--ifd target/release/ifd] [--runs 3]
"""

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from ifd_paths import ROOT, ifd_binary


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd")
    ap.add_argument("--runs", type=int, default=3)
    a = ap.parse_args()
    ifd = str(ifd_binary(a.ifd))
    with tempfile.TemporaryDirectory() as t:
        t = Path(t)
        img = cv2.resize(cv2.imread(str(ROOT / "testdata" / "astronaut.png"), 0), (1024, 1024))
        np.save(t / "img.npy", img.astype(np.float32) / 255)
        y, x = np.mgrid[0:1024, 0:1024]
        np.save(t / "swirl.npy", (np.degrees(np.arctan2(y - 512, x - 512)) + 90).astype(np.float32))
        print("| decomposition | pose | bilinear: prefilter, filter (ms) | cubic: prefilter, filter (ms) "
              "| filter, cubic / bilinear |")
        print("|---|---|---|---|---|")
        for spec in ["gauss:sx=16,sy=2", "dgauss:order=xx,sigma=8"]:
            subprocess.run([ifd, "decompose", spec, "-o", t / "d.json"], check=True, capture_output=True)
            for name, pose in [("constant", ["--angle", "30"]), ("angle map", ["--angle-map", t / "swirl.npy"])]:
                cells = []
                for interp in ["linear", "cubic"]:
                    pre, filt = [], []
                    for _ in range(a.runs):
                        p = subprocess.run([ifd, "filter", t / "img.npy", "--decomp", t / "d.json", *pose,
                                            "--interp", interp, "-o", t / "out.npy", "-v"],
                                           capture_output=True, text=True, check=True)
                        m = re.search(r"prefiltering ([\d.]+) ms.*filtering ([\d.]+) ms", p.stderr)
                        pre.append(float(m.group(1)))
                        filt.append(float(m.group(2)))
                    cells.append((statistics.median(pre), statistics.median(filt)))
                (pl, fl), (pc, fc) = cells
                print(f"| `{spec}` | {name} | {pl:.0f}, {fl:.0f} | {pc:.0f}, {fc:.0f} | {fc / fl:.2f}x |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
