"""CPU ISD shading with the AVX2 SH kernels against the baseline code, side by
side: `ifd render` (GGX alpha = 0.3, 1024x768, bundled forest map) at
L = 7, 11, 15, 30, each round running the baseline (`IFD_SIMD=baseline`) and
then the default (AVX2 where the CPU has it); medians of `render_seconds`
(the render call alone) over the rounds.

    cargo build --release -p ifd-cli && python3 tests/bench/bench_simd.py [ROUNDS]
"""

import json
import os
import statistics
import subprocess
import sys
import tempfile

IFD = os.path.join(os.environ.get("CARGO_TARGET_DIR", "target"), "release", "ifd")


def render(lmax, mode, out):
    env = dict(os.environ)
    env.pop("IFD_SIMD", None)
    if mode == "baseline":
        env["IFD_SIMD"] = "baseline"
    r = subprocess.run(
        [IFD, "render", "--env", "testdata/forest.hdr", "--brdf", "ggx:alpha=0.3",
         "--lmax", str(lmax), "--size", "1024x768", "-o", out, "--json"],
        capture_output=True, text=True, env=env, check=True)
    return json.loads(r.stdout)["render_seconds"]


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    with tempfile.TemporaryDirectory() as d:
        print("| L | baseline fps | AVX2 fps | speed-up |\n|---|---|---|---|")
        for lmax in (7, 11, 15, 30):
            t = {"baseline": [], "avx2": []}
            for _ in range(rounds):
                for mode in t:
                    t[mode].append(render(lmax, mode, os.path.join(d, f"{mode}.png")))
            b, a = statistics.median(t["baseline"]), statistics.median(t["avx2"])
            print(f"| {lmax} | {1 / b:.2f} | {1 / a:.2f} | {b / a:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
