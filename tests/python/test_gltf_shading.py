"""`ifd render --brdf gltf:..` against an independent numpy brute force of the
full glTF-BRDF integral (`gltf_brdf.integrate_env`) at single pixels: a 1x1
image whose pixel-centre ray runs from `--eye` to `--target` and hits the
unit sphere at a point computed here, so every view angle can be chosen.

The environment is a smooth random 64x32 map written as .npy and read at
its own size (no downsampling), so both sides integrate the same
piecewise-constant texels."""

import math

import numpy as np
import pytest

import gltf_brdf
from conftest import ROOT

MATERIALS = [
    # (base, metallic, roughness)
    ((0.95, 0.64, 0.54), 1.0, 0.5),
    ((0.8, 0.2, 0.2), 0.0, 0.7),
    ((0.5, 0.5, 0.5), 0.5, 1.0),
]

# (eye, target): head-on, oblique, grazing (the ray meets the sphere near its rim)
VIEWS = [
    ((0.0, -4.0, 0.5), (0.0, 0.0, 0.0)),
    ((3.0, -2.5, 1.2), (0.2, 0.3, 0.4)),
    ((0.0, -4.0, 0.0), (0.0, 0.0, 0.93)),
]


@pytest.fixture(scope="module")
def env_map(tmp_path_factory):
    """A smooth, positive, direction-dependent 64x32 RGB map (a few low
    harmonics and one bright blob)."""
    h, w = 32, 64
    t = (np.arange(h) + 0.5) * math.pi / h
    p = (np.arange(w) + 0.5) * 2 * math.pi / w
    tt, pp = np.meshgrid(t, p, indexing="ij")
    x, y, z = np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)
    blob = np.exp(-((x - 0.5) ** 2 + (y + 0.6) ** 2 + (z - 0.6) ** 2) / 0.1)
    env = np.stack([1.0 + 0.6 * z + 0.3 * x + 4.0 * blob,
                    0.9 + 0.4 * z - 0.2 * y + 3.0 * blob,
                    0.8 + 0.2 * z + 0.3 * y * x + 2.0 * blob], axis=-1)
    path = tmp_path_factory.mktemp("env") / "env.npy"
    np.save(path, env.astype(np.float32))
    return path, env


def hit(eye, target):
    """The unit sphere's first hit of the ray from `eye` towards `target`:
    the point (= the normal) and the direction towards the viewer."""
    o = np.asarray(eye, dtype=np.float64)
    d = np.asarray(target, dtype=np.float64) - o
    d /= np.linalg.norm(d)
    b = o @ d
    disc = b * b - (o @ o - 1.0)
    assert disc > 0, "the ray misses the sphere"
    t = -b - math.sqrt(disc)
    p = o + t * d
    return p / np.linalg.norm(p), -d


def render_pixel(run_ifd, tmp_path, env_path, eye, target, spec, method, extra=()):
    out = tmp_path / f"{method}.npy"
    run_ifd("render", "--env", env_path, "--env-size", "64x32", "--brdf", spec,
            "--method", method, "--size", "1x1", "--fov", "1",
            "--eye", ",".join(map(str, eye)), "--target", ",".join(map(str, target)),
            "--no-background", "-o", out, *extra)
    return np.load(out).reshape(-1)[:3].astype(np.float64)


@pytest.mark.parametrize("material", MATERIALS, ids=lambda m: f"m{m[1]}-r{m[2]}")
def test_quadrature_and_isd_match_the_numpy_brute_force(run_ifd, tmp_path, env_map, material):
    env_path, env = env_map
    base, metallic, roughness = material
    spec = (f"gltf:roughness={roughness},metallic={metallic},"
            f"base={base[0]}:{base[1]}:{base[2]}")
    for eye, target in VIEWS:
        n, wo = hit(eye, target)
        # the tangent only fixes the (isotropic) frame
        tangent = np.cross([0.0, 0.0, 1.0], n) if abs(n[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
        want = gltf_brdf.integrate_env(env, n, tangent, wo, base, metallic, roughness, tol=1e-6)
        quad = render_pixel(run_ifd, tmp_path, env_path, eye, target, spec, "quadrature")
        # the oracle converges each texel to 1e-6 of the pixel; f32 output
        np.testing.assert_allclose(quad, want, rtol=2e-4, err_msg=f"{spec} from {eye}")
        # ISD at L = 24, converged in L here: what remains is the lobe table's
        # linear interpolation over theta_o (entries 3.6 degrees apart at
        # roughness 0.5), up to 2% at one pixel next to the bright blob (the
        # same as for `ggx:alpha=0.25`); image-wide the relative RMS is below
        # 1% (crates/ifd-render/tests/render.rs)
        isd = render_pixel(run_ifd, tmp_path, env_path, eye, target, spec, "isd", ("--lmax", "24"))
        rel = np.abs(isd - want).max() / np.abs(want).max()
        assert rel < 0.03, f"{spec} from {eye}: isd {isd} vs {want} ({rel:.2e})"


def test_split_sum_is_exact_for_a_uniform_map_and_not_otherwise(run_ifd, tmp_path, env_map):
    """The split sum integrates a constant map exactly (both sides give the
    directional albedo); on a varying map it differs from the exact value."""
    env_path, env = env_map
    const = tmp_path / "one.npy"
    np.save(const, np.ones((32, 64, 3), dtype=np.float32))
    spec = "gltf:roughness=0.6,metallic=0.3,base=0.9:0.7:0.4"
    eye, target = VIEWS[1]
    n, wo = hit(eye, target)
    albedo = gltf_brdf.directional_albedo(float(n @ wo), (0.9, 0.7, 0.4), 0.3, 0.6)
    got = render_pixel(run_ifd, tmp_path, const, eye, target, spec, "split-sum")
    np.testing.assert_allclose(got, albedo, rtol=5e-3)
    tangent = np.cross([0.0, 0.0, 1.0], n)
    exact = gltf_brdf.integrate_env(env, n, tangent, wo, (0.9, 0.7, 0.4), 0.3, 0.6)
    varied = render_pixel(run_ifd, tmp_path, env_path, eye, target, spec, "split-sum")
    assert np.abs(varied - exact).max() > 1e-3 * np.abs(exact).max()


def test_gbuffer_holds_each_pixels_normal_view_cosine_and_material(run_ifd, tmp_path):
    """--gbuffer: the shading normal, n.v, roughness and metalness per pixel, against a numpy
    ray cast of the unit sphere through the same pinhole camera (z up)."""
    size, eye, fov = 40, np.array([3.0, -2.5, 1.2]), 40.0
    run_ifd("render", "--env", ROOT / "testdata" / "forest.hdr", "--brdf",
            "gltf:roughness=0.4,metallic=0.7", "--method", "split-sum", "--size", f"{size}x{size}",
            "--eye", "3,-2.5,1.2", "--target", "0,0,0", "--fov", fov, "-o", tmp_path / "a.npy",
            "--gbuffer", tmp_path / "g.npy")
    g = np.load(tmp_path / "g.npy")
    assert g.shape == (size, size, 6)
    fwd = -eye / np.linalg.norm(eye)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    th = math.tan(math.radians(fov) / 2)
    j, i = np.mgrid[0:size, 0:size] + 0.5
    d = (fwd + ((2 * i / size - 1) * th)[..., None] * right
         + ((1 - 2 * j / size) * th)[..., None] * up)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = d @ eye
    disc = b * b - (eye @ eye - 1)
    on = disc > 1e-6
    t = -b - np.sqrt(np.where(on, disc, 0))
    n = eye + t[..., None] * d
    # away from the silhouette, where a pixel centre's hit is unambiguous
    inner = on & (disc > 0.05)
    np.testing.assert_allclose(g[inner][:, :3], n[inner], atol=1e-4)
    np.testing.assert_allclose(g[inner][:, 3], np.einsum("ij,ij->i", n[inner], -d[inner]),
                               atol=1e-4)
    np.testing.assert_allclose(g[inner][:, 4:], np.tile([0.4, 0.7], (inner.sum(), 1)), atol=1e-6)
    assert not g[~on].any(), "zeros off the object"
    p = run_ifd("render", "--env", ROOT / "testdata" / "forest.hdr", "--brdf", "lambert",
                "--lmax", 2, "--size", "8x8", "-o", tmp_path / "b.png", "--gbuffer",
                tmp_path / "g.png", check=False)
    assert p.returncode == 2 and "--gbuffer" in p.stderr and ".npy" in p.stderr, p.stderr
    assert not (tmp_path / "b.png").exists()


# --- glTF assets --------------------------------------------------------------

import gltf_assets  # noqa: E402


def single_sphere(path, metallic, roughness, base):
    """A .glb of one UV sphere with one metallic-roughness material."""
    b = gltf_assets.Builder()
    pos, nrm, uv, idx = gltf_assets.uv_sphere(1.0, 64, 32)
    attrs = b.attributes(pos, nrm, uv)
    ind = b.accessor(idx, gltf_assets.ELEMENT_ARRAY_BUFFER)
    mat = b.add("materials", {"pbrMetallicRoughness": {
        "baseColorFactor": [*base, 1.0], "metallicFactor": metallic, "roughnessFactor": roughness}})
    mesh = b.add("meshes", {"primitives": [{"attributes": dict(attrs), "indices": ind,
                                            "material": mat, "mode": 4}]})
    node = b.add("nodes", {"mesh": mesh})
    b.doc["scenes"].append({"nodes": [node]})
    _, glb, data = b.finish("unused.bin")
    path.write_bytes(gltf_assets.glb_bytes(glb, data))
    return path


@pytest.mark.parametrize("metallic,roughness", [(1.0, 0.5), (0.0, 0.7), (0.5, 1.0)])
def test_a_gltf_asset_is_shaded_by_isd_within_one_percent_of_the_oracle(
        run_json, tmp_path, metallic, roughness):
    """The issue's accuracy goal on an asset: relative RMS <= 1% against the
    oracle for roughness >= 0.5 at L <= 24 (here L = 16, the forest map)."""
    asset = single_sphere(tmp_path / "s.glb", metallic, roughness, (0.9, 0.6, 0.3))
    r = run_json("render", "--env", ROOT / "testdata" / "forest.hdr", "--env-size", "64x32",
                 "--scene", asset, "--lmax", "16", "--size", "40x40", "--no-background",
                 "--error-map", tmp_path / "err.npy", "-o", tmp_path / "isd.npy")
    assert r["brdf"] == "gltf" and r["object_pixels"] > 500
    assert r["error_map"]["relative_rms"] < 0.01, r["error_map"]


def test_generated_assets_render_the_same_from_gltf_and_glb(run_ifd, tmp_path):
    """The test assets (sphere grid; textured, normal-mapped, no tangents)
    read the same from .gltf (external buffers and images) and .glb."""
    out = tmp_path / "assets"
    gltf_assets.write_all(out)
    for name in ("spheres", "textured"):
        imgs = []
        for ext in ("gltf", "glb"):
            o = tmp_path / f"{name}-{ext}.npy"
            run_ifd("render", "--env", ROOT / "testdata" / "forest.hdr", "--env-size", "64x32",
                    "--scene", out / f"{name}.{ext}", "--method", "split-sum", "--size", "48x48",
                    "-o", o)
            imgs.append(np.load(o))
        assert np.array_equal(imgs[0], imgs[1]), name
        assert np.isfinite(imgs[0]).all() and imgs[0].max() > 0


@pytest.mark.parametrize("content,part", [
    (b"{not json", "JSON"),
    (b'{"asset": {"version": "2.0"}, "extensionsRequired": ["KHR_draco_mesh_compression"],'
     b' "extensionsUsed": ["KHR_draco_mesh_compression"]}', "KHR_draco_mesh_compression"),
    (b"glTF\x02\x00\x00\x00\xff\xff\x00\x00", "GLB"),
])
def test_bad_gltf_files_exit_2_naming_the_problem(run_ifd, tmp_path, content, part):
    ext = "glb" if content.startswith(b"glTF") else "gltf"
    bad = tmp_path / f"bad.{ext}"
    bad.write_bytes(content)
    p = run_ifd("render", "--env", ROOT / "testdata" / "forest.hdr", "--scene", bad,
                "-o", tmp_path / "x.png", check=False)
    assert p.returncode == 2, p.stderr
    assert "bad." in p.stderr and part.lower() in p.stderr.lower(), p.stderr
    assert "panicked" not in p.stderr
    assert not (tmp_path / "x.png").exists()
