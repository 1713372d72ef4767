#!/usr/bin/env python3
"""Decomposition report: terms, errors, iterations and time of `ifd decompose`
for the filters the planar issue names, smooth and hard-edged, at the default
tolerance (1% relative L2) and, for hard-edged ones, at 5%. Errors are over
the kernel's window plus the fit's margin of zeros; hard-edged kernels are
also fitted between pixel centres (a grid twice as fine); the whole-plane DC
error is how much a constant image changes.

Usage: .venv/bin/python crates/ifd-paper/scripts/decompose_report.py [--ifd target/release/ifd]
Prints a markdown table (used in BENCHMARKS.md, "Planar IFD").
"""

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[3]

SMOOTH = [
    "gauss:sx=12,sy=3,theta=30",
    "gauss:sx=24,sy=3,theta=30",
    "gauss:sx=16,sy=2,theta=0",
    "gauss:sx=32,sy=4,theta=0",
    "dgauss:order=xx,sigma=4",
    "dgauss:order=xy,sigma=4",
    "log:sigma=4",
    "gabor:sigma=6,freq=0.1,theta=30",
]
HARD = ["box:w=15,h=5,theta=30", "disk:r=8", "line:len=31,width=1,theta=30", "box:w=31,h=31"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd", default=str(ROOT / "target" / "release" / "ifd"))
    a = ap.parse_args()
    print("| filter | --tol | terms | rel. L2 error | between pixels | max error (of peak) | DC error (window) "
          "| DC error (whole plane) | iterations | seconds |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as t:
        out = pathlib.Path(t) / "d.json"
        for spec, tol in [(s, 0.01) for s in SMOOTH] + [(s, tol) for s in HARD for tol in (0.01, 0.05)]:
            p = subprocess.run([a.ifd, "decompose", spec, "--tol", str(tol), "-o", str(out), "--json"], capture_output=True, text=True)
            if p.returncode != 0:
                print(f"| `{spec}` | {tol} | failed: {p.stderr.strip()} | | | | | | | |")
                continue
            r = json.loads(p.stdout)
            fine = r.get("fine_rel_l2_error")
            between = f"{100 * fine:.2f}% ({r['oversample']}x grid)" if fine is not None else "not fitted"
            print(
                f"| `{spec}` | {tol} | {r['terms']} | {100 * r['rel_l2_error']:.2f}% | {between} | "
                f"{100 * r['max_error']:.2f}% | {r['dc_error']:.1e} | {r['full_plane_dc_error']:.1e} | "
                f"{r['iterations']} | {r['seconds']:.1f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
