"""`ifd filter` and `ifd smooth` tile by tile (streaming .npy) give the whole
image's result.

Tiles are cut smaller than the filter's reach, so every tile border lies
inside some output pixel's footprint; the halo, the alignment of tile
origins to the stack's coarsest subsampling and the shared scale range must
make each tile's pixels equal the whole image's (to float rounding, 1e-5 of
the result's range asserted). The smoother's chain (Hessian, tensor
averaging, dab grid, smoothing filters) has its own halo
(`ifd_smooth::tiled`); its filter field is streamed too. Also: the automatic switch when the image does
not fit `--memory-budget`, and the formats that cannot stream.
"""

import numpy as np
import pytest
import scipy.ndimage as nd
import skimage.io

from conftest import TESTDATA, save_npy


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("tiled")
    rng = np.random.default_rng(11)
    h, w = 700, 1000
    img = nd.gaussian_filter(rng.random((h, w, 3)), (1.5, 1.5, 0)).astype(np.float32)
    y, x = np.mgrid[0:h, 0:w]
    angle = np.degrees(np.arctan2(y - h / 2, x - w / 2)).astype(np.float32)
    scale = (0.7 + 1.6 * x / w).astype(np.float32)
    return {
        "dir": d,
        "img": save_npy(d / "img.npy", img),
        "angle": save_npy(d / "angle.npy", angle),
        "scale": save_npy(d / "scale.npy", scale),
    }


@pytest.fixture(scope="module")
def decomp(scene, run_ifd):
    p = scene["dir"] / "g.json"
    run_ifd("decompose", "gauss:sx=12,sy=1.5,theta=10", "-o", p)
    return p


def _close(a, b):
    a, b = np.load(a), np.load(b)
    assert a.shape == b.shape
    err = float(np.abs(a - b).max())
    assert err <= 1e-5 * float(np.abs(b).max()), err
    return err


@pytest.mark.parametrize(
    "pose, tile",
    [
        (("--angle-map", "angle", "--scale-map", "scale"), 48),  # per-pixel angle and scale
        (("--angle-map", "angle", "--scale", "2.5"), 96),  # per-pixel angle, deep stack
        (("--angle", "30", "--scale", "1.5"), 64),  # constant pose: exact levels, direct terms
    ],
    ids=["angle+scale maps", "angle map, scale 2.5", "constant pose"],
)
def test_tiles_equal_the_whole_image(scene, decomp, run_ifd, pose, tile):
    args = [a if a not in scene else scene[a] for a in pose]
    d = scene["dir"]
    whole, tiled = d / f"whole-{tile}.npy", d / f"tiled-{tile}.npy"
    run_ifd("filter", scene["img"], "--decomp", decomp, *args, "-o", whole)
    p = run_ifd("filter", scene["img"], "--decomp", decomp, *args, "--tile", tile, "-v", "-o", tiled)
    assert "tiled:" in p.stderr, p.stderr
    n_tiles = int(p.stderr.split("tiled: ")[1].split()[0])
    assert n_tiles >= 4, p.stderr
    _close(tiled, whole)


def test_over_the_budget_goes_tiled_by_itself(scene, decomp, run_ifd):
    d = scene["dir"]
    whole, auto = d / "whole-auto.npy", d / "auto.npy"
    args = ["--angle-map", scene["angle"], "--scale", "2"]
    run_ifd("filter", scene["img"], "--decomp", decomp, *args, "-o", whole)
    p = run_ifd("filter", scene["img"], "--decomp", decomp, *args, "--memory-budget", "48", "-v", "-o", auto)
    assert "tiled:" in p.stderr, p.stderr
    _close(auto, whole)


def test_formats_that_cannot_stream_are_refused_naming_npy(scene, decomp, run_ifd):
    d = scene["dir"]
    p = run_ifd("filter", scene["img"], "--decomp", decomp, "--tile", "64", "-o", d / "out.png", check=False)
    assert p.returncode == 2 and ".npy" in p.stderr and "out.png" in p.stderr, p.stderr
    assert not (d / "out.png").exists()
    png = d / "img.png"
    run_ifd("convert", scene["img"], png)
    p = run_ifd("filter", png, "--decomp", decomp, "--memory-budget", "1", "-o", d / "o.npy", check=False)
    assert p.returncode == 2 and "more than the budget" in p.stderr and ".npy" in p.stderr, p.stderr
    assert not (d / "o.npy").exists()


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    """A 600x520 crop of the bundled photograph with noise: edges of every
    orientation, flat areas where the field is isotropic."""
    d = tmp_path_factory.mktemp("tiled-smooth")
    rgb = skimage.io.imread(TESTDATA / "astronaut.png")[..., :3].astype(np.float32) / 255
    rgb = rgb[:520, :600]
    rng = np.random.default_rng(3)
    rgb = np.clip(rgb + rng.normal(0, 0.03, rgb.shape), 0, 1).astype(np.float32)
    return {"dir": d, "img": save_npy(d / "photo.npy", rgb)}


@pytest.mark.parametrize(
    "args, tile",
    [
        # Tiles of 1 px are rounded up to twice the halo (the reach).
        (("--sigma", "4", "--mode", "per-pixel", "--strength", "0.8"), 1),
        (("--sigma", "4", "--mode", "dab"), 1),
        (("--sigma", "1.5", "--mode", "dab"), 100),  # direct kernels
    ],
    ids=["per-pixel", "dab", "direct"],
)
def test_smooth_tiles_equal_the_whole_image(photo, run_ifd, args, tile):
    d = photo["dir"]
    tag = "-".join(args).replace("-", "")
    whole, tiled = d / f"whole-{tag}.npy", d / f"tiled-{tag}.npy"
    wf, tf = d / f"wf-{tag}.npy", d / f"tf-{tag}.npy"
    run_ifd("smooth", photo["img"], *args, "--field", wf, "-o", whole)
    p = run_ifd("smooth", photo["img"], *args, "--tile", tile, "--field", tf, "-v", "-o", tiled)
    assert "tiled:" in p.stderr, p.stderr
    n_tiles = int(p.stderr.split("tiled: ")[1].split()[0])
    assert n_tiles >= 4, p.stderr
    _close(tiled, whole)
    # The field: angles of (near-)isotropic filters are arbitrary, so
    # compare the filters' covariances rather than the raw angle.
    def cov(path):
        f = np.load(path).astype(np.float64)
        t, sx, sy = np.radians(f[..., 0]), f[..., 1], f[..., 2]
        c, s = np.cos(t), np.sin(t)
        return np.stack([sx**2 * c * c + sy**2 * s * s, (sx**2 - sy**2) * c * s, sx**2 * s * s + sy**2 * c * c])

    a, b = cov(tf), cov(wf)
    assert np.abs(a - b).max() <= 1e-4 * np.abs(b).max()


def test_smooth_over_the_budget_goes_tiled_by_itself(photo, run_ifd):
    d = photo["dir"]
    whole, auto = d / "s-whole.npy", d / "s-auto.npy"
    args = ["--sigma", "3"]
    run_ifd("smooth", photo["img"], *args, "-o", whole)
    p = run_ifd("smooth", photo["img"], *args, "--memory-budget", "40", "-v", "-o", auto)
    assert "tiled:" in p.stderr, p.stderr
    _close(auto, whole)
    p = run_ifd("smooth", photo["img"], *args, "--memory-budget", "40", "-o", d / "s.png", check=False)
    assert p.returncode == 2 and ".npy" in p.stderr and "s.png" in p.stderr, p.stderr
    assert not (d / "s.png").exists()


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_an_interrupted_run_leaves_nothing(tmp_path, decomp, ifd_bin, sig):
    """Ctrl-C or SIGTERM while tiles stream: no output, no hidden temporary."""
    import signal
    import subprocess
    import time

    img = save_npy(tmp_path / "big.npy", np.random.default_rng(5).random((2000, 2000)))
    out = tmp_path / "out.npy"
    p = subprocess.Popen([str(ifd_bin), "filter", img, "--decomp", decomp, "--angle", "20",
                          "--tile", "128", "-o", out], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not any(f.name.startswith(".ifd-tmp-") for f in tmp_path.iterdir()):
        assert p.poll() is None, f"finished before it could be interrupted: {p.stderr.read()}"
        assert time.monotonic() < deadline
        time.sleep(0.02)
    p.send_signal(getattr(signal, sig))
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, (p.returncode, err)
    assert "unfinished output file(s) removed" in err, err
    assert sorted(f.name for f in tmp_path.iterdir()) == ["big.npy"]
