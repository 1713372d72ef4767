"""CPU ISD shading, the fast path against the reference path, side by side:
`ifd render` (GGX alpha = 0.3, in-plane lobes, 1024x768, bundled forest map,
the environment behind the sphere) at L = 7, 11, 15, 30, each round running
every variant once in turn; medians of `render_seconds` (the render call
alone: rays, shading, background) over the rounds, and the largest
difference of the fast image from the reference one over the image maximum.

Variants:
- `f64-avx2`: `--precision f64` with `IFD_SIMD=avx2`, the path every render
  took before the f32 lanes (four f64 lanes a vector);
- `f32-avx2`: `--precision f32` with `IFD_SIMD=avx2` (eight f32 lanes);
- `f32`: the default, `--precision f32` on the CPU's best vectors (sixteen
  f32 lanes on AVX-512);
- `old` (with `--old BIN`): another build's `ifd` (e.g. the commit before
  the f32 lanes), run as it ran by default; the table then adds the median
  (and range) over the rounds of each round's old / default ratio, which
  cancels the machine's drift between rounds.

The lobe tables are built once beforehand (`ifd sphere brdf`), so table
building is not timed.

    cargo build --release -p ifd-cli
    python3 tests/bench/bench_isd_cpu.py [--rounds N] [--lmax 7,11,15,30] [--old BIN] [--json FILE]
"""

import argparse
import json
import os
import statistics
import subprocess
import tempfile

import numpy as np

IFD = os.path.join(os.environ.get("CARGO_TARGET_DIR", "target"), "release", "ifd")
VARIANTS = {
    "f64-avx2": (["--precision", "f64"], "avx2"),
    "f32-avx2": (["--precision", "f32"], "avx2"),
    "f32": (["--precision", "f32"], None),
}


def render(binary, lmax, table, flags, simd, out):
    env = dict(os.environ)
    env.pop("IFD_SIMD", None)
    if simd:
        env["IFD_SIMD"] = simd
    r = subprocess.run(
        [binary, "render", "--env", "testdata/forest.hdr", "--brdf", "ggx:alpha=0.3",
         "--lmax", str(lmax), "--table", table, "--size", "1024x768", "-o", out, "--json",
         *flags],
        capture_output=True, text=True, env=env, check=True)
    return json.loads(r.stdout)["render_seconds"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--lmax", default="7,11,15,30")
    ap.add_argument("--old", help="another build's ifd binary to time beside")
    ap.add_argument("--json", help="write the medians and errors here")
    a = ap.parse_args()
    variants = dict(VARIANTS)
    if a.old:
        variants = {"old": ([], None), **variants}
    rows = []
    with tempfile.TemporaryDirectory() as d:
        names = " | ".join(f"{v} fps" for v in variants)
        paired = " old / f32, paired (range) |" if a.old else ""
        print(f"| L | {names} | f32 / f64-avx2 |{paired} max diff / max |")
        print("|---|" + "---|" * (len(variants) + 2 + bool(a.old)))
        for lmax in (int(x) for x in a.lmax.split(",")):
            table = os.path.join(d, f"ggx{lmax}.lobes")
            subprocess.run([IFD, "sphere", "brdf", "--lmax", str(lmax), "-o", table,
                            "ggx:alpha=0.3"], capture_output=True, check=True)
            t = {v: [] for v in variants}
            for _ in range(a.rounds):
                for v, (flags, simd) in variants.items():
                    binary = a.old if v == "old" else IFD
                    out = os.path.join(d, f"{v}.npy")
                    t[v].append(render(binary, lmax, table, flags, simd, out))
            ref = np.load(os.path.join(d, "f64-avx2.npy"))
            fast = np.load(os.path.join(d, "f32.npy"))
            err = float(np.abs(fast - ref).max() / np.abs(ref).max())
            med = {v: statistics.median(x) for v, x in t.items()}
            row = {"lmax": lmax, "seconds": med, "runs": t, "max_diff_over_max": err}
            fps = " | ".join(f"{1 / med[v]:.2f}" for v in variants)
            cell = ""
            if a.old:
                # Each round ran the old build and the default one moments
                # apart: their ratio within the round cancels the machine's
                # drift between rounds (1.5x on a shared host), which the
                # ratio of the medians keeps.
                ratios = [o / f for o, f in zip(t["old"], t["f32"])]
                row["old_over_f32_paired"] = ratios
                cell = (f" {statistics.median(ratios):.2f}x ({min(ratios):.2f}-"
                        f"{max(ratios):.2f}) |")
            rows.append(row)
            print(f"| {lmax} | {fps} | {med['f64-avx2'] / med['f32']:.2f}x |{cell} {err:.1e} |",
                  flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rounds": a.rounds, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
