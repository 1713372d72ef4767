"""Shading speed of `ifd render` (ISD, Eq. 22) and ISD against Monte Carlo at equal error.

Run from the repository root after building:  .venv/bin/python tests/bench/bench_render.py
(`--ifd PATH` to choose the binary; default target/release/ifd, else target/debug/ifd).

1. Frames per second at 1024x768, both variants (`isd`: per-band environment from SH;
   `isd-maps`: per-band prefiltered maps, bicubic), L = 7, 11, 15, 30 (the paper's Table I
   columns), GGX alpha = 0.3 (a lobe table) and Phong s = 32 (closed form), the unit sphere
   filling most of the frame. Time = the render call alone (`render_seconds`: no map loading,
   SH projection or table build), median of 3 runs, all cores.
2. Monte Carlo against ISD at equal RMS error against the exact oracle (128x128, GGX 0.3):
   ISD at L = 16 with a 96-entry table (the table's size costs nothing per pixel and keeps its
   interpolation error below the band limit's); Monte Carlo at doubling samples per pixel until
   its relative RMS error is at most ISD's; both timed by their render calls, same cores.
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
    p = subprocess.run([str(ifd), "render", "--env", str(ENV), *map(str, args)], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(p.stderr)
    return json.loads(p.stdout.strip().splitlines()[-1])


def rel_rms(a, b, mask):
    d = (a - b)[mask]
    return float(np.sqrt((d**2).sum() / (b[mask] ** 2).sum()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ifd")
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    ifd = ifd_binary(args.ifd)
    print(f"binary: {ifd}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
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
                    for _ in range(args.runs):
                        out = run(ifd, "--brdf", brdf, "--lmax", L, *table, "--method", method,
                                  "--size", "1024x768", "--eye", "1.9,-1.6,0.7", "--fov", "60",
                                  "-o", tmp / "f.exr")
                        times.append(out["render_seconds"])
                    fps[method] = 1.0 / statistics.median(times)
                    pixels = out["object_pixels"]
                print(f"| {brdf} | {L} | {fps['isd']:.2f} | {fps['isd-maps']:.2f} | {pixels} |", flush=True)

        print("\nMonte Carlo against ISD at equal error (128x128, GGX alpha = 0.3, oracle = quadrature)")
        common = ["--brdf", "ggx:alpha=0.3", "--size", "128x128", "--no-background"]
        run(ifd, *common, "--method", "quadrature", "--mask", tmp / "m.npy", "-o", tmp / "q.npy")
        q = np.load(tmp / "q.npy").astype(np.float64)
        mask = np.load(tmp / "m.npy") > 0.5
        mask3 = np.repeat(mask[..., None] if mask.ndim == 2 else mask, 3, axis=-1)
        subprocess.run([str(ifd), "sphere", "brdf", "ggx:alpha=0.3", "--lmax", "16", "--theta-entries", "96",
                        "-o", str(tmp / "t.lobes")],
                       check=True, capture_output=True)
        isd_t = []
        for _ in range(args.runs):
            out = run(ifd, *common, "--method", "isd", "--lmax", 16, "--table", tmp / "t.lobes", "-o", tmp / "i.npy")
            isd_t.append(out["render_seconds"])
        isd_err = rel_rms(np.load(tmp / "i.npy").astype(np.float64), q, mask3)
        isd_time = statistics.median(isd_t)
        print(f"ISD L = 16: relative RMS {isd_err:.4f}, {isd_time * 1e3:.1f} ms")
        spp = 64
        while True:
            out = run(ifd, *common, "--method", "mc", "--spp", spp, "-o", tmp / "mc.npy")
            err = rel_rms(np.load(tmp / "mc.npy").astype(np.float64), q, mask3)
            print(f"MC {spp} spp: relative RMS {err:.4f}, {out['render_seconds'] * 1e3:.1f} ms", flush=True)
            if err <= isd_err or spp >= 1 << 16:
                break
            spp *= 2
        mc_t = [out["render_seconds"]]
        for _ in range(args.runs - 1):
            mc_t.append(run(ifd, *common, "--method", "mc", "--spp", spp, "-o", tmp / "mc.npy")["render_seconds"])
        mc_time = statistics.median(mc_t)
        print(f"at equal error: Monte Carlo {spp} spp {mc_time:.3f} s vs ISD {isd_time:.4f} s: "
              f"ISD {mc_time / isd_time:.0f}x faster")


if __name__ == "__main__":
    main()
