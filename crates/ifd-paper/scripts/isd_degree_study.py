"""The SH degree L each glTF roughness needs: ISD's error against the exact integral over L.

Run from the repository root after building:
    .venv/bin/python crates/ifd-paper/scripts/isd_degree_study.py [--ifd PATH] [--out docs/split-sum]

For each perceptual roughness (0.2 to 1) of a glTF metal (metallic 1, base colour 0.9: the
specular lobe alone, the hardest case; a dielectric's diffuse part needs less), the unit sphere
under the bundled forest map (read at 128x64) is rendered at 64x64 by the exact oracle
(`--method quadrature`) and by ISD (`--method isd`, tables of the BRDF's three parts) at
L = 8 to 48. Writes `isd_degree.csv` (relative RMS error over the sphere per roughness and L,
and over the pixels seen at `n . v >= 0.2`, away from the silhouette), `isd_degree.png` (error
against L, one line per roughness) and prints a markdown table with the smallest L within 1%
and within 0.3% for each roughness. Uses the view and image size of split_sum_study.py (96x96).
"""

import argparse
import csv
import math
import pathlib
import tempfile

import numpy as np
from ifd_paths import ifd_binary
from split_sum_study import ENVS, ROOT, render, view_cosines

ROUGHNESS = (0.2, 0.25, 0.3, 0.4, 0.5, 0.75, 1.0)
DEGREES = (8, 12, 16, 24, 32, 40, 48)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ifd", type=pathlib.Path, default=None)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "split-sum")
    a = ap.parse_args()
    ifd = ifd_binary(a.ifd)
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    nv = view_cosines()
    inner = np.isfinite(nv) & (np.nan_to_num(nv) >= 0.2)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for rough in ROUGHNESS:
            spec = f"gltf:roughness={rough},metallic=1,base=0.9"
            ref = render(ifd, ENVS["forest"], spec, "quadrature", tmp / "ref.npy")
            on = ref.sum(axis=-1) > 0
            for lmax in DEGREES:
                img = render(ifd, ENVS["forest"], spec, "isd", tmp / "isd.npy", lmax)
                err = math.sqrt(((img - ref)[on] ** 2).sum() / (ref[on] ** 2).sum())
                sel = on & inner
                err_inner = math.sqrt(((img - ref)[sel] ** 2).sum() / (ref[sel] ** 2).sum())
                rows.append({"roughness": rough, "alpha": rough * rough, "lmax": lmax,
                             "rel_rms": err, "rel_rms_nv_0.2": err_inner})
                print(f"roughness {rough} L = {lmax}: {err:.4f} ({err_inner:.4f} at n.v >= 0.2)",
                      flush=True)
    with open(a.out / "isd_degree.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    plot(rows, a.out / "isd_degree.png")
    print("\n| roughness | alpha | " + " | ".join(f"L = {l}" for l in DEGREES)
          + " | L for 1% | L for 0.3% |")
    print("|---|---|" + "---|" * (len(DEGREES) + 2))
    for rough in ROUGHNESS:
        errs = [next(r["rel_rms"] for r in rows if r["roughness"] == rough and r["lmax"] == l)
                for l in DEGREES]

        def first(limit):
            return next((str(l) for l, e in zip(DEGREES, errs) if e <= limit), f"> {DEGREES[-1]}")

        print(f"| {rough:g} | {rough * rough:.4g} | "
              + " | ".join(f"{100 * e:.2f}%" for e in errs)
              + f" | {first(0.01)} | {first(0.003)} |")


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, rough in enumerate(ROUGHNESS):
        pts = [(r["lmax"], 100 * r["rel_rms"]) for r in rows if r["roughness"] == rough]
        ax.plot(*zip(*pts), "o-", color=plt.cm.viridis(k / (len(ROUGHNESS) - 1)),
                label=f"roughness {rough:g} (alpha {rough * rough:.3g})")
    ax.axhline(1.0, color="grey", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set_xlabel("L (maximum SH degree)")
    ax.set_ylabel("relative RMS error vs exact [%]")
    ax.set_title("ISD of a glTF metal (forest map): the L each roughness needs")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
