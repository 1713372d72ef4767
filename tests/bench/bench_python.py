#!/usr/bin/env python3
"""The Python module's cost over the Rust API (issue: Python module).

1. Call overhead: `ifd.filter` on a 64x64 image, 1000 calls; per call, the
   Python wall time minus the time the same call spent in Rust
   (`ifd.last_call_seconds()`, measured inside the extension around the
   library call). Median and 90th percentile.
2. Throughput: `ifd.filter` on a 1024x1024 image with a per-pixel angle
   (gauss sx=16, sy=2, 52 terms) against the Rust API
   (`ifd_planar::filter_image`, the same call, timed inside the
   `filter_timing` example), interleaved: one Python call, then one Rust
   process, --rounds times; medians. Both use --threads=N rayon threads
   (default 1) on the same cores.

Both sides must be built with the same Cargo profile: the script builds the
example with --profile (default release) and refuses a module built with
another (`maturin develop --release` in crates/ifd-py for release).

Usage: .venv/bin/python tests/bench/bench_python.py [--profile release|dev] [--rounds 9] [--threads=1]
"""

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

if __name__ == "__main__":
    # The thread pool's size is read when it starts: before ifd is imported.
    _threads = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--threads=")), "1")
    os.environ["RAYON_NUM_THREADS"] = _threads

import ifd  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", choices=["release", "dev"], default="release")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--calls", type=int, default=1000)
    ap.add_argument("--threads", default="1", help="rayon threads of both sides (write --threads=N)")
    args = ap.parse_args()
    built = ifd._ifd.__build_profile__
    if built != args.profile:
        sys.exit(f"the installed module is a {built} build; build a {args.profile} one "
                 f"(cd crates/ifd-py && maturin develop{' --release' if args.profile == 'release' else ''})"
                 " or pass --profile " + built)
    cargo = ["cargo", "build", "-q", "-p", "ifd-planar", "--example", "filter_timing"]
    if args.profile == "release":
        cargo.append("--release")
    subprocess.run(cargo, check=True, cwd=ROOT)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    example = target / ("release" if args.profile == "release" else "debug") / "examples" / "filter_timing"

    # 1. Call overhead.
    small = ifd.decompose("gauss:sx=4,sy=1,theta=0")
    img = np.random.default_rng(0).random((64, 64), dtype=np.float32)
    ifd.filter(img, small, angle=30.0)
    over = []
    for _ in range(args.calls):
        t = time.perf_counter()
        ifd.filter(img, small, angle=30.0)
        wall = time.perf_counter() - t
        over.append(wall - ifd.last_call_seconds())
    over = np.array(over) * 1e6
    print(f"call overhead, 64x64, {len(small)} terms, {args.calls} calls: "
          f"median {np.median(over):.1f} us, p90 {np.percentile(over, 90):.1f} us")

    # 2. Throughput against the Rust API.
    d = ifd.decompose("gauss:sx=16,sy=2,theta=0")
    n = 1024
    rng = np.random.default_rng(1)
    big = rng.random((n, n), dtype=np.float32)
    y, x = np.mgrid[0:n, 0:n].astype(np.float32)
    angle = (90.0 - np.degrees(np.arctan2(y - n / 2, x - n / 2))).astype(np.float32)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        np.save(tmp / "img.npy", big)
        np.save(tmp / "angle.npy", angle)
        d.save(tmp / "d.json")
        for _ in range(3):  # warm-up (thread pool, allocator, page faults), as the example does
            ifd.filter(big, d, angle=angle)
        py, rust = [], []
        for _ in range(args.rounds):
            t = time.perf_counter()
            ifd.filter(big, d, angle=angle)
            py.append(time.perf_counter() - t)
            out = subprocess.run([example, tmp / "img.npy", tmp / "d.json", tmp / "angle.npy", "1"],
                                 capture_output=True, text=True, check=True)
            rust.append(float(out.stdout.split()[-1]))
    mp, mr = float(np.median(py)), float(np.median(rust))
    print(f"throughput, {n}x{n}, per-pixel angle, {len(d)} terms, {args.rounds} interleaved rounds "
          f"({args.profile}, {os.environ['RAYON_NUM_THREADS']} thread(s)): ifd.filter {1e3 * mp:.1f} ms (range {1e3 * min(py):.1f}-{1e3 * max(py):.1f}), "
          f"Rust filter_image {1e3 * mr:.1f} ms (range {1e3 * min(rust):.1f}-{1e3 * max(rust):.1f}); "
          f"Python / Rust = {mp / mr:.3f}")


if __name__ == "__main__":
    main()
