#!/usr/bin/env python3
"""Two builds of `ifd filter` side by side on the wide-scale jobs of
`curves_vs_opencv.py`: the 1024x1024 upscaled camera.png, the swirl angle
map and a radial scale map over [SMIN, 1] (SMIN 0.5, 0.25, 0.125: 2:1, 4:1,
8:1), the 8:1 Gaussian `gauss:sx=32,sy=4` fitted at several tolerances, each
build's default plan. One thread each (RAYON_NUM_THREADS=1), runs
interleaved (before, after; after, before; ...), medians of `--runs` of
`-v`'s planning, prefiltering and filtering times and of the whole process.
Also prints the largest difference of the two outputs, so that a faster
path that changed the result shows. With `--shapes`, the job is instead
`bench_shapes.py`'s: its three shapes (streak, blob, comet) fitted at each
tolerance, each for its tonal region (`--filter-map`), through one stack.

    .venv/bin/python tests/bench/ab_prefilter.py --before OLD/ifd --after target/release/ifd [--runs 7] [--shapes]
"""

import argparse
import json
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bench_shapes  # noqa: E402
import curves_vs_opencv as cvo  # noqa: E402

TIMES = re.compile(r"planning ([0-9.]+) ms, prefiltering ([0-9.]+) ms .*filtering ([0-9.]+) ms")


def run(binary, args, out):
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    t = time.perf_counter()
    p = subprocess.run([str(binary), "filter", *map(str, args), "-o", str(out), "-v"], capture_output=True, text=True, env=env)
    wall = (time.perf_counter() - t) * 1e3
    m = TIMES.search(p.stderr)
    if p.returncode or m is None:
        sys.exit(f"{binary} filter failed or printed no times:\n{p.stderr}")
    return [float(m.group(k)) for k in (1, 2, 3)] + [wall]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--smins", default="0.5,0.25,0.125")
    ap.add_argument("--tols", default="0.3,0.1,0.03")
    ap.add_argument("--shapes", action="store_true", help="bench_shapes.py's three shapes through --filter-map")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        img = cvo.load_image("camera", 1024).astype(np.float32)
        np.save(tmp / "img.npy", img)
        if a.shapes:
            np.save(tmp / "labels.npy", bench_shapes.labels_of(img).astype(np.float32))
        builds = {"before": a.before, "after": a.after}
        print("| scale range | --tol | terms | build | planning | prefiltering | filtering | -v total | process | after / before (-v total) | largest output difference |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for smin in map(float, a.smins.split(",")):
            cvo.SMIN = smin
            angles, scales = cvo.fields(1024)
            np.save(tmp / "angle.npy", angles)
            np.save(tmp / "scale.npy", scales)
            for tol in map(float, a.tols.split(",")):
                if a.shapes:
                    decomps = [bench_shapes.decompose(a.after, shape, tol, tmp)[0] for shape in bench_shapes.SHAPES]
                else:
                    decomps = [tmp / f"d{tol}.json"]
                    subprocess.run([a.after, "decompose", "gauss:sx=32,sy=4,theta=0", "--tol", str(tol), "-o",
                                    str(decomps[0])], check=True, capture_output=True)
                terms = sum(len(json.loads(d.read_text())["terms"]) for d in decomps)
                args = [tmp / "img.npy"] + [x for d in decomps for x in ("--decomp", d)]
                args += ["--filter-map", tmp / "labels.npy"] if a.shapes else []
                args += ["--angle-map", tmp / "angle.npy", "--scale-map", tmp / "scale.npy"]
                times = {k: [] for k in builds}
                for r in range(a.runs):
                    order = list(builds) if r % 2 == 0 else list(builds)[::-1]
                    for k in order:
                        times[k].append(run(builds[k], args, tmp / f"{k}.npy"))
                diff = float(np.abs(np.load(tmp / "before.npy") - np.load(tmp / "after.npy")).max())
                med = {k: [statistics.median(c) for c in zip(*v)] for k, v in times.items()}
                total = {k: sum(m[:3]) for k, m in med.items()}
                for k in builds:
                    m = med[k]
                    ratio = f"{total['after'] / total['before']:.2f}" if k == "after" else ""
                    shown = f"{diff:.1e}" if k == "after" else ""
                    print(f"| [{smin}, 1] | {tol} | {terms} | {k} | {m[0]:.1f} | {m[1]:.1f} | {m[2]:.1f} | {total[k]:.1f} | {m[3]:.0f} | {ratio} | {shown} |",
                          flush=True)


if __name__ == "__main__":
    main()
