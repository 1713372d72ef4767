"""The environment renderer's window (apps/ifd-envrender) under Xvfb against `ifd render`.

The app renders the same view as `ifd render` (same map, BRDF, L, camera, tone curve); the
viewport of its screenshot (at one image pixel per screen pixel) must equal `ifd render`'s PNG
within 2 of 255 levels, on the GPU path (the WGSL kernels on the window's own device, lavapipe
here) and on the CPU path. Without Xvfb the test fails unless IFD_WINDOW_TESTS=skip.
"""

import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from conftest import TESTDATA, _binary


def envrender_binary():
    return _binary().with_name("ifd-envrender")


def run_window(tmp_path, *args, check=True):
    exe = envrender_binary()
    if not exe.exists():
        pytest.fail(f"{exe} not built: run `cargo build -p ifd-envrender` first")
    if shutil.which("xvfb-run") is None:
        if os.environ.get("IFD_WINDOW_TESTS") == "skip":
            pytest.skip("xvfb-run not installed (IFD_WINDOW_TESTS=skip)")
        pytest.fail("xvfb-run not installed (apt-get install xvfb xauth) or set IFD_WINDOW_TESTS=skip")
    state = tmp_path / "state"
    state.mkdir(exist_ok=True)
    runtime = tmp_path / "xdg"
    runtime.mkdir(mode=0o700, exist_ok=True)
    env = dict(os.environ, IFD_ENVRENDER_STATE_DIR=str(state), XDG_RUNTIME_DIR=str(runtime))
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", str(exe), *map(str, args)],
                       capture_output=True, text=True, env=env, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"ifd-envrender {args} failed ({p.returncode}):\n{p.stderr}")
    return p


@pytest.mark.parametrize("gpu,variant,brdf,lmax,extra", [
    ("gpu", "sh", "ggx:alpha=0.3", 8, []),
    ("gpu", "sh", "ggx:alpha=0.5", 6, ["maps"]),
    ("gpu", "maps", "phong:s=40", 10, ["--scene", "torus", "--eye", "0,-3.5,2", "--tonemap", "reinhard"]),
    ("cpu", "sh", "ggx:alpha=0.3", 8, ["--exposure", "1"]),
])
def test_screenshot_viewport_matches_ifd_render(run_ifd, tmp_path, gpu, variant, brdf, lmax, extra):
    import cv2
    if extra == ["maps"]:
        # a spatially varying BRDF: roughness stripes and an albedo ramp over the sphere's (u, v)
        rough = np.tile(np.linspace(0.3, 0.8, 16, dtype=np.float32), (8, 1))
        np.save(tmp_path / "rough.npy", rough)
        albedo = np.stack([np.full((8, 16), 0.9), np.linspace(0.2, 1, 8)[:, None].repeat(16, 1),
                           np.full((8, 16), 0.5)], -1).astype(np.float32)
        np.save(tmp_path / "albedo.npy", albedo)
        extra = ["--roughness-map", tmp_path / "rough.npy", "--albedo-map", tmp_path / "albedo.npy"]
    view = ["--brdf", brdf, "--lmax", lmax, "--size", "200x150", *extra]
    shot = tmp_path / "shot.png"
    p = run_window(tmp_path, "--reset", *view, "--variant", variant, "--device", gpu,
                   "--screenshot", shot, "--exit", "--json")
    vp = json.loads(p.stdout.strip().splitlines()[-1])["viewport"]
    assert (vp["width"], vp["height"]) == (200, 150), vp
    method = "isd" if variant == "sh" else "isd-maps"
    tables = ["--roughness-tables", 6] if "--roughness-map" in view else []
    run_ifd("render", "--env", TESTDATA / "forest.hdr", *view, *tables, "--method", method,
            "-o", tmp_path / "ref.png")
    ref = cv2.imread(str(tmp_path / "ref.png")).astype(int)
    img = cv2.imread(str(shot)).astype(int)
    crop = img[vp["y"]:vp["y"] + 150, vp["x"]:vp["x"] + 200]
    diff = np.abs(crop - ref)
    assert diff.max() <= 2, (gpu, variant, diff.max(), (diff > 2).sum())
    # the path the status bar names is the one asked for (GPU: the adapter's name)
    persisted = (tmp_path / "state" / "app.ron").read_text()
    assert "ifd-envrender-settings" in persisted and brdf in persisted


def test_bad_input_exits_2_with_a_message(tmp_path):
    p = run_window(tmp_path, "--reset", "--env", tmp_path / "missing.hdr", "--size", "64x48",
                   "--screenshot", tmp_path / "s.png", "--exit", check=False)
    assert p.returncode == 2 and "missing.hdr" in p.stderr and "panicked" not in p.stderr, p.stderr
    assert not (tmp_path / "s.png").exists()
    (tmp_path / "bad.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n\x01")
    p = run_window(tmp_path, "--reset", "--env", tmp_path / "bad.hdr", "--size", "64x48", "--exit", check=False)
    assert p.returncode == 2 and "bad.hdr" in p.stderr and "panicked" not in p.stderr, p.stderr
    p = run_window(tmp_path, "--reset", "--brdf", "velvet", "--exit", check=False)
    assert p.returncode == 2 and "velvet" in p.stderr, p.stderr
    # a glTF file that is not one, and a comparison without the glTF BRDF
    (tmp_path / "bad.glb").write_bytes(b"glTF\x02\x00\x00\x00\xff\xff")
    p = run_window(tmp_path, "--reset", "--scene", tmp_path / "bad.glb", "--exit", check=False)
    assert p.returncode == 2 and "bad.glb" in p.stderr and "panicked" not in p.stderr, p.stderr
    p = run_window(tmp_path, "--reset", "--brdf", "ggx:alpha=0.3", "--compare", "split-sum",
                   "--exit", check=False)
    assert p.returncode == 2 and "glTF BRDF" in p.stderr, p.stderr


def test_monte_carlo_reference_and_error_against_l(tmp_path):
    """The side-by-side Monte Carlo reference: refined while the camera is still, ISD's error
    against it reported, and the error-against-L curve of the view falling with L (at 64 spp the
    reference's own noise, about 5%, is the floor)."""
    p = run_window(tmp_path, "--reset", "--brdf", "ggx:alpha=0.3", "--lmax", 8, "--size", "96x72",
                   "--device", "gpu", "--reference", "--reference-spp", 64, "--exit", "--json")
    r = json.loads(p.stdout.strip().splitlines()[-1])["reference"]
    assert r["spp"] >= 64 and 0.0 < r["rel_rms"] < 0.25 and r["psnr_db"] > 20, r
    curve = [c["rel_rms"] for c in r["curve"]]
    assert [c["lmax"] for c in r["curve"]] == [2, 4, 6, 8], r
    assert curve[0] > 1.5 * curve[-1], curve


# the bundled textured asset: base colour, metal-roughness, normal, occlusion and emission
# textures; the view's eye given so that the window's framing and `ifd render` agree
GLTF_VIEW = ["--lmax", 6, "--size", "160x120", "--eye", "2.2,-2.0,1.0", "--target", "0,0,0"]


@pytest.mark.parametrize("device", ["gpu", "cpu"])
def test_gltf_asset_in_the_window_matches_ifd_render(run_ifd, tmp_path, device):
    """A glTF asset opened with --scene is shaded with its own materials (a roughness family
    over its range, occlusion and emission in the kernel on the GPU path) and equals `ifd render
    --scene` of the same view within 2 of 255 levels."""
    import cv2
    asset = TESTDATA / "textured.glb"
    shot = tmp_path / "shot.png"
    p = run_window(tmp_path, "--reset", "--scene", asset, *GLTF_VIEW, "--device", device,
                   "--screenshot", shot, "--exit", "--json")
    vp = json.loads(p.stdout.strip().splitlines()[-1])["viewport"]
    run_ifd("render", "--env", TESTDATA / "forest.hdr", "--scene", asset, *GLTF_VIEW,
            "--roughness-tables", 6, "--method", "isd", "-o", tmp_path / "ref.png")
    ref = cv2.imread(str(tmp_path / "ref.png")).astype(int)
    crop = cv2.imread(str(shot)).astype(int)[vp["y"]:vp["y"] + 120, vp["x"]:vp["x"] + 160]
    diff = np.abs(crop - ref)
    assert diff.max() <= 2, (device, diff.max(), (diff > 2).sum())
    persisted = (tmp_path / "state" / "app.ron").read_text()
    assert "textured.glb" in persisted and 'brdf:\\"gltf\\"' in persisted, persisted[:300]


@pytest.mark.parametrize("device,compare,method", [
    ("gpu", "split-sum", "split-sum"),
    ("cpu", "sample-renderer", "split-sum-sample-renderer"),
])
def test_split_sum_beside_isd_reports_its_difference(run_ifd, tmp_path, device, compare, method):
    """--compare shows an engine's split sum beside ISD's image; the numbers it reports (status
    bar, --json) are the split sum's difference from ISD over the object, as computed here from
    `ifd render --method isd` and `--method <split sum>` of the same view."""
    asset = TESTDATA / "textured.glb"
    p = run_window(tmp_path, "--reset", "--scene", asset, *GLTF_VIEW, "--device", device,
                   "--compare", compare, "--screenshot", tmp_path / "shot.png", "--exit", "--json")
    r = json.loads(p.stdout.strip().splitlines()[-1])["split_sum"]
    view = ["--env", TESTDATA / "forest.hdr", "--scene", asset, *GLTF_VIEW]
    run_ifd("render", *view, "--roughness-tables", 6, "--method", "isd", "-o",
            tmp_path / "isd.npy", "--mask", tmp_path / "mask.png")
    run_ifd("render", *view, "--method", method, "-o", tmp_path / "ss.npy")
    import cv2
    on = cv2.imread(str(tmp_path / "mask.png"), cv2.IMREAD_GRAYSCALE) > 127
    isd = np.load(tmp_path / "isd.npy").astype(np.float64)[on]
    ss = np.load(tmp_path / "ss.npy").astype(np.float64)[on]
    rel = np.sqrt(((ss - isd) ** 2).sum() / (isd ** 2).sum())
    assert r["rel_rms"] > 1e-3, r
    assert abs(r["rel_rms"] - rel) <= 0.01 * rel, (r, rel)
    # the 95th percentile of the per-pixel relative difference (channel sums), the colour
    # map's full scale
    # relative to ISD's value, floored at 5% of its mean over the object (ifd_render::Difference)
    tot = isd.sum(-1)
    d = np.abs((ss - isd).sum(-1) / np.maximum(tot, 0.05 * tot.mean()))
    p95 = np.sort(d)[min(len(d) * 95 // 100, len(d) - 1)]
    assert abs(r["relative_p95"] - p95) <= 0.02 * p95 + 1e-6, (r, p95)
