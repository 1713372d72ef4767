"""The glTF 2.0 metallic-roughness BRDF reference (gltf_brdf.py) and the glTF
test assets (gltf_assets.py), checked without the ifd binary: the BRDF's
algebra, reciprocity and energy, the quadratures against independent ones, the
equirect convention, and the assets against the Khronos glTF Validator (npm
gltf-validator in tests/js, installed by scripts/test-all.sh; node and the
module missing is a failure, not a skip)."""

import json
import math
import pathlib
import struct
import subprocess
import sys

import numpy as np
import pytest

import gltf_assets
import gltf_brdf as gb

HERE = pathlib.Path(__file__).resolve().parent
JS = HERE.parent / "js"
VALIDATE = JS / "validate_gltf.mjs"
ROUGH = [0.1, 0.2, 0.3, 0.5, 0.75, 1.0]
VIEWS = [1.0, 0.7, 0.4, 0.2, 0.1, 0.05, 0.02]


def hemi(rng, n):
    """n unit directions with z > 0, some near the horizon and the pole."""
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2])
    v[: n // 8, 2] *= 1e-3
    v[n // 8: n // 4, :2] *= 1e-3
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# --- the BRDF ----------------------------------------------------------------
def test_spec_mix_equals_expanded_form():
    """mix(mix(diffuse, S, F_0.04), S F_b, m) = f0 (1 - w) S + w S +
    0.96 c_diff (1 - w) / pi, with f0 = 0.04 (1 - m) + m b, c_diff = b (1 - m)."""
    rng = np.random.default_rng(35)
    n = 4000
    wi, wo = hemi(rng, n), hemi(rng, n)[rng.permutation(n)]
    base = rng.uniform(0, 1, size=(n, 3))
    m = rng.uniform(0, 1, size=n)
    m[:100], m[100:200] = 0.0, 1.0
    r = rng.uniform(0.05, 1.0, size=n)
    f = gb.brdf(wi, wo, base, m, r)

    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    a = r * r
    s = gb.ggx_d(h[:, 2], a) * gb.smith_v(wi[:, 2], wo[:, 2], a)
    w = ((1 - np.abs(np.sum(wo * h, axis=-1))) ** 5)[:, None]
    f0 = 0.04 * (1 - m[:, None]) + m[:, None] * base
    c_diff = base * (1 - m[:, None])
    expanded = f0 * (1 - w) * s[:, None] + w * s[:, None] + 0.96 * c_diff * (1 - w) / math.pi
    np.testing.assert_allclose(f, expanded, rtol=1e-12, atol=0)
    assert np.all(f > 0)


def test_brdf_head_on_value_and_horizon():
    """Head-on (wi = wo = n): D = 1 / (pi alpha^2), V = 1/4, w = 0, so
    f = f0 / (4 pi alpha^2) + 0.96 c_diff / pi; zero below either horizon."""
    n = np.array([0.0, 0.0, 1.0])
    base = np.array([0.9, 0.5, 0.1])
    for m, r in [(0.0, 0.5), (1.0, 0.3), (0.4, 1.0), (0.7, 0.1)]:
        a = r * r
        f0 = 0.04 * (1 - m) + m * base
        want = f0 / (4 * math.pi * a * a) + 0.96 * base * (1 - m) / math.pi
        np.testing.assert_allclose(gb.brdf(n, n, base, m, r), want, rtol=1e-12)
    below = np.array([0.6, 0.0, -0.8])
    up = np.array([0.0, 0.6, 0.8])
    assert np.all(gb.brdf(below, up, base, 0.5, 0.5) == 0)
    assert np.all(gb.brdf(up, below, base, 0.5, 0.5) == 0)
    with pytest.raises(ValueError):
        gb.brdf(up, up, base, 0.5, 0.0)


def test_brdf_reciprocity():
    rng = np.random.default_rng(7)
    n = 3000
    wi, wo = hemi(rng, n), hemi(rng, n)[rng.permutation(n)]
    base = rng.uniform(0, 1, size=(n, 3))
    m, r = rng.uniform(0, 1, size=n), rng.uniform(0.05, 1, size=n)
    np.testing.assert_allclose(gb.brdf(wi, wo, base, m, r), gb.brdf(wo, wi, base, m, r),
                               rtol=1e-12, atol=0)


# --- directional albedo -------------------------------------------------------
def albedo_halfvector(mu_o, rough, order=16, n_phi=1024):
    """White metal's albedo by an independent quadrature over the half vector:
    GGX's CDF in xi (Gauss-Legendre panels graded towards xi = 1) times the
    azimuth (midpoint), integrand 4 V (n.l) (v.h) / (n.h)."""
    a2 = rough ** 4
    br = np.unique(np.concatenate([1 - 2.0 ** -np.arange(0, 50), np.linspace(0, 1, 65), [1.0]]))
    x, w = np.polynomial.legendre.leggauss(order)
    lo, hi = br[:-1, None], br[1:, None]
    xi = (0.5 * (lo + hi) + 0.5 * (hi - lo) * x).ravel()
    wx = (0.5 * (hi - lo) * w).ravel()
    ph = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    c2 = (1 - xi) / (1 + xi * (a2 - 1))
    ch, sh = np.sqrt(c2), np.sqrt(1 - c2)
    hx = sh[:, None] * np.cos(ph)
    hz = np.broadcast_to(ch[:, None], hx.shape)
    vh = hx * math.sqrt(1 - mu_o * mu_o) + hz * mu_o
    lz = 2 * vh * hz - mu_o
    ok = (lz > 0) & (vh > 0) & (hz > 0)
    v = gb.smith_v(np.where(ok, lz, 0.5), mu_o, rough * rough)
    val = np.where(ok, 4 * v * np.where(ok, lz, 0) * vh / np.where(ok, hz, 1), 0)
    return float((wx[:, None] * val).sum() / n_phi)


def test_albedo_against_independent_quadratures():
    from scipy.integrate import quad

    white = np.ones(3)
    # head-on, the integral is 1-D: h at angle t, l at 2t
    for r in [0.1, 0.3, 0.5, 1.0]:
        a = r * r

        def g(t):
            c2 = math.cos(2 * t)
            return (float(gb.ggx_d(math.cos(t), a) * gb.smith_v(c2, 1.0, a))
                    * c2 * 4 * math.cos(t) * 2 * math.pi * math.sin(t))

        pts = [a * 2.0 ** k / 16 for k in range(-4, 14) if a * 2.0 ** k / 16 < math.pi / 4]
        want, _ = quad(g, 0, math.pi / 4, points=pts, limit=500, epsabs=1e-14, epsrel=1e-13)
        got = gb.directional_albedo(1.0, white, 1.0, r)
        np.testing.assert_allclose(got, want, rtol=1e-9)
    # roughness 1 head-on: D = 1 / pi, V = 1 / (2 (n.l + 1)): E = 1 - ln 2
    np.testing.assert_allclose(gb.directional_albedo(1.0, white, 1.0, 1.0), 1 - math.log(2), rtol=1e-12)
    # other views: the half-vector quadrature
    for r, mu in [(0.1, 0.5), (0.1, 0.05), (0.3, 0.2), (0.5, 0.02), (0.75, 0.7), (1.0, 0.1)]:
        got = gb.directional_albedo(mu, white, 1.0, r)[0]
        assert abs(got - albedo_halfvector(mu, r)) < 1e-5, (r, mu)
        # and its own convergence: doubling the order changes nothing
        assert abs(got - gb.directional_albedo(mu, white, 1.0, r, order=24)[0]) < 1e-9


def test_white_furnace_albedo_at_most_one():
    """A white metal (f0 = 1) keeps at most the energy it receives, at every
    roughness and view, and almost all of it when smooth and seen head-on.

    The dielectric half of the spec's BRDF is not energy conserving: its
    ``1 - F`` weights the diffuse term per light direction (through ``v.h``),
    so at grazing views the specular lobe (F near 1) and the diffuse term
    (F small away from the mirror direction) add up to more than 1 (white
    base: 1.71 at roughness 0.1, n.v = 0.02). Asserted here so no test of the
    renderer bounds a dielectric's furnace by 1."""
    white = np.ones(3)
    lines = []
    for r in ROUGH:
        metal = gb.directional_albedo(np.array(VIEWS), white, 1.0, r)[:, 0]
        diel = gb.directional_albedo(np.array(VIEWS), white, 0.0, r)[:, 0]
        lines.append(f"roughness {r}: metal {np.round(metal, 5)} dielectric {np.round(diel, 5)}")
        assert np.all(metal <= 1.0) and np.all(metal > 0.3), lines[-1]
        assert np.all(diel > 0.9) and diel[0] <= 1.0, lines[-1]
    assert gb.directional_albedo(1.0, white, 1.0, 0.1)[0] > 0.9998
    assert gb.directional_albedo(0.02, white, 0.0, 0.1)[0] > 1.5
    print("views n.v =", VIEWS)
    print("\n".join(lines))


# --- the environment integral -----------------------------------------------
def _frame_view(normal, tangent, mu, phi):
    t, b, n = gb._frame(normal, tangent)
    return n * mu + math.sqrt(1 - mu * mu) * (math.cos(phi) * t + math.sin(phi) * b)


FRAMES = [((0, 0, 1), (1, 0, 0)), ((0.3, -0.5, 0.8), (1, 0, 0)), ((-0.34, 0.6, -0.73), (0, 0, 1))]


@pytest.mark.parametrize("normal,tangent", FRAMES)
def test_white_furnace_env_equals_albedo(normal, tangent):
    """Environment 1: the integral equals the directional albedo (white metal,
    and a coloured mix), including grazing views with an oblique normal, where
    the lobe meets the local horizon inside texels."""
    env = np.ones((32, 64, 3))
    base = np.array([0.9, 0.6, 0.3])
    for (r, mu, m, b) in [(0.1, 0.9, 1.0, np.ones(3)), (0.1, 0.05, 1.0, np.ones(3)),
                          (0.3, 0.2, 1.0, np.ones(3)), (1.0, 0.6, 1.0, np.ones(3)),
                          (0.5, 0.1, 0.5, base)]:
        wo = _frame_view(normal, tangent, mu, 0.7)
        got = gb.integrate_env(env, normal, tangent, wo, b, m, r)
        want = gb.directional_albedo(mu, b, m, r)
        np.testing.assert_allclose(got, want, rtol=1e-5, err_msg=f"r {r} mu {mu} m {m}")
        assert np.all(got <= 1.0 + 1e-6)


def test_env_equirect_convention():
    """Row 0 is the zenith (+z), column 0 starts at +x and runs towards +y:
    the upper rows are the hemisphere z > 0, the first half of the columns the
    hemisphere y > 0. A surface facing into a lit hemisphere gets the full
    albedo, one facing away gets nothing."""
    h = 16
    white = np.ones(3)
    upper = np.zeros((h, 2 * h))
    upper[: h // 2] = 1
    y_pos = np.zeros((h, 2 * h))
    y_pos[:, :h] = 1
    x_pos = np.zeros((h, 2 * h))  # x > 0: azimuth in [0, pi/2) and [3 pi/2, 2 pi)
    x_pos[:, : h // 2] = 1
    x_pos[:, 3 * h // 2:] = 1
    r, mu = 0.5, 0.6
    want = gb.directional_albedo(mu, white, 1.0, r)
    for env, n, t in [(upper, (0, 0, 1), (1, 0, 0)), (y_pos, (0, 1, 0), (0, 0, 1)),
                      (x_pos, (1, 0, 0), (0, 1, 0))]:
        n = np.array(n, dtype=float)
        wo = _frame_view(n, t, mu, 1.1)
        np.testing.assert_allclose(gb.integrate_env(env, n, t, wo, white, 1.0, r), want, rtol=1e-5)
        got = gb.integrate_env(env, -n, t, _frame_view(-n, t, mu, 1.1), white, 1.0, r)
        assert np.all(np.abs(got) < 1e-12)


def brute_env(env, normal, tangent, wo, base, m, r, k=48):
    """Midpoint rule on a uniform (t, p) grid, k x k points per texel, each
    point taking its texel's value (an independent, slow, first-order-in-the-
    horizon check)."""
    hh, ww = env.shape[:2]
    t = (np.arange(hh * k) + 0.5) * math.pi / (hh * k)
    p = (np.arange(ww * k) + 0.5) * 2 * math.pi / (ww * k)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    d = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1)
    tx, bx, nx = gb._frame(normal, tangent)
    loc = np.stack([d @ tx, d @ bx, d @ nx], axis=-1)
    wo = np.asarray(wo, float)
    wo_l = np.array([wo @ tx, wo @ bx, wo @ nx])
    f = gb.brdf(loc, wo_l, base, m, r)
    cos = np.maximum(loc[..., 2], 0)
    e = np.repeat(np.repeat(env, k, axis=0), k, axis=1)
    dw = (math.pi / (hh * k)) * (2 * math.pi / (ww * k)) * np.sin(tt)
    return np.einsum("ij,ijc,ijc->c", dw * cos, f, e)


def test_env_integral_against_brute_force():
    rng = np.random.default_rng(3)
    env = rng.uniform(0, 1, size=(8, 16, 3)) ** 3 * 4
    base = np.array([0.8, 0.5, 0.2])
    for (n, t), (m, r, mu) in zip(FRAMES, [(0.0, 0.5, 0.8), (1.0, 0.7, 0.3), (0.6, 1.0, 0.5)]):
        n = np.array(n, float) / np.linalg.norm(n)
        wo = _frame_view(n, t, mu, 2.0)
        got = gb.integrate_env(env, n, t, wo, base, m, r)
        want = brute_env(env, n, t, wo, base, m, r)
        np.testing.assert_allclose(got, want, rtol=2e-3, err_msg=f"m {m} r {r}")


# --- the assets ------------------------------------------------------------------
def pinned_validator_version():
    deps = json.loads((JS / "package.json").read_text())["dependencies"]
    return deps["gltf-validator"]


def run_validator(*files, json_out=True):
    """node tests/js/validate_gltf.mjs; node or the module missing is a
    failure (the script exits 2 without the module)."""
    import shutil

    if shutil.which("node") is None:
        pytest.fail("node not found: install nodejs and npm, then npm ci --prefix tests/js "
                    "(scripts/test-all.sh does both)")
    args = ["node", str(VALIDATE), *(["--json"] if json_out else []), *map(str, files)]
    return subprocess.run(args, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    out = tmp_path_factory.mktemp("gltf")
    return gltf_assets.write_all(out)


def test_assets_pass_the_khronos_validator(assets):
    """All four assets: no errors, no warnings but the one the script allows
    (MESH_PRIMITIVE_GENERATED_TANGENT_SPACE: no TANGENT on purpose), every
    external resource found, the pinned validator version."""
    p = run_validator(*assets)
    assert p.returncode == 0, p.stdout + p.stderr
    reports = [json.loads(line) for line in p.stdout.splitlines()]
    assert [pathlib.Path(r["file"]).name for r in reports] == list(gltf_assets.ASSETS)
    for r in reports:
        name = pathlib.Path(r["file"]).name
        assert r["validatorVersion"] == pinned_validator_version()
        assert r["issues"]["numErrors"] == 0, name
        warnings = {m["code"] for m in r["issues"]["messages"] if m["severity"] == 1}
        assert warnings <= {"MESH_PRIMITIVE_GENERATED_TANGENT_SPACE"}, (name, warnings)
        assert bool(warnings) == name.startswith("textured"), (name, warnings)
        res = r["info"]["resources"]
        assert all(x["storage"] in ("external", "glb", "buffer-view") for x in res)
        if name.startswith("textured"):
            assert len([x for x in res if x["pointer"].startswith("/images/")]) == 5
            assert all(x["image"]["width"] == 256 for x in res if "image" in x)
        assert r["info"]["drawCallCount"] == (25 if name.startswith("spheres") else 2)
    # the summary form exits 0 too
    p = run_validator(*assets, json_out=False)
    assert p.returncode == 0, p.stdout + p.stderr
    assert p.stdout.count(": ok (glTF Validator") == 4


def test_validator_catches_a_broken_asset(assets, tmp_path):
    """A wrong POSITION max and a missing image are reported as errors."""
    import shutil

    src = assets[0].parent
    for f in src.iterdir():
        shutil.copy(f, tmp_path / f.name)
    doc = json.loads((tmp_path / "spheres.gltf").read_text())
    doc["accessors"][0]["max"][0] += 0.5
    (tmp_path / "spheres.gltf").write_text(json.dumps(doc))
    (tmp_path / "textured_normal.png").unlink()
    for name in ["spheres.gltf", "textured.gltf"]:
        p = run_validator(tmp_path / name, json_out=False)
        assert p.returncode == 1, p.stdout + p.stderr
        assert "FAIL" in p.stdout and "error" in p.stdout


def test_generator_is_deterministic(tmp_path):
    """The CLI and a second in-process build write the same bytes."""
    a, b = tmp_path / "a", tmp_path / "b"
    p = subprocess.run([sys.executable, str(HERE / "gltf_assets.py"), str(a)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    gltf_assets.write_all(b)
    names = sorted(x.name for x in a.iterdir())
    assert names == sorted(x.name for x in b.iterdir())
    assert {"spheres.bin", "textured.bin", "textured_basecolor.png"} <= set(names)
    for n in names:
        assert (a / n).read_bytes() == (b / n).read_bytes(), n


def read_glb(path):
    b = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", b, 0)
    assert (magic, version, length) == (b"glTF", 2, len(b))
    jl, jt = struct.unpack_from("<I4s", b, 12)
    assert jt == b"JSON" and jl % 4 == 0
    js = b[20:20 + jl]
    body = js.rstrip(b" ")
    assert body.endswith(b"}") and len(js) - len(body) < 4  # padded with spaces
    doc = json.loads(js)
    bl, bt = struct.unpack_from("<I4s", b, 20 + jl)
    assert bt == b"BIN\x00" and bl % 4 == 0
    assert 20 + jl + 8 + bl == len(b)
    binary = b[28 + jl:]
    assert doc["buffers"] == [{"byteLength": doc["buffers"][0]["byteLength"]}]
    assert doc["buffers"][0]["byteLength"] <= bl <= doc["buffers"][0]["byteLength"] + 3
    assert set(binary[doc["buffers"][0]["byteLength"]:]) <= {0}
    return doc, binary, js


def accessor_array(doc, data, i):
    a = doc["accessors"][i]
    v = doc["bufferViews"][a["bufferView"]]
    dt = {5126: "<f4", 5123: "<u2"}[a["componentType"]]
    k = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
    off = v["byteOffset"] + a.get("byteOffset", 0)
    assert off % 4 == 0 and "byteStride" not in v
    arr = np.frombuffer(data, dtype=dt, count=a["count"] * k, offset=off)
    assert arr.nbytes <= v["byteLength"]
    return arr.reshape(a["count"], k)


def test_asset_structure(assets):
    """What the renderer's tests rely on, read back independently of the
    validator: GLB framing and padding, exact POSITION bounds, unit normals,
    the same data in .gltf and .glb, no tangents, the non-indexed floor, the
    rotated and scaled node, the wrap modes and texture slots."""
    spheres_gltf, spheres_glb, textured_gltf, textured_glb = assets
    for glb, gltf in [(spheres_glb, spheres_gltf), (textured_glb, textured_gltf)]:
        doc, binary, _ = read_glb(glb)
        tdoc = json.loads(gltf.read_text())
        tbin = (gltf.parent / tdoc["buffers"][0]["uri"]).read_bytes()
        assert len(tbin) == tdoc["buffers"][0]["byteLength"]
        for i in range(len(doc["accessors"])):
            x, y = accessor_array(doc, binary, i), accessor_array(tdoc, tbin, i)
            np.testing.assert_array_equal(x, y)
        for mesh in doc["meshes"]:
            for prim in mesh["primitives"]:
                assert "TANGENT" not in prim["attributes"]
                pos = accessor_array(doc, binary, prim["attributes"]["POSITION"])
                acc = doc["accessors"][prim["attributes"]["POSITION"]]
                assert acc["min"] == [float(v) for v in pos.min(axis=0)]
                assert acc["max"] == [float(v) for v in pos.max(axis=0)]
                nrm = accessor_array(doc, binary, prim["attributes"]["NORMAL"])
                np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1, atol=1e-6)
                assert doc["bufferViews"][acc["bufferView"]]["target"] == 34962
                if "indices" in prim:
                    iv = doc["bufferViews"][doc["accessors"][prim["indices"]]["bufferView"]]
                    assert iv["target"] == 34963
                    idx = accessor_array(doc, binary, prim["indices"])
                    assert idx.max() < len(pos) and len(idx) % 3 == 0

        def strip(d):
            return {k: v for k, v in d.items() if k not in ("buffers", "bufferViews", "images")}

        assert strip(tdoc) == strip(doc)
        assert tdoc["bufferViews"] == doc["bufferViews"][: len(tdoc["bufferViews"])]
    doc, binary, _ = read_glb(textured_glb)
    prims = {m["name"]: m["primitives"][0] for m in doc["meshes"]}
    assert "indices" not in prims["floor"] and "indices" in prims["ellipsoid"]
    assert doc["accessors"][prims["floor"]["attributes"]["POSITION"]]["count"] % 3 == 0
    node = next(n for n in doc["nodes"] if n["name"] == "ellipsoid")
    assert abs(np.linalg.norm(node["rotation"]) - 1) < 1e-12 and node["scale"] != [1, 1, 1]
    assert doc["samplers"] == [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 33648}]
    mat = doc["materials"][0]
    assert mat["normalTexture"]["scale"] == gltf_assets.NORMAL_SCALE
    assert mat["occlusionTexture"]["strength"] == gltf_assets.OCCLUSION_STRENGTH
    assert mat["emissiveFactor"] == list(gltf_assets.EMISSIVE_FACTOR)
    assert all(im["mimeType"] == "image/png" and "bufferView" in im for im in doc["images"])
    uv = accessor_array(doc, binary, prims["ellipsoid"]["attributes"]["TEXCOORD_0"])
    assert uv[:, 0].max() > 1.5  # wrapping matters
    # the sphere grid: 25 materials, metallic by row, roughness by column
    doc, _, _ = read_glb(spheres_glb)
    grid = {(m["extras"]["row"], m["extras"]["col"]): m for m in doc["materials"]}
    assert len(grid) == 25
    for (i, j), m in grid.items():
        pbr = m["pbrMetallicRoughness"]
        assert pbr["metallicFactor"] == gltf_assets.METALLIC[i]
        assert pbr["roughnessFactor"] == gltf_assets.ROUGHNESS[j] > 0
    assert doc["cameras"][0]["type"] == "perspective" and doc["scene"] == 0


def test_normal_map_bumps_are_raised():
    """The normal texture follows glTF's tangent space (+x = +u, +y = image
    up): to the right of a bump's centre the normal leans to +x, above it
    (smaller v) to +y."""
    nrm = gltf_assets.textures()["normal"].astype(float) / 255 * 2 - 1
    n = nrm.shape[0]
    c = n // 16  # the first bump's centre (8 bumps per side)
    d = n // 64
    assert nrm[c, c + d, 0] > 0.1 and nrm[c, c - d, 0] < -0.1
    assert nrm[c - d, c, 1] > 0.1 and nrm[c + d, c, 1] < -0.1
    assert np.all(nrm[..., 2] > 0)


def test_the_bundled_assets_are_the_generators_output():
    """testdata/spheres.glb and testdata/textured.glb (used by the docs and
    the quick tour) are byte for byte what gltf_assets.py writes."""
    testdata = pathlib.Path(__file__).resolve().parents[2] / "testdata"
    built = {**gltf_assets.build_spheres(), **gltf_assets.build_textured()}
    for name in ("spheres.glb", "textured.glb"):
        assert (testdata / name).read_bytes() == built[name], name
