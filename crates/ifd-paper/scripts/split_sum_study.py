"""How far engines' split-sum shading is from the exact integral of the glTF BRDF.

Run from the repository root after building:
    .venv/bin/python crates/ifd-paper/scripts/split_sum_study.py [--ifd PATH] [--out docs/split-sum]

For each environment (the bundled forest map and `testdata/sunrise.hdr`, a 256x128
solid-angle average of `../shared/testdata/envmaps/sunrise.hdr`, both read at 128x64 by
every method), each metallic (0, 1) and perceptual roughness (0.25, 0.5, 0.75, 1), the unit
sphere (base colour 0.9 grey) is rendered at 96x96 by four methods of `ifd render`:

- `quadrature`: the exact oracle (every texel integrated against the whole BRDF);
- `split-sum`: the split-sum approximation of the same BRDF (prefiltered chain of 256-texel
  faces and 32-texel irradiance baked in memory, the DFG table);
- `split-sum-sample-renderer`: glTF-Sample-Renderer's shader as written;
- `isd`: ISD at L = 24 (tables of the BRDF's three parts).

Every pixel's view angle `n . v` is computed here from the camera, and the error relative to
the oracle is reported per view-angle bin as the relative RMS error of the bin, plus the whole
image's. Writes `split_sum.csv`, `split_sum.png` (error against `n . v`, one panel per
environment and metallic) and prints a markdown table.
"""

import argparse
import csv
import math
import pathlib
import subprocess
import tempfile

import numpy as np
from ifd_paths import ifd_binary

ROOT = pathlib.Path(__file__).resolve().parents[3]
ENVS = {"forest": ROOT / "testdata" / "forest.hdr", "sunrise": ROOT / "testdata" / "sunrise.hdr"}
METHODS = ["split-sum", "split-sum-sample-renderer", "isd"]
SIZE = 96
EYE, TARGET, FOV = (3.0, -2.5, 1.2), (0.0, 0.0, 0.0), 40.0
BINS = [0.0, 0.1, 0.2, 0.35, 0.5, 0.7, 0.85, 1.0001]


def view_cosines():
    """`n . v` of every pixel (NaN off the sphere), with ifd_render::Camera's model."""
    eye, target = np.array(EYE), np.array(TARGET)
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    th = math.tan(math.radians(FOV) / 2)
    j, i = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    sx = (2 * i / SIZE - 1) * th
    sy = (1 - 2 * j / SIZE) * th
    d = fwd + sx[..., None] * right + sy[..., None] * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = d @ eye
    disc = b * b - (eye @ eye - 1)
    t = -b - np.sqrt(np.where(disc > 0, disc, np.nan))
    p = eye + t[..., None] * d
    return np.einsum("ijk,ijk->ij", p, -d)


def render(ifd, env, spec, method, out, lmax=24):
    """`ifd render` of the unit sphere at SIZE x SIZE (ISD at degree `lmax`); the image."""
    args = [str(ifd), "render", "--env", str(env), "--env-size", "128x64", "--brdf", spec,
            "--method", method, "--size", f"{SIZE}x{SIZE}", "--fov", str(FOV),
            "--eye", ",".join(map(str, EYE)), "--target", ",".join(map(str, TARGET)),
            "--no-background", "-o", str(out)]
    if method == "isd":
        args += ["--lmax", str(lmax)]
    subprocess.run(args, check=True, capture_output=True)
    return np.load(out).astype(np.float64)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ifd", type=pathlib.Path, default=None)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "docs" / "split-sum")
    a = ap.parse_args()
    ifd = ifd_binary(a.ifd)
    a.out.mkdir(parents=True, exist_ok=True)
    nv = view_cosines()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for env_name, env in ENVS.items():
            for metallic in (0.0, 1.0):
                for rough in (0.25, 0.5, 0.75, 1.0):
                    spec = f"gltf:roughness={rough},metallic={metallic},base=0.9"
                    ref = render(ifd, env, spec, "quadrature", tmp / "ref.npy")
                    for method in METHODS:
                        img = render(ifd, env, spec, method, tmp / f"{method}.npy")
                        err = img - ref
                        row = {"env": env_name, "metallic": metallic, "roughness": rough,
                               "method": method}
                        on = np.isfinite(nv)
                        row["all"] = math.sqrt((err[on] ** 2).sum() / (ref[on] ** 2).sum())
                        for lo, hi in zip(BINS[:-1], BINS[1:]):
                            sel = on & (nv >= lo) & (nv < hi)
                            key = f"nv {lo:.2f}-{min(hi, 1):.2f}"
                            row[key] = (math.sqrt((err[sel] ** 2).sum() / (ref[sel] ** 2).sum())
                                        if sel.any() else float("nan"))
                        rows.append(row)
                        print(f"{env_name} m={metallic} r={rough} {method}: {row['all']:.4f}",
                              flush=True)
    keys = list(rows[0].keys())
    with open(a.out / "split_sum.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    plot(rows, keys, a.out / "split_sum.png")
    print("\n| env | metallic | roughness | " + " | ".join(METHODS) + " |")
    print("|---|---|---|" + "---|" * len(METHODS))
    for env_name in ENVS:
        for metallic in (0.0, 1.0):
            for rough in (0.25, 0.5, 0.75, 1.0):
                vals = [next(r["all"] for r in rows if r["env"] == env_name and
                             r["metallic"] == metallic and r["roughness"] == rough and
                             r["method"] == m) for m in METHODS]
                print(f"| {env_name} | {metallic:g} | {rough:g} | "
                      + " | ".join(f"{100 * v:.1f}%" for v in vals) + " |")


def plot(rows, keys, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    bins = [k for k in keys if k.startswith("nv ")]
    centres = [0.5 * (lo + min(hi, 1.0)) for lo, hi in zip(BINS[:-1], BINS[1:])]
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True, sharey=True)
    styles = {"split-sum": "-", "split-sum-sample-renderer": "--", "isd": ":"}
    for ax, (env_name, metallic) in zip(axes.ravel(), [(e, m) for e in ENVS for m in (0.0, 1.0)]):
        for k, rough in enumerate((0.25, 0.5, 0.75, 1.0)):
            colour = plt.cm.viridis(k / 3)
            for method, ls in styles.items():
                r = next(r for r in rows if r["env"] == env_name and r["metallic"] == metallic
                         and r["roughness"] == rough and r["method"] == method)
                ax.plot(centres, [100 * r[b] for b in bins], ls, color=colour,
                        label=f"r={rough:g} {method}" if ax is axes[0, 0] else None)
        ax.set_title(f"{env_name}, metallic {metallic:g}")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("n . v (view angle cosine)")
    for ax in axes[:, 0]:
        ax.set_ylabel("relative RMS error vs exact [%]")
    fig.legend(loc="lower center", ncol=4, fontsize=7)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
