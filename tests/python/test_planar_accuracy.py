"""End-to-end accuracy of `ifd decompose` + `ifd filter` (issue: planar core, second pass).

For every built-in filter spec, at scales 0.5 (where the scaled kernel's finest
feature is at least 1 px), 1, 2 and 4 and at several angles:

(a) the evaluation error: `ifd filter` on white noise against `cv2.filter2D`
    with the decomposition's own sum of Gaussians sampled at pixel centres
    (numpy, from the JSON terms; each atom widened by the pixel footprint
    where the filter is defined as averaged over pixels: hard-edged kernels,
    and every kernel below scale 1) must be <= 0.5% relative L2;
(b) the end-to-end error: the same output against `cv2.filter2D` with the true
    kernel (sampled in numpy from its formula, independently of the Rust kernel
    code; integrated over each pixel at scale 0.5 and for hard-edged kernels)
    must be <= the fit's reported kernel error + 0.5%;
(c) on a photograph, both errors are reported (printed; with IFD_UPDATE_DOCS=1
    the table is written to docs/planar-accuracy.csv).
"""

import csv
import json
import os

import cv2
import numpy as np
import pytest

from conftest import ROOT, TESTDATA, load_gray

NOISE_SIZE = 768
RESULTS = []


def rotate(x, y, theta_deg):
    """R_{-theta} d in (x right, y down): the kernel's local coordinates."""
    t = np.deg2rad(theta_deg)
    c, s = np.cos(t), np.sin(t)
    return c * x - s * y, s * x + c * y


def gauss_fn(sx, sy):
    return lambda u, v: np.exp(-0.5 * ((u / sx) ** 2 + (v / sy) ** 2))


def dgauss_fn(order, sigma):
    def k(u, v):
        g = np.exp(-(u * u + v * v) / (2 * sigma**2)) / (2 * np.pi * sigma**2)
        if order == "xx":
            return (u * u / sigma**4 - 1 / sigma**2) * g
        return u * v / sigma**4 * g

    return k


def log_fn(sigma):
    def k(u, v):
        q = u * u + v * v
        g = np.exp(-q / (2 * sigma**2)) / (2 * np.pi * sigma**2)
        return g * (q / sigma**4 - 2 / sigma**2)

    return k


def gabor_fn(sigma, freq):
    def k(u, v):
        g = np.exp(-(u * u + v * v) / (2 * sigma**2)) / (2 * np.pi * sigma**2)
        return g * np.cos(2 * np.pi * freq * u)

    return k


def rect_fn(w, h):
    return lambda u, v: ((np.abs(u) <= 0.5 * w) & (np.abs(v) <= 0.5 * h)).astype(np.float64)


# spec, true kernel in its own frame (theta = 0), spec angle, normalised to
# unit sum (as the spec samples it), hard-edged, finest feature (px at scale 1).
SPECS = [
    ("gauss:sx=16,sy=4,theta=10", gauss_fn(16, 4), 10, True, False, 4),
    ("gauss:sx=16,sy=2,theta=20", gauss_fn(16, 2), 20, True, False, 2),
    ("dgauss:order=xx,sigma=2", dgauss_fn("xx", 2), 0, False, False, 2),
    ("dgauss:order=xy,sigma=2", dgauss_fn("xy", 2), 0, False, False, 2),
    ("dgauss:order=xx,sigma=4", dgauss_fn("xx", 4), 0, False, False, 4),
    ("dgauss:order=xy,sigma=8", dgauss_fn("xy", 8), 0, False, False, 8),
    ("dgauss:order=xx,sigma=12", dgauss_fn("xx", 12), 0, False, False, 12),
    ("dgauss:order=xx,sigma=16", dgauss_fn("xx", 16), 0, False, False, 16),
    ("log:sigma=4", log_fn(4), 0, False, False, 4),
    ("gabor:sigma=6,freq=0.1", gabor_fn(6, 0.1), 0, False, False, 5),
]

# Hard-edged kernels: fitted to pixel averages on a grid twice as fine (see
# docs/planar-accuracy.md). They do not meet the goals away from the fitted
# pose: a sum of Gaussians no narrower than the pixel's own blur matches a
# 1 px edge to a few percent, and rescaling a pixel average by Gaussian
# variance arithmetic is only second-order exact. Measured, and expected to
# fail until the study's next step lands.
HARD_EDGED = [
    ("box:w=15,h=5,theta=20", rect_fn(15, 5), 20, True, True, 5),
    ("line:len=31,theta=10", rect_fn(31, 1), 10, True, True, 1),
]
ANGLES = [0.0, 30.0, -75.0]
SCALES = [0.5, 1.0, 2.0, 4.0]


def true_kernel(fn, spec_theta, normalise, angle, scale, r, integrate):
    """k_{theta,s}(d) = k(R_{-theta} d / s) / s^2 on the (2r+1)^2 grid,
    averaged over 8x8 points per pixel when `integrate`."""
    n = 8 if integrate else 1
    off = (np.arange(n) + 0.5) / n - 0.5
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    k = np.zeros_like(x)
    for oy in off:
        for ox in off:
            u, v = rotate(x + ox, y + oy, spec_theta + angle)
            k += fn(u / scale, v / scale) / scale**2
    k /= n * n
    if normalise:
        k /= k.sum()
    return k


def footprint_variance(sampling, scale):
    """The pixel average's variance added to every atom at `scale` (docs/planar-accuracy.md):
    the target sampling (averaged over the output pixel for hard-edged kernels
    and below scale 1) minus the average the fit already carries, scaled."""
    box = 1.0 / 12.0
    target = box if sampling == "area" or scale < 1 else 0.0
    fitted = box * scale * scale if sampling == "area" else 0.0
    return target - fitted


def mog_kernel(d, angle, scale, r):
    """The decomposition's sum of Gaussians, rotated and scaled (each atom widened by the
    pixel footprint), sampled at pixel centres."""
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)
    t = np.deg2rad(angle)
    c, s = np.cos(t), np.sin(t)
    k = np.zeros_like(x)
    var = footprint_variance(d["kernel"]["sampling"], scale)
    for term in d["terms"]:
        cx, cy = term["x"], term["y"]
        sg = np.sqrt(max((scale * term["sigma"]) ** 2 + var, 0.25 * (scale * term["sigma"]) ** 2))
        ox, oy = scale * (c * cx + s * cy), scale * (-s * cx + c * cy)
        k += term["weight"] * np.exp(-((x - ox) ** 2 + (y - oy) ** 2) / (2 * sg * sg)) / (2 * np.pi * sg * sg)
    return k


def rel(out, ref):
    return float(np.linalg.norm(out - ref) / np.linalg.norm(ref))


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    d = tmp_path_factory.mktemp("acc")
    noise = np.random.default_rng(7).standard_normal((NOISE_SIZE, NOISE_SIZE)).astype(np.float32)
    photo = load_gray("camera.png").astype(np.float32)
    photo = cv2.resize(photo, (NOISE_SIZE, NOISE_SIZE), interpolation=cv2.INTER_CUBIC)
    np.save(d / "noise.npy", noise)
    np.save(d / "photo.npy", photo)
    return d, {"noise": noise, "photo": photo}


@pytest.fixture(scope="module", autouse=True)
def write_table():
    yield
    if os.environ.get("IFD_UPDATE_DOCS") == "1" and RESULTS:
        with open(ROOT / "docs" / "planar-accuracy.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["spec", "scale", "angle", "terms", "kernel_error", "noise_eval", "noise_total",
                        "photo_eval", "photo_total", "interpolation", "pyramid_factor", "direct_terms"])
            w.writerows(RESULTS)


@pytest.mark.parametrize(
    "spec,fn,spec_theta,normalise,hard,finest",
    SPECS
    + [
        pytest.param(*h, marks=pytest.mark.xfail(strict=True, reason="hard-edged: docs/planar-accuracy.md"))
        for h in HARD_EDGED
    ],
    ids=[s[0] for s in SPECS + HARD_EDGED],
)
def test_filtered_error_matches_kernel_error(run_ifd, images, spec, fn, spec_theta, normalise, hard, finest):
    folder, arrays = images
    dfile = folder / "d.json"
    run_ifd("decompose", spec, "-o", dfile)
    d = json.loads(dfile.read_text())
    kernel_error = d["report"]["rel_l2_error"]
    half = max(d["kernel"]["width"], d["kernel"]["height"]) // 2
    failures = []
    for scale in SCALES:
        if scale * finest < 1.0:
            continue  # the scaled kernel's finest feature is below a pixel
        # Wide enough for the true kernel and for every term's Gaussian to 5 sigma.
        reach = max(np.hypot(t["x"], t["y"]) + 5 * t["sigma"] for t in d["terms"])
        r = int(np.ceil(max(half, reach) * scale)) + 2
        if 2 * r + 1 > NOISE_SIZE:
            failures.append(f"scale {scale}: kernel {2 * r + 1} px does not fit the test image")
            continue
        for angle in ANGLES:
            out_file = folder / "out.npy"
            row = [spec, scale, angle, len(d["terms"]), f"{kernel_error:.5f}"]
            km = mog_kernel(d, angle, scale, r)
            kt = true_kernel(fn, spec_theta, normalise, angle, scale, r, integrate=hard or scale < 1)
            for name in ["noise", "photo"]:
                p = run_ifd("filter", folder / f"{name}.npy", "--decomp", dfile, "--angle", angle,
                            "--scale", scale, "-o", out_file, "-v")
                out = np.load(out_file).astype(np.float64)
                src = arrays[name].astype(np.float64)
                ref_m = cv2.filter2D(src, -1, km, borderType=cv2.BORDER_REFLECT_101)
                ref_t = cv2.filter2D(src, -1, kt, borderType=cv2.BORDER_REFLECT_101)
                e_eval, e_total = rel(out, ref_m), rel(out, ref_t)
                row += [f"{e_eval:.5f}", f"{e_total:.5f}"]
                if name == "noise":
                    if e_eval > 0.005:
                        failures.append(f"scale {scale} angle {angle}: evaluation error {e_eval:.2%} > 0.5%")
                    if e_total > kernel_error + 0.005:
                        failures.append(f"scale {scale} angle {angle}: error {e_total:.2%} against the true "
                                        f"kernel > kernel error {kernel_error:.2%} + 0.5%")
            plan = next(line for line in p.stderr.splitlines() if line.startswith("evaluation:"))
            words = plan.replace(",", "").split()
            row += [words[1], words[5], words[6]]
            RESULTS.append(row)
            print(f"{spec} s={scale} angle={angle}: noise eval {float(row[5]):.3%} total {float(row[6]):.3%}, "
                  f"photo eval {float(row[7]):.3%} total {float(row[8]):.3%} ({plan})")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("spec", ["box:w=15,h=5,theta=20", "line:len=31,theta=10", "disk:r=10", "disk:r=4"])
def test_hard_edged_fit_reaches_the_tolerance_on_pixels_and_between(run_json, tmp_path, spec):
    """Fitted on a grid twice as fine, hard-edged kernels reach 1% both on the pixel
    grid and between pixel centres (the disk stalled at 5-8% before)."""
    r = run_json("decompose", spec, "-o", tmp_path / "d.json", "--json")
    print(f"{spec}: {r['terms']} terms, {r['rel_l2_error']:.3%} on pixels, "
          f"{r['fine_rel_l2_error']:.3%} between, {r['seconds']:.2f} s")
    assert r["oversample"] == 2
    assert r["fine_rel_l2_error"] <= 0.01 + 1e-9
    assert r["rel_l2_error"] <= 0.011


# Not strict: how far the sub-pixel atoms' sum drifts depends on the fit, which
# varies slightly from run to run (parallel sums), and may fall within the
# tolerance; an XPASS is reported as such, never counted as a pass.
HARD_POSE = pytest.mark.xfail(strict=False, reason="hard-edged, away from the fitted pose: docs/planar-accuracy.md")


@pytest.mark.parametrize(
    "spec,poses",
    [
        (spec, [(0, 1), (30, 1.5)])
        for spec in ["gauss:sx=8,sy=2,theta=30", "dgauss:order=xx,sigma=4", "gabor:sigma=6,freq=0.1"]
    ]
    + [(spec, [(0, 1)]) for spec in ["box:w=15,h=5,theta=20", "disk:r=6"]]
    + [pytest.param(spec, [(30, 1.5)], marks=HARD_POSE) for spec in ["box:w=15,h=5,theta=20", "disk:r=6"]],
)
def test_a_constant_image_changes_by_at_most_the_reported_dc_error(run_json, run_ifd, tmp_path, spec, poses):
    """The report's full-plane DC error (the sum of Gaussians sampled at pixel centres over
    the whole plane, against the kernel's sum) is what the filter does to a constant image.
    Hard-edged fits hold it at the pose they were fitted at; rotated and rescaled, their
    sub-pixel atoms sum differently (a known failure, measured 5.8e-3 against 1.2e-3 for
    the box)."""
    r = run_json("decompose", spec, "-o", tmp_path / "d.json", "--json")
    c = 0.7
    np.save(tmp_path / "flat.npy", np.full((160, 160), c, np.float32))
    for angle, scale in poses:
        run_ifd("filter", tmp_path / "flat.npy", "--decomp", tmp_path / "d.json", "--angle", angle,
                "--scale", scale, "-o", tmp_path / "out.npy")
        out = np.load(tmp_path / "out.npy").astype(np.float64)
        change = np.abs(out / c - r["kernel_sum"]).max()
        print(f"{spec} angle {angle} scale {scale}: gain error {change:.2e}, reported {r['full_plane_dc_error']:.2e}")
        # (f32 weights and lookups: 1e-4.)
        assert change <= r["full_plane_dc_error"] + 1e-4, (change, r["full_plane_dc_error"])


def test_parameter_maps_are_data_not_images(run_ifd, tmp_path):
    """An angle map of 45 degrees stored as an 8-bit PNG used to be read as 45/255: it is
    refused with a message saying how to write a map; .npy maps are read as values."""
    import cv2

    img = np.random.default_rng(1).random((48, 64)).astype(np.float32)
    np.save(tmp_path / "img.npy", img)
    run_ifd("decompose", "gauss:sx=6,sy=1.5", "-o", tmp_path / "d.json")
    cv2.imwrite(str(tmp_path / "angle.png"), np.full((48, 64), 45, np.uint8))
    p = run_ifd("filter", tmp_path / "img.npy", "--decomp", tmp_path / "d.json", "--angle-map",
                tmp_path / "angle.png", "-o", tmp_path / "out.npy", check=False)
    assert p.returncode == 2, p.stderr
    assert "angle.png" in p.stderr and "8-bit" in p.stderr and ".npy" in p.stderr, p.stderr
    assert "panicked" not in p.stderr
    assert not (tmp_path / "out.npy").exists()
    # The same map as uint8 and float32 .npy: both read as 45 degrees.
    run_ifd("filter", tmp_path / "img.npy", "--decomp", tmp_path / "d.json", "--angle", 45,
            "-o", tmp_path / "const.npy")
    outs = []
    for dtype in [np.uint8, np.float32]:
        np.save(tmp_path / "angle.npy", np.full((48, 64), 45, dtype))
        run_ifd("filter", tmp_path / "img.npy", "--decomp", tmp_path / "d.json", "--angle-map",
                tmp_path / "angle.npy", "-o", tmp_path / "out.npy")
        outs.append(np.load(tmp_path / "out.npy"))
    np.testing.assert_array_equal(outs[0], outs[1])
    # The per-pixel path reads every term from the stack; the constant one
    # evaluates the narrowest directly: the same filter to 1e-4.
    np.testing.assert_allclose(outs[0], np.load(tmp_path / "const.npy"), atol=1e-4)
