"""Times ducc0 and pyshtools on the spherical tasks benchmarked for ifd-sphere.

Run from the repository root:  .venv/bin/python tests/bench/bench_sphere.py
(our numbers come from `cargo bench -p ifd-sphere --bench sphere` in the same
session; the script also times `ifd sphere sh`, whose JSON reports the in-process
analysis time, when target/debug/ifd or target/release/ifd exists).

Tasks: SH analysis of a 1024x512 RGB equirectangular map at L = 8, 16, 32, 64
(ducc0: adjoint_synthesis_2d on the F1 grid with the exact pixel solid angles,
which reproduces ifd's coefficients to 1e-15; pyshtools: SHExpandDH on the
512x1024 Driscoll-Healy grid, the closest equivalent it offers), and SH rotation
at orders N = 3..20 (ducc0.sht.rotate_alm), all single-threaded.
"""

import json
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
    H, W = 512, 1024
    rng = np.random.default_rng(0)
    img = rng.random((H, W, 3))
    v = np.arange(H)
    dA = (2 * np.pi / W) * (np.cos(np.pi * v / H) - np.cos(np.pi * (v + 1) / H))
    print("## SH analysis, 1024x512 RGB, single thread (ms)")
    print("| L | ducc0 | pyshtools SHExpandDH | ifd sphere sh (CLI, in-process) |")
    print("|---|---|---|---|")
    ifd = next((p for p in [ROOT / "target/release/ifd", ROOT / "target/debug/ifd"] if p.exists()), None)
    with tempfile.TemporaryDirectory() as tmp:
        np.save(f"{tmp}/map.npy", img.astype(np.float32))
        for L in [8, 16, 32, 64]:
            def ducc():
                for c in range(3):
                    mp = (img[:, :, c] * dA[:, None])[None]
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
                                          "--keep-negatives", "-o", f"{tmp}/c.npy"],
                                         capture_output=True, text=True, check=True)
                    ts.append(json.loads(out.stdout)["seconds"])
                t_ifd = min(ts)
            print(f"| {L} | {best(ducc) * 1e3:.2f} | {best(shtools) * 1e3:.2f} | {t_ifd * 1e3:.2f} |")

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
