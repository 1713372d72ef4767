"""The SH degree L `ifd render --tol E` needs: ISD's error against the oracle per material, L and map.

Run from the repository root after building (minutes to an hour: the lobe tables of smooth
materials at high L dominate; rows already in the CSV are kept, so an interrupted run resumes):
    .venv/bin/python tests/bench/render_tol_table.py [--ifd PATH] [--csv docs/render-tol.csv]

For each material kind `ifd render --tol` knows (the glTF metallic-roughness BRDF as a red
dielectric, base colour 0.8,0.1,0.1 and metallic 0, and as a metal, base colour 0.9 and
metallic 1; the analytic `ggx:alpha=roughness^2`; `phong:s=..` and `lambert`), each
roughness (or Phong exponent) and each L of a ladder, the unit sphere at 128x128 through the
default camera is rendered by ISD (`--method isd`, f32, tables built once per BRDF and L with
`ifd sphere brdf` and shared by the maps and the glTF materials) and by the exact oracle
(`--method quadrature`), on the bundled forest map and the sunrise map (a small, bright sun:
the harder of the two, most at grazing views), both read at 128x64. Each pixel's `n . v` comes from `--gbuffer`. The relative RMS
error, `sqrt(sum |isd - oracle|^2 / sum |oracle|^2)` over RGB, is taken over the object and
over its grazing pixels (`n . v < 0.2`). Each ladder stops once the error has stopped falling
(its floor: the lobe table's interpolation over the view angle, largest at grazing views).

Writes `docs/render-tol.csv` (material, roughness, L, rel_rms_object, rel_rms_grazing, map,
grazing_pixels, object_pixels). The rule of `crates/ifd-render/src/tolerance/` takes, per
material row and L, the worst of the four errors (object and grazing, both maps);
`--rust FILE` writes its table (`tolerance/table.rs`) from the CSV, and `--markdown` prints
the degree it chooses per row and tolerance (the table of docs/guide/rendering.md).
"""

import argparse
import csv
import math
import pathlib
import subprocess
import tempfile

import numpy as np
from ifd_paths import ROOT, ifd_binary

MAPS = {"forest": ROOT / "testdata" / "forest.hdr", "sunrise": ROOT / "testdata" / "sunrise.hdr"}
SIZE = "128x128"
ENV_SIZE = "128x64"
GRAZING = 0.2
LADDER = (1, 2, 3, 4, 6, 8, 12, 16, 20, 24, 32, 40, 48, 64, 80, 100)
# the smallest L of each roughness' ladder: below it every map errs by tens of percent
GLOSSY_ROUGHNESS = {0.3: 16, 0.4: 12, 0.45: 12, 0.5: 8, 0.6: 6, 0.7: 4, 0.85: 4, 1.0: 4}
PHONG = {4: 2, 16: 2, 64: 4, 256: 8}
FIELDS = ["material", "roughness", "L", "rel_rms_object", "rel_rms_grazing", "map",
          "grazing_pixels", "object_pixels", "size"]


def kinds():
    """(material, parameter, the BRDF spec, the tabulated spec or None, the first L), the
    cheap ones first."""
    yield ("lambert", 1.0, "lambert", None, 1)
    for s, l0 in PHONG.items():
        yield ("phong", s, f"phong:s={s}", None, l0)
    for r, l0 in sorted(GLOSSY_ROUGHNESS.items(), reverse=True):
        yield ("gltf-dielectric", r, f"gltf:roughness={r:g},metallic=0,base=0.8:0.1:0.1",
               f"gltf-lobes:roughness={r:g}", l0)
        yield ("gltf-metal", r, f"gltf:roughness={r:g},metallic=1,base=0.9",
               f"gltf-lobes:roughness={r:g}", l0)
        yield ("ggx", r, f"ggx:alpha={r * r:.6g}", f"ggx:alpha={r * r:.6g}", l0)


def run(args):
    subprocess.run([str(a) for a in args], check=True, capture_output=True)


def render(ifd, env, spec, method, out, lmax=None, table=None, gbuffer=None, size=SIZE):
    args = [ifd, "render", "--env", env, "--env-size", ENV_SIZE, "--brdf", spec, "--method",
            method, "--size", size, "--no-background", "-o", out]
    if lmax is not None:
        args += ["--lmax", lmax]
    if table is not None:
        args += ["--table", table]
    if gbuffer is not None:
        args += ["--gbuffer", gbuffer]
    run(args)
    return np.load(out).astype(np.float64)


def rel_rms(img, ref, sel):
    return math.sqrt(((img - ref)[sel] ** 2).sum() / (ref[sel] ** 2).sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ifd", type=pathlib.Path, default=None)
    ap.add_argument("--csv", type=pathlib.Path, default=ROOT / "docs" / "render-tol.csv")
    ap.add_argument("--tables", type=pathlib.Path, default=None,
                    help="folder keeping the lobe tables between runs (default: a temporary one)")
    ap.add_argument("--only", default=None, help="only this material")
    ap.add_argument("--size", default=SIZE, help=f"image size (default {SIZE}; the CSV has "
                    "128x128 and 64x64, whose grazing pixels err more)")
    ap.add_argument("--rust", type=pathlib.Path, default=None,
                    help="write the rule's table (crates/ifd-render/src/tolerance/table.rs) "
                         "from the CSV instead of measuring")
    ap.add_argument("--markdown", action="store_true",
                    help="print the degree the rule chooses per material and tolerance (a "
                         "markdown table, as docs/guide/rendering.md has it) instead of measuring")
    a = ap.parse_args()
    if a.markdown:
        print_markdown(a.csv)
        return
    if a.rust:
        write_rust(a.csv, a.rust)
        return
    ifd = ifd_binary(a.ifd)
    done = []
    if a.csv.exists():
        with open(a.csv) as f:
            done = list(csv.DictReader(f))
    for r in done:
        r.setdefault("size", SIZE)
        r["size"] = r["size"] or SIZE
    rows = list(done)
    size = a.size

    def save():
        rows.sort(key=lambda r: (r["material"], float(r["roughness"]), r["size"], r["map"],
                                 int(r["L"])))
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
            w.writeheader()
            w.writerows(rows)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        tables = a.tables or tmp
        tables.mkdir(parents=True, exist_ok=True)
        gb = tmp / "g.npy"
        render(ifd, MAPS["forest"], "lambert", "isd", tmp / "x.npy", 1, gbuffer=gb, size=size)
        nv = np.load(gb)[..., 3]
        for material, param, spec, tabulated, l0 in kinds():
            if a.only and material != a.only:
                continue
            refs = dict.fromkeys(MAPS)
            prev = {}
            ladder = [l for l in LADDER if l >= l0]
            if size != SIZE:
                # the degrees the default size measured, each of them (no early stop)
                ladder = sorted({int(r["L"]) for r in done if r["material"] == material and
                                 r["size"] == SIZE and float(r["roughness"]) == param})
            for lmax in ladder:
                have = [r for r in done if r["material"] == material and r["size"] == size and
                        float(r["roughness"]) == param and int(r["L"]) == lmax]
                errs = {}
                if len(have) == len(MAPS):
                    for r in have:
                        errs[r["map"]] = (float(r["rel_rms_object"]), float(r["rel_rms_grazing"]))
                else:
                    table = None
                    if tabulated is not None:
                        table = tables / f"{tabulated.replace(':', '_')}_L{lmax}.lobes"
                        if not table.exists():
                            run([ifd, "sphere", "brdf", tabulated, "--lmax", lmax, "-o", table])
                    for name, env in MAPS.items():
                        if refs[name] is None:
                            refs[name] = render(ifd, env, spec, "quadrature", tmp / "ref.npy",
                                                size=size)
                        ref = refs[name]
                        on = ref.sum(axis=-1) > 0
                        graze = on & (nv < GRAZING)
                        img = render(ifd, env, spec, "isd", tmp / "isd.npy", lmax, table,
                                     size=size)
                        e = (rel_rms(img, ref, on), rel_rms(img, ref, graze))
                        errs[name] = e
                        rows.append({"material": material, "roughness": param, "L": lmax,
                                     "rel_rms_object": f"{e[0]:.4e}",
                                     "rel_rms_grazing": f"{e[1]:.4e}", "map": name,
                                     "grazing_pixels": int(graze.sum()),
                                     "object_pixels": int(on.sum()), "size": size})
                    save()
                worst = max(max(e) for e in errs.values())
                print(f"{material} {param:g} L = {lmax}: "
                      + ", ".join(f"{n} {e[0]:.2e} / {e[1]:.2e}" for n, e in errs.items()),
                      flush=True)
                # the floor: no error fell by 10% since the last two degrees
                stalled = prev and all(errs[n][k] > 0.9 * prev[-1][n][k]
                                       for n in errs for k in (0, 1))
                if size == SIZE and len(prev) >= 2 and stalled and all(
                        errs[n][k] > 0.9 * prev[-2][n][k] for n in errs for k in (0, 1)):
                    break
                if size == SIZE and worst < 2e-4:
                    break
                prev = (list(prev) + [errs])[-2:]


RUST_KINDS = {"GLTF_DIELECTRIC": ("gltf-dielectric",), "GLTF_METAL": ("gltf-dielectric", "gltf-metal"),
              "GGX": ("ggx",), "PHONG": ("phong",), "LAMBERT": ("lambert",)}


def sizes(rows):
    """The image sizes the CSV has."""
    return {r.get("size") or SIZE for r in rows}


def write_rust(path, out):  # noqa: C901
    """The rule's table: per material row and L, the largest error over the object and the
    grazing pixels on every map (a glTF metal's row also covers the dielectric's, for
    metalness between 0 and 1), made non-increasing in L from the top (each L's error is the
    largest at that L or above), so the smallest L within a tolerance stays within it at every
    measured L above."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    text = ["//! Generated by `tests/bench/render_tol_table.py --rust` from `docs/render-tol.csv`:",
            "//! per material row (roughness, or Phong's exponent) and degree, the largest",
            "//! relative RMS error against the oracle over the object and over its grazing",
            "//! pixels on both maps (a metal's row covers the dielectric's too), each the",
            "//! largest at that degree or above. Do not edit; rerun the script, then cargo fmt.",
            "",
            "/// One material's measurements: its roughness (or exponent) and, per degree, the",
            "/// worst error.", "pub(super) struct Row {", "    pub param: f64,",
            "    pub errors: &'static [(usize, f64)],", "}", ""]
    for name, materials in RUST_KINDS.items():
        sel = [r for r in rows if r["material"] in materials]
        params = sorted({float(r["roughness"]) for r in sel})
        text.append(f"pub(super) const {name}: &[Row] = &[")
        for p in params:
            per_material = []
            for m in materials:
                per_l = {}
                for r in sel:
                    if r["material"] == m and float(r["roughness"]) == p:
                        e = max(float(r["rel_rms_object"]), float(r["rel_rms_grazing"]))
                        per_l.setdefault(int(r["L"]), {})[(r["map"], r.get("size"))] = e
                # the degrees measured on every map and size
                per_material.append({l: max(e.values()) for l, e in per_l.items()
                                     if len(e) == len(MAPS) * len(sizes(rows))})
            ls = sorted(set.intersection(*(set(d) for d in per_material)))
            if not ls:
                continue
            worst = {l: max(d[l] for d in per_material) for l in ls}
            errs = [worst[l] for l in ls]
            for k in range(len(errs) - 2, -1, -1):
                errs[k] = max(errs[k], errs[k + 1])
            pts = ", ".join(f"({l}, {e:.3e})" for l, e in zip(ls, errs))
            text.append(f"    Row {{\n        param: {p!r},\n        errors: &[{pts}],\n    }},")
        text.append("];")
        text.append("")
    out.write_text("\n".join(text))


def rule_rows(path):
    """{kind: {param: [(L, worst error)]}} as write_rust reduces the CSV."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    out = {}
    for name, materials in RUST_KINDS.items():
        sel = [r for r in rows if r["material"] in materials]
        for p in sorted({float(r["roughness"]) for r in sel}):
            per = []
            for m in materials:
                d = {}
                for r in sel:
                    if r["material"] == m and float(r["roughness"]) == p:
                        e = max(float(r["rel_rms_object"]), float(r["rel_rms_grazing"]))
                        d.setdefault(int(r["L"]), {})[(r["map"], r.get("size"))] = e
                per.append({l: max(e.values()) for l, e in d.items()
                            if len(e) == len(MAPS) * len(sizes(rows))})
            ls = sorted(set.intersection(*(set(d) for d in per)))
            errs = [max(d[l] for d in per) for l in ls]
            for k in range(len(errs) - 2, -1, -1):
                errs[k] = max(errs[k], errs[k + 1])
            out.setdefault(name, {})[p] = list(zip(ls, errs))
    return out


def print_markdown(path, margin=1.2, tols=(0.05, 0.02, 0.01, 0.005)):
    """The degree the rule (crates/ifd-render/src/tolerance) picks at each measured row."""
    print("| material | roughness (Phong: s) | " + " | ".join(f"E = {100 * t:g}%" for t in tols)
          + " | smallest reachable E |")
    print("|---|---|" + "---|" * (len(tols) + 1))
    for name, rows in rule_rows(path).items():
        for p, pts in rows.items():
            cells = []
            for t in tols:
                l = next((l for l, e in pts if e * margin <= t), None)
                cells.append(str(l) if l else "refused")
            best = min(e for _, e in pts) * margin
            print(f"| {name.lower().replace('_', ' ')} | {p:g} | " + " | ".join(cells)
                  + f" | {100 * best:.2g}% |")


if __name__ == "__main__":
    main()
