#!/usr/bin/env python3
"""Two builds' evaluation plans side by side: for every configuration of fit tolerance,
scale map (none, or the radial 0.5-1 one), `--interp` and `--eval-budget`, one
`ifd filter -v` run of each build (interleaved), on the 1024x1024 swirl job of
`curves_vs_opencv.py`. Reports whether the plans (the `evaluation:` line) and the outputs
(byte for byte) are the same, and the planning times (`-v`'s "planning") of each build:
their sums over all configurations and, per tolerance, their medians.

    .venv/bin/python tests/bench/ab_plans.py --before OLD/ifd --after target/release/ifd

One thread each (RAYON_NUM_THREADS=1); the fits are cached in a temporary folder.
"""

import argparse
import filecmp
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import curves_vs_opencv as cvo  # noqa: E402

TOLS = (0.4, 0.2, 0.1, 0.05, 0.03, 0.02, 0.015, 0.01)
INTERPS = ("linear", "auto", "cubic")


def run(binary, args, out):
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    p = subprocess.run([str(binary), "filter", *map(str, args), "-o", str(out), "-v"], capture_output=True, text=True, env=env)
    if p.returncode:
        sys.exit(f"{binary} filter failed:\n{p.stderr}")
    plan = next((l for l in p.stderr.splitlines() if l.startswith("evaluation:")), None)
    if plan is None:
        sys.exit(f"{binary}: no evaluation line in -v output")
    m = re.search(r"planning ([0-9.]+) ms", p.stderr)
    if m is None:
        sys.exit(f"{binary}: no planning time in -v output (a build from before 2026-12-06?)")
    return plan, float(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--image", default="camera")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        img = cvo.load_image(a.image, 1024)
        angles, scales = cvo.fields(1024)
        for name, arr in (("img", img), ("angle", angles), ("scale", scales)):
            np.save(tmp / f"{name}.npy", arr)
        same_plan = same_out = total = 0
        sums = {"before": 0.0, "after": 0.0}
        per_tol = {}
        for tol in TOLS:
            decomp, _ = cvo.decompose(a.after, tol, tmp)
            for scaled in (False, True):
                for interp in INTERPS:
                    for budget in dict.fromkeys((None, 0.001, tol, 0.03)):
                        args = [tmp / "img.npy", "--decomp", decomp, "--angle-map", tmp / "angle.npy", "--interp", interp]
                        if scaled:
                            args += ["--scale-map", tmp / "scale.npy"]
                        if budget is not None:
                            args += ["--eval-budget", f"{budget:g}"]
                        pb, tb = run(a.before, args, tmp / "before.npy")
                        pa, ta = run(a.after, args, tmp / "after.npy")
                        total += 1
                        same_plan += pb == pa
                        same_out += filecmp.cmp(tmp / "before.npy", tmp / "after.npy", shallow=False)
                        sums["before"] += tb
                        sums["after"] += ta
                        per_tol.setdefault(tol, []).append((tb, ta))
                        if pb != pa:
                            print(f"plan differs: tol {tol} scaled {scaled} {interp} budget {budget}:\n  {pb}\n  {pa}")
        print(f"{total} configurations: plans the same in {same_plan}, outputs byte-identical in {same_out}")
        print(f"planning, sum over all: before {sums['before']:.0f} ms, after {sums['after']:.0f} ms "
              f"({sums['before'] / sums['after']:.2f}x)")
        print("| --tol | planning before, median (ms) | after (ms) |")
        print("|---|---|---|")
        for tol, v in per_tol.items():
            print(f"| {tol:g} | {statistics.median(b for b, _ in v):.1f} | {statistics.median(x for _, x in v):.1f} |")
        if same_plan != total or same_out != total:
            sys.exit(1)


if __name__ == "__main__":
    main()
