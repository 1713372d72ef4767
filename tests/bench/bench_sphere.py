"""Times ducc0 and pyshtools on the spherical tasks benchmarked for ifd-sphere.

Run from the repository root:  .venv/bin/python tests/bench/bench_sphere.py
ifd is timed in the same run through `ifd sphere sh` (single-threaded,
RAYON_NUM_THREADS=1), whose JSON (`--json`) reports the in-process analysis time, when
target/release/ifd or target/debug/ifd exists (`--ifd PATH` to choose); the
criterion bench `cargo bench -p ifd-sphere --bench sphere` gives the same
analysis without the CLI.

Tasks: SH analysis of a 1024x512 RGB equirectangular map at L = 8, 16, 32, 64
(ifd with `--projection centre`; ducc0: adjoint_synthesis_2d on the F1 grid with
the exact pixel solid angles, which reproduces those coefficients to 1e-15; pyshtools: SHExpandDH on the
512x1024 Driscoll-Healy grid, the closest equivalent it offers), and SH rotation
at orders N = 3..20 (ducc0.sht.rotate_alm), all single-threaded.
"""

import argparse
import json
import os
import pathlib
import subprocess
import tempfile
import time

import numpy as np
import ducc0
import pyshtools as pysh

ROOT = pathlib.Path(__file__).resolve().parents[2]


def best(f, repeat=5, number=1):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(number):
            f()
        ts.append((time.perf_counter() - t) / number)
    return min(ts)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd", help="the ifd binary (default: target/release/ifd, else target/debug/ifd)")
    a = ap.parse_args()
    H, W = 512, 1024
    rng = np.random.default_rng(0)
    img = rng.random((H, W, 3))
    v = np.arange(H)
    dA = (2 * np.pi / W) * (np.cos(np.pi * v / H) - np.cos(np.pi * (v + 1) / H))
    print("## SH analysis, 1024x512 RGB, single thread (ms)")
    print("| L | ifd sphere sh (in-process) | ducc0 | pyshtools SHExpandDH | ifd / ducc0 |")
    print("|---|---|---|---|---|")
    ifd = pathlib.Path(a.ifd) if a.ifd else next((p for p in [ROOT / "target/release/ifd", ROOT / "target/debug/ifd"] if p.exists()), None)
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    # The solid-angle weighting is done once, outside ducc0's timing.
    weighted = [np.ascontiguousarray((img[:, :, c] * dA[:, None])[None]) for c in range(3)]
    with tempfile.TemporaryDirectory() as tmp:
        np.save(f"{tmp}/map.npy", img.astype(np.float32))
        for L in [8, 16, 32, 64]:
            def ducc():
                for mp in weighted:
                    ducc0.sht.experimental.adjoint_synthesis_2d(
                        map=mp, spin=0, lmax=L, geometry="F1", phi0=np.pi / W, nthreads=1)

            def shtools():
                for c in range(3):
                    pysh.expand.SHExpandDH(img[:, :, c], norm=4, sampling=2, csphase=-1, lmax_calc=L)

            t_ifd = float("nan")
            if ifd is not None:
                ts = []
                for _ in range(5):
                    out = subprocess.run([str(ifd), "sphere", "sh", f"{tmp}/map.npy", "--lmax", str(L),
                                          "--keep-negatives", "--projection", "centre", "-o", f"{tmp}/c.npy",
                                          "--json"],
                                         capture_output=True, text=True, check=True, env=env)
                    ts.append(json.loads(out.stdout)["seconds"])
                t_ifd = min(ts)
            t_ducc = best(ducc)
            print(f"| {L} | {t_ifd * 1e3:.2f} | {t_ducc * 1e3:.2f} | {best(shtools) * 1e3:.2f} | {t_ifd / t_ducc:.2f} |")

    print()
    print("## SH rotation, ducc0.sht.rotate_alm, one real function, single thread (us per rotation)")
    print("| N | ducc0 |")
    print("|---|---|")
    for N in range(3, 21):
        L = N - 1
        alm = (rng.normal(size=(L + 1) * (L + 2) // 2) + 1j * rng.normal(size=(L + 1) * (L + 2) // 2))
        alm[: L + 1] = alm[: L + 1].real
        t = best(lambda: ducc0.sht.rotate_alm(alm, L, 0.3, 1.1, -0.7, 1), repeat=5, number=2000)
        print(f"| {N} | {t * 1e6:.2f} |")


if __name__ == "__main__":
    main()
