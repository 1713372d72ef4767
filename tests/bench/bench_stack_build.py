#!/usr/bin/env python3
"""Scale-stack prefiltering: the direct separable build against the FFT
build, side by side on one core.

Runs `cargo`'s `stack_timing` example (build it first:
`cargo build --release -p ifd-planar --example stack_timing`) with
`IFD_STACK_BUILD=fft`, `direct` and unset (the cost model's choice), in
turn, `--rounds` times per stack (each run: the median of 7 builds after a
warm-up), and prints a markdown table of the medians over rounds: the two
builds, which one the model picked, and the speed-up of the picked build
over the FFT one.

    .venv/bin/python tests/bench/bench_stack_build.py --image /tmp/camera.npy --rounds 3
"""

import argparse
import os
import re
import statistics
import subprocess
import sys

STACKS = [
    # (sigma_min, sigma_max, pyramid factor): the cheap end's stacks
    # (angle map, then angle and scale maps), wider ones, unsubsampled ones.
    (4.0, 6.73, 2.0), (4.0, 6.73, 4.0), (2.0, 6.73, 2.0), (2.0, 6.73, 4.0),
    (0.5, 2.0, 4.0), (1.0, 32.0, 2.0), (1.0, 32.0, 8.0), (4.0, 64.0, 4.0),
    (1.0, 32.0, 1e9), (8.0, 32.0, 1e9),
]


def run(binary, image, stack, build):
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    env.pop("IFD_STACK_BUILD", None)
    if build:
        env["IFD_STACK_BUILD"] = build
    lo, hi, f = stack
    p = subprocess.run([binary, image, str(lo), str(hi), str(f)], capture_output=True, text=True, env=env)
    if p.returncode:
        sys.exit(f"stack_timing failed: {p.stderr}")
    m = re.search(r"median ([0-9.]+) ms.*, (\w+) build", p.stdout)
    return float(m.group(1)), m.group(2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--image", required=True, help="the image (any format ifd reads)")
    ap.add_argument("--bin", default="target/release/examples/stack_timing")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    times = {s: {"fft": [], "direct": [], "": []} for s in STACKS}
    picked = {}
    for r in range(a.rounds):
        for s in STACKS:
            for b in ("fft", "direct", ""):
                ms, used = run(a.bin, a.image, s, b)
                times[s][b].append(ms)
                if not b:
                    picked[s] = used
        print(f"round {r + 1}/{a.rounds} done", file=sys.stderr)
    print("| sigmas | pyramid factor | FFT build (ms) | direct build (ms) | picked | picked (ms) | FFT / picked |")
    print("|---|---|---|---|---|---|---|")
    for s in STACKS:
        fft, direct, auto = (statistics.median(times[s][b]) for b in ("fft", "direct", ""))
        factor = "none" if s[2] > 1e6 else f"{s[2]:g}"
        print(f"| {s[0]:g}-{s[1]:g} | {factor} | {fft:.1f} | {direct:.1f} | {picked[s]} | {auto:.1f} | {fft / auto:.2f}x |")


if __name__ == "__main__":
    main()
