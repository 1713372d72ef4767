"""The split sum's error on the bundled glTF sphere grid, per metalness, roughness and view angle.

Run from the repository root after building:
    .venv/bin/python crates/ifd-paper/scripts/split_sum_assets_study.py [--ifd PATH] [--out docs/split-sum]

`testdata/spheres.glb` (25 spheres: metallic 0, 0.25, 0.5, 0.75, 1 upwards, roughness 0.1, 0.3,
0.5, 0.75, 1 to the right, base colour from the asset) is rendered through its own camera at
160x160 under the bundled forest map and `testdata/sunrise.hdr` (both read at 128x64) by the
exact oracle (`--method quadrature`) and by the two split-sum methods, with `--gbuffer` giving
every pixel's `n . v`, roughness and metalness. The error relative to the oracle is reported per
sphere (metalness, roughness) and per view-angle bin (the bins of split_sum_study.py) as the
relative RMS error of the pixels in it. Writes `split_sum_assets.csv`, `split_sum_assets.png`
(error against `n . v`, one panel per map and metalness 0, 0.5, 1) and prints a markdown table
of the whole-sphere errors.

With `--isd-lmax L`, ISD is measured too (`--method isd --lmax L --roughness-tables 19`: tables
every 0.05 of roughness from 0.1 to 1, so every sphere's roughness has its own table);
`--size N` and `--envs forest` change the image size and the maps.
"""

import argparse
import csv
import math
import pathlib
import subprocess
import tempfile

import numpy as np
from ifd_paths import ifd_binary
from split_sum_study import BINS, ENVS, ROOT

ASSET = ROOT / "testdata" / "spheres.glb"
SIZE = 160
METHODS = ["split-sum", "split-sum-sample-renderer"]
METALLIC = (0.0, 0.25, 0.5, 0.75, 1.0)
ROUGHNESS = (0.1, 0.3, 0.5, 0.75, 1.0)


def render(ifd, env, method, out, gbuffer=None, lmax=None):
    args = [str(ifd), "render", "--env", str(env), "--env-size", "128x64", "--scene", str(ASSET),
            "--scene-camera", "--method", method, "--size", f"{SIZE}x{SIZE}", "--no-background",
            "-o", str(out)]
    if lmax is not None:
        args += ["--lmax", str(lmax), "--roughness-tables", "19"]
    if gbuffer is not None:
        args += ["--gbuffer", str(gbuffer)]
    subprocess.run(args, check=True, capture_output=True)
    return np.load(out).astype(np.float64)


def rel_rms(err, ref, sel):
    den = (ref[sel] ** 2).sum()
    return math.sqrt((err[sel] ** 2).sum() / den) if sel.any() and den > 0 else float("nan")


def main():
    global SIZE, METHODS
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ifd", type=pathlib.Path, default=None)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "split-sum")
    ap.add_argument("--isd-lmax", type=int, default=None)
    ap.add_argument("--size", type=int, default=SIZE)
    ap.add_argument("--envs", nargs="+", default=list(ENVS))
    a = ap.parse_args()
    SIZE = a.size
    envs = {k: ENVS[k] for k in a.envs}
    if a.isd_lmax is not None:
        METHODS = [*METHODS, "isd"]
    ifd = ifd_binary(a.ifd)
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for env_name, env in envs.items():
            ref = render(ifd, env, "quadrature", tmp / "ref.npy", tmp / "g.npy")
            g = np.load(tmp / "g.npy").astype(np.float64)
            on = g[..., 3] > 0
            nv, rough, metal = g[..., 3], g[..., 4], g[..., 5]
            for method in METHODS:
                lmax = a.isd_lmax if method == "isd" else None
                err = render(ifd, env, method, tmp / f"{method}.npy", lmax=lmax) - ref
                for m in METALLIC:
                    for r in ROUGHNESS:
                        sphere = on & (np.abs(metal - m) < 1e-3) & (np.abs(rough - r) < 1e-3)
                        row = {"env": env_name, "method": method, "metallic": m, "roughness": r,
                               "pixels": int(sphere.sum()), "all": rel_rms(err, ref, sphere)}
                        for lo, hi in zip(BINS[:-1], BINS[1:]):
                            row[f"nv {lo:.2f}-{min(hi, 1):.2f}"] = rel_rms(
                                err, ref, sphere & (nv >= lo) & (nv < hi))
                        rows.append(row)
                print(f"{env_name} {method} done", flush=True)
    keys = list(rows[0].keys())
    stem = "split_sum_assets" if a.isd_lmax is None else f"split_sum_assets_isd{a.isd_lmax}"
    with open(a.out / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    if a.isd_lmax is None:
        plot(rows, keys, a.out / f"{stem}.png")
    for method in METHODS:
        print(f"\n{method}: relative RMS error against the oracle per sphere")
        print("\n| map | metallic | " + " | ".join(f"roughness {r:g}" for r in ROUGHNESS) + " |")
        print("|---|---|" + "---|" * len(ROUGHNESS))
        for env_name in envs:
            for m in METALLIC:
                vals = [next(x["all"] for x in rows if x["env"] == env_name and
                             x["method"] == method and x["metallic"] == m and
                             x["roughness"] == r) for r in ROUGHNESS]
                print(f"| {env_name} | {m:g} | " + " | ".join(f"{100 * v:.1f}%" for v in vals)
                      + " |")


def plot(rows, keys, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    bins = [k for k in keys if k.startswith("nv ")]
    centres = [0.5 * (lo + min(hi, 1.0)) for lo, hi in zip(BINS[:-1], BINS[1:])]
    shown = (0.0, 0.5, 1.0)
    fig, axes = plt.subplots(len(ENVS), len(shown), figsize=(12, 7), sharex=True, sharey=True)
    styles = {"split-sum": "-", "split-sum-sample-renderer": "--"}
    for i, env_name in enumerate(ENVS):
        for j, m in enumerate(shown):
            ax = axes[i, j]
            for k, r in enumerate(ROUGHNESS):
                colour = plt.cm.viridis(k / (len(ROUGHNESS) - 1))
                for method, ls in styles.items():
                    x = next(x for x in rows if x["env"] == env_name and x["method"] == method
                             and x["metallic"] == m and x["roughness"] == r)
                    ax.plot(centres, [100 * x[b] for b in bins], ls, color=colour,
                            label=f"r={r:g} {method}" if (i, j) == (0, 0) else None)
            ax.set_title(f"spheres.glb, {env_name}, metallic {m:g}")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("n . v (view angle cosine)")
    for ax in axes[:, 0]:
        ax.set_ylabel("relative RMS error vs exact [%]")
    fig.legend(loc="lower center", ncol=5, fontsize=7)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    main()
