"""ISD Table I (memory and speed) and the L = sqrt(s) rule for Phong against SHRM's order rule
(issue 14 item 6; ISD Sec. 7.2 Table I and Sec. 7.3; SHRM Sec. 6.3, 7.4 and App. D).

Run from the repository root:  .venv/bin/python tests/bench/isd_table1.py [--out DIR]
(`--ifd PATH` to choose the binary; default target/release/ifd, else target/debug/ifd;
`--quick` for a small, fast run; `--part table|rule|all`).

Part 1, Table I. For each degree L (default 8, 12, 16, 31: the paper's header "s = L^2 = 8^2,
12^2, 16^2, 31^2"; see docs/isd-rules.md for the other reading, L = 7, 11, 15, 30):
  - memory of the tabulated ISD weights as this code stores them: `ifd sphere brdf` at its
    default table resolution for an isotropic BRDF (ggx:alpha=0.3: 1D over theta_o, in-plane
    lobes, (L+1)(L+2)/2 weights per entry) and an anisotropic one (ggx:ax=0.2,ay=0.5: 2D over
    (theta_o, phi_o), 2L+1 shared lobes, (L+1)^2 weights per entry), f32; the weight bytes the
    command reports and the table file's size (JSON header included); beside them the
    paper's count, 2(L+1)^2 f32 coefficients (lambda_l^m and e_l^m) per view entry, at our
    entry counts, and the paper's MB;
  - speed of the CPU renderer (`ifd render --method isd`, Eq. 22 with the per-band
    environment from SH) on a procedural chair (seat, back, four legs: boxes written as an
    OBJ, z up, per-face normals and texture coordinates) lit by testdata/forest.hdr, with
    both tables: `render_seconds` of the JSON (the shading alone: no map loading, SH
    projection or table build), median of --runs, at --size (default 256x192; the paper
    rendered 1024x768); pixels per second over the whole frame (the paper's FOPS = 1024 x 768
    x Hz) and over the object's pixels (the pixels actually shaded).
Part 2, the L = sqrt(s) rule. For normalised Phong lobes (`phong:s=S`, closed-form weights)
on a unit sphere (--err-size, no background), ISD at L = round(sqrt(s)) (ISD Sec. 7.3), at
SHRM's order F_B = ceil(sqrt(-s ln eps)) (App. D; eps = 0.01 as SHRM Sec. 7.4), at SHRM
Sec. 7.4's conservative F_B = floor(1 + sqrt(6 s)), all capped at the code's L <= 100, and at
a ladder of degrees for the curve; each against `--method quadrature` (the exact per-texel
oracle of the same map at the same --env-size); relative RMS error over the object's pixels
(the quadrature render's --mask), all channels. Beside it, the band limit's relative L2 error
over all reflection directions, from the averaged map's SH band powers (`ifd sphere sh`, no
rendering): the pixel error weighs directions as the sphere's image samples them and, at
s = 900 on a 64x64 image, the sun's highlight covers only about ten pixels. Maps: a
synthetic sky gradient without a sun (smooth), testdata/forest.hdr (no sun, but its
brightest 128x64 texel, sunlight through the trees, holds 3.5% of the radiant power and 40%
of the squared norm), the shared sunrise.hdr (../shared/testdata/envmaps; 54% of the power
in one 128x64 texel) when present, and the synthetic sky plus a small, very bright disk
holding 60% of the power (`sun_sky_map`, written by this script). Beside each error, the
point-light prediction sqrt(eps(L)): eps(L) is the exact fraction of the Phong lobe's energy
above degree L (Legendre moments), which is the relative L2 error of the band-limited image
over reflection directions when the light is a single point (docs/isd-rules.md).

With --out DIR: results.json, results.md (the tables) and, when matplotlib imports,
error_vs_L.png.
"""

import argparse
import json
import math
import os
import pathlib
import platform
import statistics
import subprocess
import tempfile

import numpy as np
from ifd_paths import ROOT, ifd_binary

FOREST = ROOT / "testdata" / "forest.hdr"
SUNRISE = ROOT.parent / "shared" / "testdata" / "envmaps" / "sunrise.hdr"
ISO_BRDF = "ggx:alpha=0.3"
ANISO_BRDF = "ggx:ax=0.2,ay=0.5"
CHAIR_VIEW = ["--eye", "2.1,-1.75,0.95", "--target", "0,0,-0.05", "--fov", "40"]  # the chair fills ~20%
MAX_L = 100  # `ifd render` and `ifd sphere brdf`: L <= 100

# ISD Table I as printed (GTX 780 Ti, GLSL, 1024x768, the chair of Fig. 5, MERL BRDFs).
PAPER = {
    "header": ["8^2", "12^2", "16^2", "31^2"],
    "hz": [59, 46, 29, 11],
    "fops": [46.4e6, 36.2e6, 22.8e6, 8.0e6],
    "mem_iso_mb": [0.1, 0.2, 0.4, 1.5],
    "mem_aniso_mb": [12, 24, 48, 192],
    "machine": "NVIDIA GTX 780 Ti (3 GB), Xeon 1.2 GHz; GLSL shader; 1024x768; MERL BRDFs",
}


# ---------------------------------------------------------------- helpers shared with the test


def run_ifd(ifd, *args):
    """Runs `ifd ARGS --json`; returns its JSON report."""
    p = subprocess.run([str(ifd), *map(str, args), "--json"], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"ifd {' '.join(map(str, args))} failed ({p.returncode}):\n{p.stderr}")
    return json.loads(p.stdout)


def rel_rms(a, ref, mask):
    """Relative RMS error of `a` against `ref` over the pixels where `mask` (H x W), all channels."""
    d = (a - ref)[mask]
    return float(np.sqrt((d**2).sum() / (ref[mask] ** 2).sum()))


def rule_sqrt(s):
    """ISD Sec. 7.3: L_max = sqrt(s) (rounded)."""
    return int(round(math.sqrt(s)))


def rule_shrm(s, eps):
    """SHRM App. D: the order keeping 1 - eps of the Phong lobe's energy, F_B = sqrt(-s ln eps)
    (rounded up)."""
    return math.ceil(math.sqrt(-s * math.log(eps)))


def rule_shrm_conservative(s):
    """SHRM Sec. 7.4 (eps = 0.01, 'conservatively'): F_B = 1 + sqrt(6 s) (rounded down)."""
    return int(math.floor(1 + math.sqrt(6 * s)))


def phong_tail_energy(s, L):
    """Exact fraction of the energy (squared L2 norm) of the zonal lobe max(t, 0)^s above
    degree L: band l holds pi (2l+1) C^2 I_l^2 with I_l = int_0^1 t^s P_l(t) dt
    (I_0 = 1/(s+1), I_1 = 1/(s+2), I_{l+2} = (s-l)/(s+l+3) I_l, docs/shading.md), and all bands
    together 2 pi C^2 int_0^1 t^(2s) dt = 2 pi C^2 / (2s+1) (Parseval)."""
    captured = np.sum((2 * np.arange(L + 1) + 1) * phong_moments(s, L) ** 2)
    return max(0.0, float(1.0 - captured * (2 * s + 1) / 2))


def write_chair_obj(path):
    """A chair of boxes (seat, back, four legs), z up, in metres-ish units; per-face normals
    (flat boxes, no smoothing across edges) and per-face texture coordinates (tangents for
    anisotropic BRDFs)."""
    boxes = [((-0.45, -0.45, 0.45), (0.45, 0.45, 0.55))]  # seat
    boxes.append(((-0.45, 0.37, 0.55), (0.45, 0.45, 1.45)))  # back
    for x in (-0.45, 0.37):
        for y in (-0.45, 0.37):
            boxes.append(((x, y, 0.0), (x + 0.08, y + 0.08, 0.45)))  # legs
    v, vt, vn, f = [], [(0, 0), (1, 0), (1, 1), (0, 1)], [], []
    for lo, hi in boxes:
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        faces = [
            ((1, 0, 0), [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)]),
            ((-1, 0, 0), [(x0, y1, z0), (x0, y0, z0), (x0, y0, z1), (x0, y1, z1)]),
            ((0, 1, 0), [(x1, y1, z0), (x0, y1, z0), (x0, y1, z1), (x1, y1, z1)]),
            ((0, -1, 0), [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)]),
            ((0, 0, 1), [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]),
            ((0, 0, -1), [(x0, y1, z0), (x1, y1, z0), (x1, y0, z0), (x0, y0, z0)]),
        ]
        for n, quad in faces:
            vn.append(n)
            base = len(v)
            v.extend(quad)
            k = len(vn)
            f.append(" ".join(f"{base + i + 1}/{i + 1}/{k}" for i in range(4)))
    with open(path, "w") as fh:
        fh.write("# procedural chair (tests/bench/isd_table1.py), z up\n")
        fh.writelines(f"v {a:g} {b:g} {c:g}\n" for a, b, c in v)
        fh.writelines(f"vt {a:g} {b:g}\n" for a, b in vt)
        fh.writelines(f"vn {a:g} {b:g} {c:g}\n" for a, b, c in vn)
        fh.writelines(f"f {x}\n" for x in f)
    return pathlib.Path(path)


def sun_sky_map(path, width=128, height=64, sun_polar_deg=45.0, sun_azimuth_deg=10.0,
                sun_radius_deg=2.0, sun_share=0.6, supersample=8):
    """A sun-lit equirectangular map (ifd's convention: row 0 = +z, column u at azimuth
    phi = 2 pi u / W from +x towards +y): a blue sky brightening towards the zenith, a dim
    brown ground, and a disk of `sun_radius_deg` holding `sun_share` of the radiant power
    (texel coverage by `supersample`^2 points). Writes (H, W, 3) float32 .npy; returns the path."""
    n = supersample
    t = (np.arange(height * n) + 0.5) / (height * n) * np.pi
    p = (np.arange(width * n) + 0.5) / (width * n) * 2 * np.pi
    tt, pp = np.meshgrid(t, p, indexing="ij")
    d = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    ts, ps = np.radians(sun_polar_deg), np.radians(sun_azimuth_deg)
    sun_dir = np.array([np.sin(ts) * np.cos(ps), np.sin(ts) * np.sin(ps), np.cos(ts)])
    disk = (d @ sun_dir > np.cos(np.radians(sun_radius_deg))).astype(np.float64)
    disk = disk.reshape(height, n, width, n).mean((1, 3))
    th = (np.arange(height) + 0.5) / height * np.pi
    up = np.cos(th)[:, None, None]
    sky = np.where(up > 0, np.array([0.35, 0.55, 1.0]) * (0.4 + 0.6 * up), np.array([0.25, 0.2, 0.15]))
    sky = np.broadcast_to(sky, (height, width, 3)).copy()
    # solid angle per texel ~ sin(theta): scale the sun so that it holds sun_share of the power
    w = np.sin(th)[:, None]
    sky_power = (sky.mean(-1) * w).sum()
    disk_power = (disk * w).sum()
    radiance = sun_share / (1 - sun_share) * sky_power / disk_power
    img = sky + radiance * disk[..., None] * np.array([1.0, 0.95, 0.85])
    np.save(path, img.astype(np.float32))
    return pathlib.Path(path)


def averaged_map(ifd, env, width, height, tmp):
    """The map (H x W x C, float64, negatives set to 0) averaged to width x height by solid
    angle, as `ifd render --env-size` does (`downsample_equirect`: texel rows weighted by
    sin(theta))."""
    env = pathlib.Path(env)
    if env.suffix != ".npy":
        subprocess.run([str(ifd), "convert", str(env), str(tmp / "map.npy")], check=True, capture_output=True)
        env = tmp / "map.npy"
    y = np.maximum(np.load(env).astype(np.float64), 0)
    if y.ndim == 2:
        y = y[..., None]
    h, w = y.shape[:2]
    if h % height or w % width:
        raise SystemExit(f"{env}: {w}x{h} is not a multiple of {width}x{height}")
    fy, fx = h // height, w // width
    sin = np.sin((np.arange(h) + 0.5) / h * np.pi)[:, None, None] * np.ones((1, w, 1))
    sw = sin.reshape(height, fy, width, fx, 1).sum((1, 3))
    return (y * sin).reshape(height, fy, width, fx, -1).sum((1, 3)) / sw


def map_stats(e):
    """How concentrated an averaged map is: the brightest texel's share of the radiant power
    (int E dw) and of the squared norm (int E^2 dw, what an L2 error weighs), on the
    luminance = channel mean."""
    y = e.mean(-1)
    height, width = y.shape
    a = np.sin((np.arange(height) + 0.5) / height * np.pi)[:, None] * np.ones((1, width))
    i = np.unravel_index(np.argmax(y), y.shape)
    return {"power_share_brightest_texel": float((y * a).max() / (y * a).sum()),
            "l2_share_brightest_texel": float((y * y * a).max() / (y * y * a).sum()),
            "brightest_texel": [int(i[1]), int(i[0])],
            "brightest_over_mean": float(y.max() / ((y * a).sum() / a.sum()))}


def band_powers(ifd, e, tmp, lmax=MAX_L, replicate=1):
    """P_l = sum_m sum_channels e_lm^2 of the piecewise-constant averaged map `e`, l <= lmax:
    `ifd sphere sh`, whose default projection integrates every texel exactly, as the renderer
    does (`replicate` > 1 repeats each texel replicate x replicate times first; with the exact
    projection that changes nothing but the time)."""
    up = np.repeat(np.repeat(e, replicate, 0), replicate, 1).astype(np.float32)
    np.save(tmp / "up.npy", up)
    subprocess.run([str(ifd), "sphere", "sh", str(tmp / "up.npy"), "--lmax", str(lmax), "-o",
                    str(tmp / "sh.npy")], check=True, capture_output=True)
    c = np.load(tmp / "sh.npy")
    return np.array([(c[l * l:(l + 1) ** 2] ** 2).sum() for l in range(lmax + 1)])


def phong_moments(s, lmax):
    """I_l(s) = int_0^1 t^s P_l(t) dt, l = 0..lmax (docs/shading.md, "Closed forms")."""
    I = [1.0 / (s + 1), 1.0 / (s + 2)]
    for l in range(lmax - 1):
        I.append((s - l) / (s + l + 3) * I[l])
    return np.array(I[: lmax + 1])


def direction_error(powers, s, L):
    """Relative L2 error over all reflection directions of the Phong image band-limited at L:
    the image's band l holds Lambda_l^2 g_l^2 P_l, proportional to I_l(s)^2 P_l (the constants
    cancel in the ratio); bands above len(powers) - 1 are left out of both sums."""
    w = phong_moments(s, len(powers) - 1) ** 2 * powers
    return float(np.sqrt(w[L + 1:].sum() / w.sum()))


def maps_markdown(stats, env_size):
    out = [f"Maps, averaged to {env_size}: the brightest texel's share of the radiant power "
           f"(int E) and of the squared norm (int E^2, what a relative RMS error weighs).", "",
           "| map | brightest texel / mean | share of power | share of squared norm |", "|---|---|---|---|"]
    for name, m in stats.items():
        out.append(f"| {name} | {m['brightest_over_mean']:.3g} | {100 * m['power_share_brightest_texel']:.3g}% "
                   f"| {100 * m['l2_share_brightest_texel']:.3g}% |")
    return "\n".join(out)


def error_curve(ifd, env, s, degrees, tmp, size, env_size):
    """Quadrature once, then ISD at each degree: {L: relative RMS}, plus the oracle's JSON."""
    common = ["render", "--env", env, "--brdf", f"phong:s={s:g}", "--size", size,
              "--env-size", env_size, "--no-background"]
    q_json = run_ifd(ifd, *common, "--method", "quadrature", "--mask", tmp / "mask.npy",
                     "-o", tmp / "q.npy")
    q = np.load(tmp / "q.npy").astype(np.float64)
    mask = np.load(tmp / "mask.npy") > 0.5
    errs = {}
    for L in degrees:
        run_ifd(ifd, *common, "--method", "isd", "--lmax", L, "-o", tmp / "i.npy")
        errs[L] = rel_rms(np.load(tmp / "i.npy").astype(np.float64), q, mask)
    return errs, q_json


# ---------------------------------------------------------------- part 1: Table I


def table_one(ifd, tmp, degrees, size, runs, aniso_entries):
    env = FOREST
    load_before = list(os.getloadavg())  # other work on the cores shows here
    chair = write_chair_obj(tmp / "chair.obj")
    w, h = (int(x) for x in size.split("x"))
    rows = []
    for L in degrees:
        row = {"L": L}
        for kind, brdf, extra in [("iso", ISO_BRDF, []), ("aniso", ANISO_BRDF, aniso_entries)]:
            t = tmp / f"{kind}{L}.lobes"
            info = run_ifd(ifd, "sphere", "brdf", brdf, "--lmax", L, *extra, "-o", t)
            entries = info["theta_entries"] * info["phi_entries"]
            times, out = [], None
            for _ in range(runs):
                out = run_ifd(ifd, "render", "--env", env, "--scene", chair, "--obj-up", "z",
                              "--brdf", brdf, "--table", t, "--lmax", L, "--method", "isd",
                              "--size", size, *CHAIR_VIEW, "-o", tmp / "chair.exr")
                times.append(out["render_seconds"])
            sec = statistics.median(times)
            row[kind] = {
                "brdf": brdf, "theta_entries": info["theta_entries"],
                "phi_entries": info["phi_entries"], "lobes": info["lobes"],
                "lobe_layout": info["lobe_layout"], "weight_bytes": info["weight_bytes"],
                "file_bytes": t.stat().st_size, "build_seconds": info["seconds"],
                "interpolation_error": info["interpolation_error"],
                # the paper's count: 2 (L+1)^2 f32 coefficients per view entry
                "paper_layout_bytes": 2 * (L + 1) ** 2 * 4 * entries,
                "render_seconds": times, "render_seconds_median": sec,
                "object_pixels": out["object_pixels"],
                "frame_pixels_per_second": w * h / sec,
                "object_pixels_per_second": out["object_pixels"] / sec,
                "hz_at_size": 1.0 / sec,
            }
        rows.append(row)
        print(f"L = {L}: iso {row['iso']['weight_bytes']} B, {row['iso']['frame_pixels_per_second'] / 1e6:.2f} "
              f"Mpx/s; aniso {row['aniso']['weight_bytes']} B, "
              f"{row['aniso']['frame_pixels_per_second'] / 1e6:.2f} Mpx/s", flush=True)
    return {"size": size, "runs": runs, "env": str(env.relative_to(ROOT)), "rows": rows,
            "aniso_table_options": aniso_entries, "load_average_before": load_before,
            "load_average_after": list(os.getloadavg())}


def table_one_markdown(t):
    out = [f"ISD Table I on this machine: chair of boxes, {t['size']} (the paper: 1024x768), "
           f"CPU `ifd render --method isd`, median of {t['runs']} runs of render_seconds; "
           f"memory = the f32 lobe weights `ifd sphere brdf` stores (file size in brackets, "
           f"JSON header included). Load average (1, 5, 15 min) before: "
           f"{', '.join(f'{x:.2f}' for x in t['load_average_before'])}; after: "
           f"{', '.join(f'{x:.2f}' for x in t['load_average_after'])}.", ""]
    out.append("| L | iso table (ggx:alpha=0.3) | iso entries | iso, paper layout 2(L+1)^2 at our entries "
               "| aniso table (ggx:ax=0.2,ay=0.5) | aniso entries | aniso, paper layout | "
               "interpolation error iso / aniso | "
               "iso Mpx/s (frame) | iso Mpx/s (object) | aniso Mpx/s (frame) | aniso Mpx/s (object) | "
               "iso / aniso Hz at our size |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in t["rows"]:
        i, a = r["iso"], r["aniso"]
        out.append(
            f"| {r['L']} | {fmt_bytes(i['weight_bytes'])} ({fmt_bytes(i['file_bytes'])}) | {i['theta_entries']} "
            f"| {fmt_bytes(i['paper_layout_bytes'])} | {fmt_bytes(a['weight_bytes'])} ({fmt_bytes(a['file_bytes'])}) "
            f"| {a['theta_entries']} x {a['phi_entries']} | {fmt_bytes(a['paper_layout_bytes'])} "
            f"| {100 * i['interpolation_error']:.2g}% / {100 * a['interpolation_error']:.2g}% "
            f"| {i['frame_pixels_per_second'] / 1e6:.2f} | {i['object_pixels_per_second'] / 1e6:.2f} "
            f"| {a['frame_pixels_per_second'] / 1e6:.2f} | {a['object_pixels_per_second'] / 1e6:.2f} "
            f"| {i['hz_at_size']:.1f} / {a['hz_at_size']:.1f} |")
    out += ["", f"The paper's Table I (not measured here: {PAPER['machine']}):", "",
            "| s = L^2 | speed [Hz] | speed [FOPS = 1024 x 768 x Hz] | mem. isotropic [MB] | mem. anisotropic [MB] |",
            "|---|---|---|---|---|"]
    for k, hdr in enumerate(PAPER["header"]):
        out.append(f"| {hdr} | {PAPER['hz'][k]} | {PAPER['fops'][k] / 1e6:.1f}M | {PAPER['mem_iso_mb'][k]} "
                   f"| {PAPER['mem_aniso_mb'][k]} |")
    return "\n".join(out)


def fmt_bytes(b):
    if b >= 1e6:
        return f"{b / 1e6:.2f} MB"
    if b >= 1e3:
        return f"{b / 1e3:.1f} KB"
    return f"{b} B"


# ---------------------------------------------------------------- part 2: the L = sqrt(s) rule


def ladder(cap):
    base = [2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 24, 28, 32, 36, 40, 48, 56, 64, 72, 80, 90, 100]
    return [L for L in base if L <= cap]


def rules_study(ifd, tmp, exponents, eps, size, env_size, maps, powers, curve):
    res = []
    for name, env in maps:
        for s in exponents:
            rules = {
                "sqrt(s)": min(rule_sqrt(s), MAX_L),
                f"SHRM App. D, eps = {eps:g}": min(rule_shrm(s, eps), MAX_L),
                "SHRM Sec. 7.4, 1 + sqrt(6s)": min(rule_shrm_conservative(s), MAX_L),
            }
            degrees = sorted(set(rules.values()) | (set(ladder(MAX_L)) if curve else set()))
            errs, q = error_curve(ifd, env, s, degrees, tmp, size, env_size)
            row = {"map": name, "s": s, "object_pixels": q["object_pixels"],
                   "quadrature_seconds": q["render_seconds"],
                   "quadrature_unconverged_pixels": q["quadrature_unconverged_pixels"],
                   "rules": {k: {"L": L, "rel_rms": errs[L],
                                 "rel_rms_directions": direction_error(powers[name], s, L),
                                 "point_light_prediction": math.sqrt(phong_tail_energy(s, L)),
                                 "lobe_energy_missed": phong_tail_energy(s, L)}
                             for k, L in rules.items()},
                   "curve": {str(L): e for L, e in errs.items()},
                   # up to L = 90: the bands above MAX_L are left out of the sums
                   "curve_directions": {str(L): direction_error(powers[name], s, L) for L in range(1, 91)}}
            res.append(row)
            print(f"{name} s = {s:g}: " + ", ".join(f"{k}: L = {v['L']} -> {v['rel_rms']:.4f}"
                                                   for k, v in row["rules"].items())
                  + f" (quadrature {q['render_seconds']:.1f} s)", flush=True)
    return {"size": size, "env_size": env_size, "eps": eps, "max_L": MAX_L, "rows": res}


def rules_markdown(r):
    keys = list(r["rows"][0]["rules"])
    out = [f"Relative RMS error of ISD (Phong, closed form) against the exact quadrature over the "
           f"object's pixels (unit sphere {r['size']}, maps averaged to {r['env_size']}); the band "
           f"limit's relative L2 error over all reflection directions (from the map's SH band "
           f"powers, no rendering); the point-light prediction sqrt(eps(L)) (eps(L): the Phong "
           f"lobe's exact energy fraction above L); L capped at {r['max_L']}.", "",
           "| map | s | rule | L | error over pixels | over directions | point-light prediction | "
           "pixel error, sqrt(s) / this rule |",
           "|---|---|---|---|---|---|---|---|"]
    for row in r["rows"]:
        base = row["rules"][keys[0]]["rel_rms"]
        for k in keys:
            v = row["rules"][k]
            ratio = "" if k == keys[0] else f"{base / v['rel_rms']:.3g}x"
            out.append(f"| {row['map']} | {row['s']:g} | {k} | {v['L']} | {pct(v['rel_rms'])} "
                       f"| {pct(v['rel_rms_directions'])} | {pct(v['point_light_prediction'])} | {ratio} |")
    return "\n".join(out)


def pct(x):
    return f"{100 * x:.3g}%"


def plot(r, path):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not importable: no plot")
        return None
    maps = sorted({row["map"] for row in r["rows"]}, key=[row["map"] for row in r["rows"]].index)
    cols = min(2, len(maps))
    rows = -(-len(maps) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(6.5 * cols, 4.6 * rows), squeeze=False)
    for ax in axes.flat[len(maps):]:
        ax.set_visible(False)
    for ax, name in zip(axes.flat, maps):
        for k, row in enumerate(x for x in r["rows"] if x["map"] == name):
            Ls = sorted(int(L) for L in row["curve"])
            c = f"C{k}"
            ax.semilogy(Ls, [max(row["curve"][str(L)], 1e-9) for L in Ls], "-", color=c, label=f"s = {row['s']:g}")
            Ld = sorted(int(L) for L in row["curve_directions"])
            ax.semilogy(Ld, [row["curve_directions"][str(L)] or np.nan for L in Ld], ":", color=c,
                        label="over directions (SH)" if k == 0 else None)
            for (label, v), m in zip(row["rules"].items(), ["o", "s", "^"]):
                ax.semilogy([v["L"]], [max(v["rel_rms"], 1e-9)], m, color=c, mfc="none" if m != "o" else c,
                            label=label if k == 0 else None)
        ax.set_title(name)
        ax.set_xlabel("L")
        ax.set_ylabel("relative RMS error of ISD")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ---------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ifd")
    ap.add_argument("--quick", action="store_true", help="small sizes and few degrees (tests, smoke runs)")
    ap.add_argument("--part", choices=["table", "rule", "all"], default="all")
    ap.add_argument("--out", type=pathlib.Path, help="write results.json, results.md and error_vs_L.png here")
    ap.add_argument("--runs", type=int, help="timed runs per speed measurement (median; default 3, quick 1)")
    ap.add_argument("--size", help="chair image size WxH (default 256x192, quick 64x48)")
    ap.add_argument("--degrees", help="Table I degrees L (default 8,12,16,31; quick 4,6)")
    ap.add_argument("--exponents", help="Phong exponents s (default 16,64,256,900; quick 16,64)")
    ap.add_argument("--eps", type=float, default=0.01, help="SHRM's energy tolerance (default 0.01, SHRM Sec. 7.4)")
    ap.add_argument("--err-size", help="sphere image size for the errors (default 64x64, quick 32x32)")
    ap.add_argument("--env-size", help="map size every method integrates (default 128x64, quick 64x32)")
    ap.add_argument("--no-curve", action="store_true", help="only the rules' degrees, not the ladder for the plot")
    args = ap.parse_args()
    q = args.quick
    runs = args.runs or (1 if q else 3)
    size = args.size or ("64x48" if q else "256x192")
    degrees = [int(x) for x in (args.degrees or ("4,6" if q else "8,12,16,31")).split(",")]
    exponents = [float(x) for x in (args.exponents or ("16,64" if q else "16,64,256,900")).split(",")]
    err_size = args.err_size or ("32x32" if q else "64x64")
    env_size = args.env_size or ("64x32" if q else "128x64")
    ifd = ifd_binary(args.ifd)
    print(f"binary: {ifd}")
    results = {"binary": str(ifd), "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                               "gpu": "none used (CPU renderer)"},
               "paper_table1": PAPER, "quick": q}
    md = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        if args.part in ("table", "all"):
            aniso = ["--theta-entries", "8", "--phi-entries", "16"] if q else []
            results["table1"] = table_one(ifd, tmp, degrees, size, runs, aniso)
            md.append(table_one_markdown(results["table1"]))
        if args.part in ("rule", "all"):
            ew, eh = (int(x) for x in env_size.split("x"))
            maps = [("synthetic sky, no sun", sun_sky_map(tmp / "sky.npy", ew, eh, sun_share=0.0)),
                    ("forest (bundled)", FOREST)]
            if SUNRISE.exists() and not q:
                maps.append(("sunrise (real sun)", SUNRISE))
            maps.append(("synthetic sun", sun_sky_map(tmp / "sun.npy", ew, eh)))
            averaged = {name: averaged_map(ifd, env, ew, eh, tmp) for name, env in maps}
            results["maps"] = {name: map_stats(e) for name, e in averaged.items()}
            md.append(maps_markdown(results["maps"], env_size))
            powers = {name: band_powers(ifd, e, tmp) for name, e in averaged.items()}
            results["rules"] = rules_study(ifd, tmp, exponents, args.eps, err_size, env_size, maps,
                                           powers, curve=not args.no_curve)
            md.append(rules_markdown(results["rules"]))
    text = "\n\n".join(md)
    print("\n" + text)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "results.json").write_text(json.dumps(results, indent=1) + "\n")
        (args.out / "results.md").write_text(text + "\n")
        if "rules" in results:
            p = plot(results["rules"], args.out / "error_vs_L.png")
            if p:
                print(f"plot: {p}")
        print(f"wrote {args.out}/results.json, results.md")


if __name__ == "__main__":
    main()
