"""Shading speed of `ifd render` (ISD, Eq. 22) and ISD against Monte Carlo at equal error.

Run from the repository root after building:  .venv/bin/python tests/bench/bench_render.py
(`--ifd PATH` to choose the binary; default target/release/ifd, else target/debug/ifd).

1. Frames per second at 1024x768, both variants (`isd`: per-band environment from SH;
   `isd-maps`: per-band prefiltered maps, bicubic), L = 7, 11, 15, 30 (the paper's Table I
   columns), GGX alpha = 0.3 (a lobe table) and Phong s = 32 (closed form), the unit sphere
   filling most of the frame. Time = the render call alone (`render_seconds`: no map loading,
   SH projection or table build), median of 3 runs, all cores.
2. Monte Carlo against ISD at equal RMS error against the exact oracle (128x128, GGX 0.3),
   as a curve: ISD at L = 8 ... 24 with 128-entry tables (in-plane lobes, with the shared
   2L + 1 layout timed beside it) (a table's size costs nothing per
   pixel and keeps its interpolation error below the band limit's); Monte Carlo at doubling
   samples per pixel until its relative RMS error is below ISD's smallest; at each ISD error the
   Monte Carlo time interpolated log-log between the two rungs that bracket it; both timed by
   their render calls (medians of --runs for ISD, one run per rung), same cores.
3. GPU frames per second (`ifd render --gpu`, shaders/isd_shade.wgsl) in the setting of part 1,
   both variants, GPU time per frame from timestamp queries (median of --frames shaded in one
   process after the upload; one frame from L = 15 up), and the CPU path's render time run
   beside it for the ratio.
   On a machine without a GPU the adapter is lavapipe (Mesa's software Vulkan on the same
   cores): the table reports the adapter, and lavapipe numbers say nothing of a real GPU.
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import tempfile

import numpy as np
from ifd_paths import ifd_binary

ROOT = pathlib.Path(__file__).resolve().parents[2]
ENV = ROOT / "testdata" / "forest.hdr"


def run(ifd, *args):
    p = subprocess.run([str(ifd), "render", "--env", str(ENV), *map(str, args), "--json"], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(p.stderr)
    return json.loads(p.stdout)


def rel_rms(a, b, mask):
    d = (a - b)[mask]
    return float(np.sqrt((d**2).sum() / (b[mask] ** 2).sum()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--part", choices=["1", "2", "3", "all"], default="all",
                    help="1: frames per second; 2: Monte Carlo against ISD; 3: GPU frames per second; "
                         "all: 1 and 2 (3 only when asked: slow on lavapipe)")
    ap.add_argument("--frames", type=int, default=3, help="part 3: frames per GPU measurement")
    ap.add_argument("--degrees", default="7,11,15,30", help="part 3: the degrees L")
    args = ap.parse_args()
    ifd = ifd_binary(args.ifd)
    print(f"binary: {ifd}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        if args.part in ("1", "all"):
            frames_per_second(ifd, tmp, args.runs)
        if args.part in ("2", "all"):
            isd_against_monte_carlo(ifd, tmp, args.runs)
        if args.part == "3":
            gpu_frames_per_second(ifd, tmp, args.frames, [int(x) for x in args.degrees.split(",")])


def frames_per_second(ifd, tmp, runs):
    print("\n| BRDF | L | isd fps | isd-maps fps | object pixels |")
    print("|---|---|---|---|---|")
    for brdf in ["ggx:alpha=0.3", "phong:s=32"]:
        for L in [7, 11, 15, 30]:
            table = []
            if not brdf.startswith("phong"):
                t = tmp / f"t{L}.lobes"
                subprocess.run([str(ifd), "sphere", "brdf", brdf, "--lmax", str(L), "-o", str(t)],
                               check=True, capture_output=True)
                table = ["--table", t]
            fps = {}
            for method in ["isd", "isd-maps"]:
                times = []
                for _ in range(runs):
                    out = run(ifd, "--brdf", brdf, "--lmax", L, *table, "--method", method,
                              "--size", "1024x768", "--eye", "1.9,-1.6,0.7", "--fov", "60",
                              "-o", tmp / "f.exr")
                    times.append(out["render_seconds"])
                fps[method] = 1.0 / statistics.median(times)
                pixels = out["object_pixels"]
            print(f"| {brdf} | {L} | {fps['isd']:.2f} | {fps['isd-maps']:.2f} | {pixels} |", flush=True)



def gpu_frames_per_second(ifd, tmp, frames, degrees):
    view = ["--size", "1024x768", "--eye", "1.9,-1.6,0.7", "--fov", "60"]
    print("\n| BRDF | L | variant | GPU ms/frame | GPU fps | CPU ms (same variant, same run) | GPU / CPU time | adapter |")
    print("|---|---|---|---|---|---|---|---|")
    for brdf in ["ggx:alpha=0.3", "phong:s=32"]:
        for L in degrees:
            table = []
            if not brdf.startswith("phong"):
                t = tmp / f"t{L}.lobes"
                subprocess.run([str(ifd), "sphere", "brdf", brdf, "--lmax", str(L), "-o", str(t)],
                               check=True, capture_output=True)
                table = ["--table", t]
            for method in ["isd", "isd-maps"]:
                common = ["--brdf", brdf, "--lmax", L, *table, "--method", method, *view]
                # one frame at L >= 15 (a frame takes minutes on lavapipe there)
                n = frames if L < 15 else 1
                gpu = run(ifd, *common, "--gpu", "--frames", n, "-o", tmp / "g.exr")["gpu"]
                cpu = run(ifd, *common, "-o", tmp / "c.exr")["render_seconds"]
                g = gpu["gpu_seconds_median"] or gpu["frame_seconds_median"]
                print(f"| {brdf} | {L} | {method} | {g * 1e3:.0f} | {1 / g:.3f} | {cpu * 1e3:.0f} | "
                      f"{g / cpu:.2f} | {gpu['adapter']} |", flush=True)


def isd_against_monte_carlo(ifd, tmp, runs):
    print("\nMonte Carlo against ISD at equal error (128x128, GGX alpha = 0.3, oracle = quadrature)")
    common = ["--brdf", "ggx:alpha=0.3", "--size", "128x128", "--no-background"]
    run(ifd, *common, "--method", "quadrature", "--mask", tmp / "m.npy", "-o", tmp / "q.npy")
    q = np.load(tmp / "q.npy").astype(np.float64)
    mask = np.load(tmp / "m.npy") > 0.5
    mask3 = np.repeat(mask[..., None] if mask.ndim == 2 else mask, 3, axis=-1)
    # ISD at several L: error against the oracle and render time (median of runs), with the
    # default in-plane lobes (L + 1) and, interleaved, the shared layout (2L + 1) for comparison.
    isd = []
    for L in [8, 12, 16, 20, 24]:
        tables = {}
        for lobes in ["in-plane", "shared"]:
            tables[lobes] = tmp / f"mc{L}-{lobes}.lobes"
            subprocess.run([str(ifd), "sphere", "brdf", "ggx:alpha=0.3", "--lmax", str(L),
                            "--theta-entries", "128", "--lobes", lobes, "-o", str(tables[lobes])],
                           check=True, capture_output=True)
        times = {k: [] for k in tables}
        errs = {}
        for _ in range(runs):
            for lobes, t in tables.items():
                out = run(ifd, *common, "--method", "isd", "--lmax", L, "--table", t, "-o", tmp / "i.npy")
                times[lobes].append(out["render_seconds"])
                errs[lobes] = rel_rms(np.load(tmp / "i.npy").astype(np.float64), q, mask3)
        err = errs["in-plane"]
        isd.append((L, err, statistics.median(times["in-plane"])))
        shared = statistics.median(times["shared"])
        print(f"ISD L = {L}: relative RMS {err:.5f}, {isd[-1][2] * 1e3:.1f} ms "
              f"(shared 2L+1 lobes: {errs['shared']:.5f}, {shared * 1e3:.1f} ms, "
              f"{shared / isd[-1][2]:.2f}x slower)", flush=True)
    # Monte Carlo at doubling samples until below the smallest ISD error.
    target = min(e for _, e, _ in isd)
    ladder = []
    spp = 32
    while True:
        out = run(ifd, *common, "--method", "mc", "--spp", spp, "-o", tmp / "mc.npy")
        err = rel_rms(np.load(tmp / "mc.npy").astype(np.float64), q, mask3)
        ladder.append((spp, err, out["render_seconds"]))
        print(f"MC {spp} spp: relative RMS {err:.5f}, {out['render_seconds'] * 1e3:.1f} ms", flush=True)
        if err <= target or spp >= 1 << 17:
            break
        spp *= 2
    # Equal error: between the two rungs that bracket ISD's error, error and time
    # interpolated log-log (error falls as a power of the samples, time grows linearly).
    print("\n| ISD L | ISD error | ISD time | MC spp at that error | MC time | ISD faster by |")
    print("|---|---|---|---|---|---|")
    for L, e, t in isd:
        below = [i for i, (_, me, _) in enumerate(ladder) if me <= e]
        if not below:
            print(f"| {L} | {e:.5f} | {t * 1e3:.1f} ms | beyond {ladder[-1][0]} | - | - |")
            continue
        i = below[0]
        if i == 0:
            n, mt = ladder[0][0], ladder[0][2]
        else:
            (n0, e0, t0), (n1, e1, t1) = ladder[i - 1], ladder[i]
            f = np.log(e / e0) / np.log(e1 / e0)
            n = n0 * (n1 / n0) ** f
            mt = t0 * (t1 / t0) ** f
        print(f"| {L} | {e:.5f} | {t * 1e3:.1f} ms | {n:.0f} | {mt:.2f} s | {mt / t:.0f}x |", flush=True)

if __name__ == "__main__":
    main()
