"""Reference checks of `ifd sphere` against pyshtools, scipy and ducc0.

Conventions (see crates/ifd-sphere docs): real SH in the Sloan graphics convention
= pyshtools ortho/real/csphase=-1, flat index l(l+1)+m; R = Rz(a) Ry(b) Rz(c),
g(w) = f(R^T w) = ducc0.sht.rotate_alm(alm, lmax, psi=c, theta=b, phi=a).
"""

import json
import os

# The reference libraries are imported outright: a missing one is an error
# (counted as a failure by scripts/test-all.sh), never a silent skip.
import ducc0
import numpy as np
import pyshtools as pysh
import pytest
import scipy.special as scipy_special


def real_to_alm(c: np.ndarray, lmax: int) -> np.ndarray:
    """Sloan real coefficients -> ducc0/healpy complex alm (m >= 0, index m(2L+1-m)/2 + l)."""
    alm = np.zeros((lmax + 1) * (lmax + 2) // 2, dtype=np.complex128)
    for m in range(lmax + 1):
        for l in range(m, lmax + 1):
            i = m * (2 * lmax + 1 - m) // 2 + l
            if m == 0:
                alm[i] = c[l * (l + 1)]
            else:
                alm[i] = (c[l * (l + 1) + m] - 1j * c[l * (l + 1) - m]) / np.sqrt(2)
    return alm


def alm_to_real(alm: np.ndarray, lmax: int) -> np.ndarray:
    c = np.zeros((lmax + 1) ** 2)
    for m in range(lmax + 1):
        for l in range(m, lmax + 1):
            a = alm[m * (2 * lmax + 1 - m) // 2 + l]
            if m == 0:
                c[l * (l + 1)] = a.real
            else:
                c[l * (l + 1) + m] = np.sqrt(2) * a.real
                c[l * (l + 1) - m] = -np.sqrt(2) * a.imag
    return c


def random_dirs(n, seed=0):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # include the poles and the equator
    d[0] = [0, 0, 1]
    d[1] = [0, 0, -1]
    d[2] = [1, 0, 0]
    return d


@pytest.mark.parametrize("lmax", [2, 20, 100])
def test_sh_values_match_pyshtools(run_ifd, tmp_path, lmax):
    dirs = random_dirs(12, seed=lmax)
    np.save(tmp_path / "dirs.npy", dirs)
    run_ifd("sphere", "eval", "--lmax", lmax, "--dirs", tmp_path / "dirs.npy", "-o", tmp_path / "y.npy")
    y = np.load(tmp_path / "y.npy")
    assert y.shape == (len(dirs), (lmax + 1) ** 2) and y.dtype == np.float64
    for k, (x, yy, z) in enumerate(dirs):
        theta, phi = np.arccos(np.clip(z, -1, 1)), np.arctan2(yy, x)
        ref = pysh.expand.spharm(lmax, theta, phi, normalization="ortho", kind="real", csphase=-1, degrees=False)
        want = np.zeros((lmax + 1) ** 2)
        for l in range(lmax + 1):
            want[l * (l + 1)] = ref[0, l, 0]
            for m in range(1, l + 1):
                want[l * (l + 1) + m] = ref[0, l, m]
                want[l * (l + 1) - m] = ref[1, l, m]
        np.testing.assert_allclose(y[k], want, rtol=0, atol=1e-10)


def test_sh_values_match_scipy_and_f32_path(run_ifd, tmp_path):
    lmax = 30
    dirs = random_dirs(8, seed=3)
    np.save(tmp_path / "dirs.npy", dirs)
    run_ifd("sphere", "eval", "--lmax", lmax, "--dirs", tmp_path / "dirs.npy", "-o", tmp_path / "y.npy")
    run_ifd("sphere", "eval", "--lmax", lmax, "--dirs", tmp_path / "dirs.npy", "--f32", "-o", tmp_path / "y32.npy")
    y, y32 = np.load(tmp_path / "y.npy"), np.load(tmp_path / "y32.npy")
    theta = np.arccos(np.clip(dirs[:, 2], -1, 1))
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            Y = scipy_special.sph_harm_y(l, abs(m), theta, phi)  # Condon-Shortley phase included
            want = Y.real if m == 0 else np.sqrt(2) * (Y.real if m > 0 else Y.imag)
            np.testing.assert_allclose(y[:, l * (l + 1) + m], want, atol=1e-10)
    assert np.abs(y32 - y).max() < 1e-4


@pytest.mark.parametrize("lmax", [1, 3, 8, 16, 32])
@pytest.mark.parametrize("method", ["zhf", "tailored", "reference"])
def test_rotation_matches_ducc0(run_ifd, tmp_path, lmax, method):
    rng = np.random.default_rng(lmax)
    c = rng.uniform(-1, 1, size=((lmax + 1) ** 2, 2))
    np.save(tmp_path / "c.npy", c)
    a, b, g = 0.7, -1.9, 2.4
    run_ifd("sphere", "rotate", tmp_path / "c.npy", "--zyz", f"{a},{b},{g}", "--method", method, "-o", tmp_path / "r.npy")
    got = np.load(tmp_path / "r.npy")
    for ch in range(2):
        alm = real_to_alm(c[:, ch], lmax)
        rot = ducc0.sht.rotate_alm(alm, lmax, g, b, a)
        want = alm_to_real(rot, lmax)
        np.testing.assert_allclose(got[:, ch], want, rtol=0, atol=1e-10)


def test_equirect_analysis_matches_ducc0(run_ifd, tmp_path):
    """Same quadrature (exact pixel solid angles, pixel centres) via ducc0's adjoint SHT."""
    H, W, L = 96, 192, 40
    rng = np.random.default_rng(1)
    img = rng.random((H, W, 3)).astype(np.float32)
    np.save(tmp_path / "map.npy", img)
    out = json.loads(run_ifd("sphere", "sh", "--json", tmp_path / "map.npy", "--lmax", L, "--projection", "centre",
                             "-o", tmp_path / "c.npy").stdout)
    assert out["negatives"] == 0 and out["projection"] == "centre"
    c = np.load(tmp_path / "c.npy")
    assert c.shape == ((L + 1) ** 2, 3)
    v = np.arange(H)
    dA = (2 * np.pi / W) * (np.cos(np.pi * v / H) - np.cos(np.pi * (v + 1) / H))
    for ch in range(3):
        mp = (img[:, :, ch].astype(np.float64) * dA[:, None])[None]
        alm = ducc0.sht.experimental.adjoint_synthesis_2d(map=mp, spin=0, lmax=L, geometry="F1", phi0=np.pi / W)[0]
        np.testing.assert_allclose(c[:, ch], alm_to_real(alm, L), rtol=0, atol=1e-10)


def real_sh(lmax: int, z: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Real SH (Sloan's convention, flat index l(l+1)+m) at (cos theta, phi), from scipy."""
    theta = np.arccos(np.clip(z, -1, 1))
    out = np.empty(z.shape + ((lmax + 1) ** 2,))
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            Y = scipy_special.sph_harm_y(l, abs(m), theta, phi)
            out[..., l * (l + 1) + m] = Y.real if m == 0 else np.sqrt(2) * (Y.real if m > 0 else Y.imag)
    return out


def test_texel_projection_integrates_each_texel(run_ifd, tmp_path):
    """The default projection of a 2:1 map is the exact integral of the map read
    as piecewise constant over its texels (what `ifd render`'s oracle and the IBL
    baker integrate): checked against Gauss-Legendre quadrature over every texel
    in (cos theta, phi), written here with scipy's SH. The pixel-centre rule
    misses it by far more than the tolerance, so the check cannot pass by
    accident; a cube strip has no texel-exact projection and says so."""
    H, W, L = 8, 16, 6
    rng = np.random.default_rng(11)
    img = rng.random((H, W)).astype(np.float32)
    np.save(tmp_path / "map.npy", img)
    rep = json.loads(run_ifd("sphere", "sh", tmp_path / "map.npy", "--lmax", L, "-o", tmp_path / "t.npy",
                             "--json").stdout)
    assert rep["projection"] == "texel"
    run_ifd("sphere", "sh", tmp_path / "map.npy", "--lmax", L, "--projection", "centre", "-o", tmp_path / "c.npy")
    texel, centre = np.load(tmp_path / "t.npy")[:, 0], np.load(tmp_path / "c.npy")[:, 0]
    x, w = np.polynomial.legendre.leggauss(10)
    want = np.zeros((L + 1) ** 2)
    for v in range(H):
        z0, z1 = np.cos(np.pi * (v + 1) / H), np.cos(np.pi * v / H)
        zs, wz = 0.5 * (z1 - z0) * x + 0.5 * (z1 + z0), 0.5 * (z1 - z0) * w
        for u in range(W):
            p0, p1 = 2 * np.pi * u / W, 2 * np.pi * (u + 1) / W
            ps, wp = 0.5 * (p1 - p0) * x + 0.5 * (p1 + p0), 0.5 * (p1 - p0) * w
            Z, P = np.meshgrid(zs, ps, indexing="ij")
            Y = real_sh(L, Z, P)
            want += float(img[v, u]) * np.einsum("ij,ijk->k", np.outer(wz, wp), Y)
    tol = 1e-5 * np.abs(want).max()
    assert np.abs(texel - want).max() < tol, np.abs(texel - want).max()
    assert np.abs(centre - want).max() > 10 * tol
    # the Python module projects the same way
    assert np.array_equal(np.asarray(ifd_sh(img, L)).reshape(-1), texel)
    strip = np.ones((4, 24), dtype=np.float32)
    np.save(tmp_path / "strip.npy", strip)
    p = run_ifd("sphere", "sh", tmp_path / "strip.npy", "--lmax", 2, "--projection", "texel", "-o", tmp_path / "s.npy",
                check=False)
    assert p.returncode == 2 and "texel-exact cube projection is not implemented" in p.stderr, p.stderr
    assert not (tmp_path / "s.npy").exists()


def ifd_sh(img, lmax):
    import ifd

    return ifd.sphere.sh(img, lmax)


def test_synthesis_matches_ducc0(run_ifd, tmp_path):
    H, W, L = 64, 128, 24
    rng = np.random.default_rng(2)
    img = rng.random((H, W, 1)).astype(np.float32)
    np.save(tmp_path / "map.npy", img)
    run_ifd("sphere", "sh", tmp_path / "map.npy", "--lmax", L, "-o", tmp_path / "c.npy",
            "--reconstruct", tmp_path / "rec.npy")
    c = np.load(tmp_path / "c.npy")[:, 0]
    rec = np.load(tmp_path / "rec.npy").reshape(H, W)
    alm = real_to_alm(c, L)
    want = ducc0.sht.experimental.synthesis_2d(alm=alm[None], spin=0, lmax=L, geometry="F1", ntheta=H, nphi=W,
                                               phi0=np.pi / W)[0]
    np.testing.assert_allclose(rec, want, atol=1e-5)  # rec is stored as float32


def test_bundled_envmap_negatives_are_clamped_and_counted(run_ifd, tmp_path):
    from conftest import TESTDATA

    out = run_ifd("sphere", "sh", TESTDATA / "forest_dwab.exr", "--lmax", 8, "-o", tmp_path / "c.npy", "--json")
    info = json.loads(out.stdout)
    assert info["negatives"] > 0 and "clamped" in out.stderr
    c = np.load(tmp_path / "c.npy")
    assert c.shape == (81, info["channels"]) and c[0].min() > 0


def test_bad_inputs_fail_cleanly(run_ifd, tmp_path):
    np.save(tmp_path / "sq.npy", np.ones((16, 16, 3), np.float32))
    p = run_ifd("sphere", "sh", tmp_path / "sq.npy", "--lmax", 4, "-o", tmp_path / "c.npy", check=False)
    assert p.returncode == 2 and "2:1" in p.stderr and "6:1" in p.stderr and "16x16" in p.stderr, p.stderr
    nan = np.ones((8, 16), np.float32)
    nan[3, 4] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    p = run_ifd("sphere", "sh", tmp_path / "nan.npy", "--lmax", 4, "-o", tmp_path / "c.npy", check=False)
    assert p.returncode == 2 and ("non-finite" in p.stderr or "NaN" in p.stderr)
    # a valid 2:1 map, so that the degree is what is refused
    np.save(tmp_path / "eq.npy", np.ones((8, 16, 3), np.float32))
    p = run_ifd("sphere", "sh", tmp_path / "eq.npy", "--lmax", 5000, "-o", tmp_path / "c.npy", check=False)
    assert p.returncode == 2 and "--lmax 5000: at most L = 1000 is supported" in p.stderr, p.stderr
    p = run_ifd("sphere", "decompose", "gauss:s=0.3", "--lmax", 5000, "-o", tmp_path / "d.json", check=False)
    assert p.returncode == 2 and "at most L = 40" in p.stderr and "--lmax 5000" in p.stderr, p.stderr
    np.save(tmp_path / "c.npy", np.ones((5, 1)))
    p = run_ifd("sphere", "rotate", tmp_path / "c.npy", "--zyz", "0,1,0", "-o", tmp_path / "r.npy", check=False)
    assert p.returncode == 2 and "(L+1)^2" in p.stderr
    bad = np.ones((9, 3))
    bad[4, 2] = np.nan
    np.save(tmp_path / "bad.sh.npy", bad)
    for args in (("rotate", tmp_path / "bad.sh.npy", "--zyz", "0,1,0", "-o", tmp_path / "r.npy"),
                 ("decompose", tmp_path / "bad.sh.npy", "--lmax", 2, "-o", tmp_path / "d.json")):
        p = run_ifd("sphere", *args, check=False)
        assert p.returncode == 2 and "1 non-finite SH coefficient(s)" in p.stderr, p.stderr
        assert "row 4, column 2" in p.stderr and "bad.sh.npy" in p.stderr


def test_decompose_and_condition(run_ifd, run_paper, tmp_path):
    out = json.loads(run_ifd("sphere", "decompose", "--json", "aniso-gauss:s1=0.3,s2=0.05", "--lmax", 8,
                             "--directions", "shared", "-o", tmp_path / "d.json").stdout)
    assert out["lobes"] == 81 and out["directions"] == 17 and out["channels"] == 1
    assert out["condition_number"] < 1e4
    d = json.loads((tmp_path / "d.json").read_text())
    assert d["profile"] == "zonal" and d["directions"]["sharing"] == "shared"
    out = json.loads(run_ifd("sphere", "decompose", "--json", "vmf:kappa=50", "--lmax", 6, "--profile", "gauss",
                             "-o", tmp_path / "g.json").stdout)
    assert out["profile"] == "gauss"
    p = run_ifd("sphere", "decompose", "phong:s=-3", "--lmax", 4, "-o", tmp_path / "x.json", check=False)
    assert p.returncode == 2 and "phong:s=-3" in p.stderr
    rows = json.loads(run_paper("isd-condition", "--json", "--lmax", 6, "--plot", tmp_path / "c.png",
                              "--csv", tmp_path / "c.csv").stdout)
    assert (tmp_path / "c.png").stat().st_size > 1000
    csv = (tmp_path / "c.csv").read_text().splitlines()
    assert csv[0] == "L,profile,sharing,cond,singular" and len(csv) == 1 + 6 * 2 * 6
    by = {(r["profile"], r["sharing"]): r["cond"] for r in rows}
    # ISD Fig. 13: sharing matters little for Legendre, a lot for Gauss
    assert by[("gauss", "shared")][-1] > 10 * by[("gauss", "per-band")][-1]
    assert by[("legendre", "shared")][-1] < 100 * by[("legendre", "per-band")][-1]


def real_sh_matrix(lmax, dirs):
    """(N, (L+1)^2) real SH (Sloan convention) from scipy, independent of ifd."""
    theta = np.arccos(np.clip(dirs[:, 2], -1, 1))
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    out = np.zeros((len(dirs), (lmax + 1) ** 2))
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            Y = scipy_special.sph_harm_y(l, abs(m), theta, phi)
            out[:, l * (l + 1) + m] = Y.real if m == 0 else np.sqrt(2) * (Y.real if m > 0 else Y.imag)
    return out


def kernel_fn(spec):
    """The closed-form kernels of `ifd sphere decompose`, written again here."""
    name, args = spec.split(":")
    a = {k: float(v) for k, v in (kv.split("=") for kv in args.split(","))}

    def k(d):
        t = np.clip(d[:, 2], -1, 1)
        if name == "vmf":
            return np.exp(a["kappa"] * (t - 1))
        th = np.arccos(t)
        r = np.hypot(d[:, 0], d[:, 1])
        c = np.where(r > 0, d[:, 0] / np.where(r > 0, r, 1), 1.0)
        s = np.where(r > 0, d[:, 1] / np.where(r > 0, r, 1), 0.0)
        x, y = th * c, th * s
        return np.exp(-x**2 / (2 * a["s1"] ** 2) - y**2 / (2 * a["s2"] ** 2))

    return k


def project(k, lmax, n=64):
    """SH coefficients of k by Gauss-Legendre x uniform-azimuth quadrature."""
    z, wz = np.polynomial.legendre.leggauss(n)
    p = (np.arange(2 * n) + 0.5) * np.pi / n
    Z, P = np.meshgrid(z, p, indexing="ij")
    s = np.sqrt(1 - Z**2)
    d = np.stack([s * np.cos(P), s * np.sin(P), Z], -1).reshape(-1, 3)
    w = (wz[:, None] * np.full(2 * n, np.pi / n)[None]).reshape(-1)
    return real_sh_matrix(lmax, d).T @ (w * k(d))


def equirect_dirs(H, W):
    v, u = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    t, p = np.pi * (v + 0.5) / H, 2 * np.pi * (u + 0.5) / W
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    dA = (2 * np.pi / W) * (np.cos(np.pi * np.arange(H) / H) - np.cos(np.pi * (np.arange(H) + 1) / H))
    return d.reshape(-1, 3), np.repeat(dA, W), t.reshape(-1), p.reshape(-1)


@pytest.mark.parametrize("spec,lmax,directions", [("vmf:kappa=10", 16, "fibonacci"),
                                                   ("aniso-gauss:s1=0.6,s2=0.25", 10, "shared")])
def test_sphere_filter_matches_quadrature(run_ifd, tmp_path, spec, lmax, directions):
    """`ifd sphere filter --projection centre` = sum over input texels of E(w') k_L(R(w)^T w') dA'
    (texel centres w'), R(w) = Rz(phi) Ry(theta). The default texel projection differs from it only in
    the analysis, checked by test_texel_projection_integrates_each_texel."""
    H, W = 24, 48
    rng = np.random.default_rng(5)
    env = rng.random((H, W, 2)).astype(np.float32) ** 4  # a few bright texels
    np.save(tmp_path / "env.npy", env)
    run_ifd("sphere", "decompose", spec, "--lmax", lmax, "--directions", directions, "-o", tmp_path / "d.json")
    out = json.loads(run_ifd("sphere", "filter", "--json", tmp_path / "env.npy", "--decomp", tmp_path / "d.json",
                             "--raw", "--size", "32x16", "--projection", "centre", "-o", tmp_path / "f.npy").stdout)
    assert out["layout"] == "equirect" and out["scale"] == 1.0 and out["projection"] == "centre"
    got = np.load(tmp_path / "f.npy").astype(np.float64)
    assert got.shape == (16, 32, 2)
    k = kernel_fn(spec)
    kc = project(k, lmax)
    src, dA, _, _ = equirect_dirs(H, W)
    E = env.reshape(-1, 2).astype(np.float64)
    dst, _, t, p = equirect_dirs(16, 32)
    pick = rng.choice(len(dst), 40, replace=False)
    band, true = [], []
    for i in pick:
        ct, st, cp, sp = np.cos(t[i]), np.sin(t[i]), np.cos(p[i]), np.sin(p[i])
        R = np.array([[cp, -sp, 0], [sp, cp, 0], [0, 0, 1]]) @ np.array([[ct, 0, st], [0, 1, 0], [-st, 0, ct]])
        local = src @ R  # rows are R^T w'
        kl = real_sh_matrix(lmax, local) @ kc
        band.append((kl * dA) @ E)
        true.append((k(local) * dA) @ E)
    want = np.array(band)
    got_px = got.reshape(-1, 2)[pick]
    scale = np.abs(want).max()
    # ifd writes float32: 1e-6 of the maximum is float32's resolution plus the solve
    assert np.abs(got_px - want).max() <= 1e-6 * scale, np.abs(got_px - want).max() / scale
    if spec.startswith("vmf"):
        # the kernel's energy beyond L = 16 is below 1e-8: the true kernel agrees as well
        energy = np.sum(kc**2)
        tail = project(k, 32)
        assert np.sum(tail[(lmax + 1) ** 2:] ** 2) / energy < 1e-8
        assert np.abs(got_px - np.array(true)).max() <= 1e-5 * scale


def test_sphere_filter_normalises_and_refuses_bad_input(run_ifd, tmp_path):
    rng = np.random.default_rng(7)
    np.save(tmp_path / "env.npy", rng.random((16, 32, 3)).astype(np.float32))
    run_ifd("sphere", "decompose", "vmf:kappa=10", "--lmax", 16, "-o", tmp_path / "d.json")
    raw = json.loads(run_ifd("sphere", "filter", "--json", tmp_path / "env.npy", "--decomp", tmp_path / "d.json",
                             "--raw", "--size", "48x8", "-o", tmp_path / "raw.npy").stdout)
    out = json.loads(run_ifd("sphere", "filter", "--json", tmp_path / "env.npy", "--decomp", tmp_path / "d.json",
                             "--size", "48x8", "-o", tmp_path / "c.npy").stdout)
    assert out["layout"] == "cubemap-strip" and raw["scale"] == 1.0
    # int exp(kappa (t - 1)) dw = 2 pi (1 - exp(-2 kappa)) / kappa, and the energy beyond L = 16 is < 1e-8
    integral = 2 * np.pi * (1 - np.exp(-20.0)) / 10.0
    assert abs(out["kernel_integral"] - integral) < 1e-7 * integral
    assert abs(out["scale"] * integral - 1) < 1e-7
    c, r = np.load(tmp_path / "c.npy"), np.load(tmp_path / "raw.npy")
    assert c.shape == (8, 48, 3)
    np.testing.assert_allclose(c, r / integral, rtol=1e-6)
    np.save(tmp_path / "one.npy", np.ones((16, 32, 3), np.float32))
    d = json.loads((tmp_path / "d.json").read_text())
    d["weights"]["data"] = d["weights"]["data"][:-1]
    (tmp_path / "bad.json").write_text(json.dumps(d))
    p = run_ifd("sphere", "filter", tmp_path / "one.npy", "--decomp", tmp_path / "bad.json",
                "-o", tmp_path / "x.exr", check=False)
    assert p.returncode == 2 and "bad.json" in p.stderr and "weights" in p.stderr, p.stderr
    assert not (tmp_path / "x.exr").exists()
    p = run_ifd("sphere", "filter", tmp_path / "one.npy", "--decomp", tmp_path / "d.json", "--size", "30x20",
                "-o", tmp_path / "x.exr", check=False)
    assert p.returncode == 2 and "--size 30x20" in p.stderr and "6:1" in p.stderr, p.stderr
    d = json.loads((tmp_path / "d.json").read_text())
    d["beta"][0] = 2.0  # not the zonal profile's beta
    (tmp_path / "beta.json").write_text(json.dumps(d))
    p = run_ifd("sphere", "filter", tmp_path / "one.npy", "--decomp", tmp_path / "beta.json",
                "-o", tmp_path / "x.exr", check=False)
    assert p.returncode == 2 and "beta[0]" in p.stderr and "zonal" in p.stderr, p.stderr
    (tmp_path / "trunc.json").write_text((tmp_path / "d.json").read_text()[:200])
    p = run_ifd("sphere", "filter", tmp_path / "one.npy", "--decomp", tmp_path / "trunc.json",
                "-o", tmp_path / "x.exr", check=False)
    assert p.returncode == 2 and "trunc.json" in p.stderr and "panicked" not in p.stderr, p.stderr


def ggx_albedo_numpy(alpha, theta_o, n=600):
    """Directional albedo of GGX (glTF, height-correlated Smith, F = 1) by a midpoint rule."""
    t = (np.arange(n) + 0.5) * (np.pi / 2) / n
    p = (np.arange(4 * n) + 0.5) * 2 * np.pi / (4 * n)
    T, P = np.meshgrid(t, p, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    wo = np.array([np.sin(theta_o), 0.0, np.cos(theta_o)])
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    a2 = alpha * alpha
    D = a2 / (np.pi * (h[..., 2] ** 2 * (a2 - 1) + 1) ** 2)
    nl, nv = wi[..., 2], wo[2]
    V = 0.5 / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))
    f = D * V * nl * np.sin(T)
    return f.sum() * (np.pi / 2 / n) * (2 * np.pi / (4 * n))


def test_sphere_brdf_tables(run_ifd, tmp_path):
    out = json.loads(run_ifd("sphere", "brdf", "--json", "lambert", "--lmax", 6, "-o", tmp_path / "l.lobes").stdout)
    assert abs(out["albedo_min"] - 1) < 1e-6 and abs(out["albedo_max"] - 1) < 1e-6
    # isotropic: L + 1 lobes in the plane of the view (the slice is even in y there)
    assert out["lobes"] == 7 and out["lobe_layout"] == "in-plane"
    assert out["isotropic"] and out["phi_entries"] == 1
    # a table of two entries: GGX's directional albedo at the two entry angles (pi/8, 3pi/8)
    out = json.loads(run_ifd("sphere", "brdf", "--json", "ggx:alpha=0.3", "--lmax", 8, "--theta-entries", 2,
                             "-o", tmp_path / "g.lobes").stdout)
    want = [ggx_albedo_numpy(0.3, np.pi / 8), ggx_albedo_numpy(0.3, 3 * np.pi / 8)]
    got = sorted([out["albedo_min"], out["albedo_max"]])
    np.testing.assert_allclose(got, sorted(want), rtol=2e-4)
    data = (tmp_path / "g.lobes").read_bytes()
    assert data[:8] == b"IFDLOBES"
    hl = int.from_bytes(data[8:12], "little")
    header = json.loads(data[12:12 + hl])
    assert header["brdf"] == "ggx:alpha=0.3" and header["l_max"] == 8 and header["version"] == 2
    assert header["lobes"]["kind"] == "in-plane" and len(header["lobes"]["angles"]) == 9
    # 2 entries of (L + 1)(L + 2) / 2 = 45 f32 weights
    assert out["weight_bytes"] == 2 * 45 * 4
    assert len(data) == 12 + hl + out["weight_bytes"]
    out = json.loads(run_ifd("sphere", "brdf", "--json", "ggx:ax=0.3,ay=0.6", "--lmax", 3, "--theta-entries", 4,
                             "--phi-entries", 8, "-o", tmp_path / "a.lobes").stdout)
    assert not out["isotropic"] and out["weight_bytes"] == 4 * 8 * 16 * 4
    assert out["lobes"] == 7 and out["lobe_layout"] == "shared"


@pytest.mark.parametrize("args,needle", [
    (("ggx:alpha=-0.3", "--lmax", 4), "outside"),
    (("ggx:alpha=nan", "--lmax", 4), "not"),
    (("velvet", "--lmax", 4), "unknown BRDF"),
    (("phong", "--lmax", 4), "missing s="),
    (("ggx:alpha=0.3", "--lmax", 500), "L <= 100"),
    (("merl:/nonexistent.binary", "--lmax", 4), "nonexistent.binary"),
])
def test_sphere_brdf_refuses_bad_input(run_ifd, tmp_path, args, needle):
    p = run_ifd("sphere", "brdf", *args, "-o", tmp_path / "t.lobes", check=False)
    assert p.returncode == 2 and needle in p.stderr and "panicked" not in p.stderr, p.stderr
    assert not (tmp_path / "t.lobes").exists()


def test_sphere_brdf_refuses_truncated_merl_and_missing_folders(run_ifd, tmp_path):
    (tmp_path / "short.binary").write_bytes(b"\x5a\x00\x00\x00" * 3 + b"\x00" * 64)
    p = run_ifd("sphere", "brdf", f"merl:{tmp_path / 'short.binary'}", "--lmax", 4, "-o", tmp_path / "t.lobes",
                check=False)
    assert p.returncode == 2 and "short.binary" in p.stderr and "34992012" in p.stderr, p.stderr
    p = run_ifd("sphere", "brdf", "lambert", "--lmax", 4, "-o", tmp_path / "no" / "t.lobes", check=False)
    assert p.returncode == 2 and "does not exist" in p.stderr, p.stderr


def test_render_matches_numpy_brute_force(run_ifd, tmp_path):
    """A few pixels of `ifd render` (quadrature and isd) against a numpy brute force of the
    shading integral over the same piecewise-constant environment, GGX written out again."""
    rng = np.random.default_rng(11)
    env = (rng.random((8, 16, 3)) ** 3 * 4).astype(np.float32)
    np.save(tmp_path / "env.npy", env)
    common = ["--env", tmp_path / "env.npy", "--brdf", "ggx:alpha=0.4", "--size", "24x24",
              "--eye", "0,-4,1", "--fov", "35", "--env-rotate", "20", "--no-background"]
    out = json.loads(run_ifd("render", "--json", *common, "--method", "quadrature", "--mask", tmp_path / "m.npy",
                             "-o", tmp_path / "q.npy").stdout)
    assert out["env_size"] == [16, 8] and out["object_pixels"] > 100
    run_ifd("render", *common, "--method", "isd", "--lmax", 20, "-o", tmp_path / "i.npy")
    q, isd = np.load(tmp_path / "q.npy"), np.load(tmp_path / "i.npy")
    mask = np.load(tmp_path / "m.npy").reshape(24, 24) > 0.5
    # camera: z up, vertical fov, pixel centres
    eye, target, up = np.array([0, -4.0, 1]), np.zeros(3), np.array([0, 0, 1.0])
    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, up); r /= np.linalg.norm(r)
    u = np.cross(r, f)
    th = np.tan(np.radians(35) / 2)
    # dense sub-samples of every texel (midpoint, 40 x 40 per texel)
    k, H, W = 40, 8, 16
    tt = (np.arange(H * k) + 0.5) * np.pi / (H * k)
    pp = (np.arange(W * k) + 0.5) * 2 * np.pi / (W * k)
    T, P = np.meshgrid(tt, pp, indexing="ij")
    t0, t1 = T - np.pi / (2 * H * k), T + np.pi / (2 * H * k)
    sa = (np.cos(t0) - np.cos(t1)) * 2 * np.pi / (W * k)
    Pr = P + np.radians(20)  # the map rotated by 20 degrees about z
    dirs = np.stack([np.sin(T) * np.cos(Pr), np.sin(T) * np.sin(Pr), np.cos(T)], -1).reshape(-1, 3)
    E = np.repeat(np.repeat(env.astype(np.float64), k, 0), k, 1).reshape(-1, 3)
    sa = sa.reshape(-1)
    a2 = 0.4**2
    checked = 0
    for (py, px) in [(12, 12), (8, 14), (15, 9), (12, 5), (6, 12)]:
        if not mask[py, px]:
            continue
        sx = (2 * (px + 0.5) / 24 - 1) * th
        sy = (1 - 2 * (py + 0.5) / 24) * th
        d = f + sx * r + sy * u; d /= np.linalg.norm(d)
        b = eye @ d; c = eye @ eye - 1
        t = -b - np.sqrt(b * b - c)
        n = eye + t * d  # unit sphere: the point is the normal
        wo = -d
        wi = dirs
        nl, nv = wi @ n, wo @ n
        h = wi + wo; h /= np.linalg.norm(h, axis=1, keepdims=True)
        nh = h @ n
        D = a2 / (np.pi * (nh**2 * (a2 - 1) + 1) ** 2)
        V = 0.5 / (nl * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(nl * nl * (1 - a2) + a2))
        kk = np.where(nl > 0, D * V * nl, 0.0) if nv > 0 else np.zeros_like(nl)
        want = (kk * sa) @ E
        np.testing.assert_allclose(q[py, px], want, rtol=2e-3)  # the brute force's own midpoint error
        np.testing.assert_allclose(isd[py, px], want, rtol=2e-2)
        checked += 1
    assert checked >= 4


@pytest.mark.parametrize("args,needle", [
    (("--brdf", "ggx:alpha=0.3"), "--lmax"),
    (("--brdf", "lambert", "--lmax", 4, "--eye", "0,-4,0", "--target", "0,-8,0"), "sees no object"),
    (("--brdf", "lambert", "--lmax", 4, "--env-size", "30x15"), "--env-size"),
    (("--brdf", "lambert", "--lmax", 4, "--scene", "teapot"), "--scene"),
    (("--brdf", "lambert", "--lmax", 4, "--fov", "0"), "--fov"),
    (("--brdf", "velvet", "--lmax", 4), "unknown BRDF"),
    (("--brdf", "lambert", "--lmax", 4, "--method", "path-tracing"), "--method"),
    (("--brdf", "lambert", "--method", "mc", "--spp", 0), "--spp"),
    (("--brdf", "lambert", "--lmax", 4, "--stderr", "x.exr"), "--stderr"),
    (("--brdf", "lambert", "--lmax", 500), "L <= 100"),
    (("--brdf", "lambert", "--lmax", 4, "--size", "0x8"), "--size"),
    (("--brdf", "lambert", "--lmax", 4, "--eye", "1,nan,2"), "--eye"),
])
def test_render_refuses_bad_input(run_ifd, tmp_path, args, needle):
    np.save(tmp_path / "square.npy", np.ones((8, 8, 3), np.float32))
    p = run_ifd("render", "--env", tmp_path / "square.npy", "--brdf", "lambert", "--lmax", 2, "--size", "8x8",
                "-o", tmp_path / "o.exr", check=False)
    assert p.returncode == 2 and "2:1" in p.stderr, p.stderr
    np.save(tmp_path / "env.npy", np.ones((8, 16, 3), np.float32))
    p = run_ifd("render", "--env", tmp_path / "env.npy", "--size", "8x8", *args, "-o", tmp_path / "o.exr",
                check=False)
    assert p.returncode == 2 and needle in p.stderr and "panicked" not in p.stderr, p.stderr
    assert not (tmp_path / "o.exr").exists()


def test_render_obj_meshes_and_their_bad_input(run_ifd, tmp_path):
    np.save(tmp_path / "env.npy", np.ones((8, 16, 3), np.float32))
    # a tetrahedron without normals or texture coordinates, y-up
    (tmp_path / "tet.obj").write_text("v 0 1 0\nv -1 -1 1\nv 1 -1 1\nv 0 -1 -1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n")
    out = json.loads(run_ifd("render", "--json", "--env", tmp_path / "env.npy", "--scene", tmp_path / "tet.obj",
                             "--brdf", "lambert", "--lmax", 4, "--size", "32x32", "-o", tmp_path / "t.npy").stdout)
    assert out["object_pixels"] > 50
    img = np.load(tmp_path / "t.npy")
    # a white Lambertian object in a uniform unit light is 1 wherever it is seen
    lit = img[img.sum(-1) > 0]
    np.testing.assert_allclose(lit, 1.0, atol=1e-3)
    for args, needle in [
        (("--scene", tmp_path / "tet.obj", "--brdf", "ggx:ax=0.1,ay=0.4", "--lmax", 4), "texture coordinates"),
        (("--scene", tmp_path / "missing.obj", "--brdf", "lambert", "--lmax", 4), "missing.obj"),
        (("--scene", tmp_path / "tet.obj", "--obj-up", "x", "--brdf", "lambert", "--lmax", 4), "--obj-up"),
    ]:
        p = run_ifd("render", "--env", tmp_path / "env.npy", "--size", "8x8", *args, "-o", tmp_path / "o.exr",
                    check=False)
        assert p.returncode == 2 and needle in p.stderr and "panicked" not in p.stderr, p.stderr


def test_render_texture_maps(run_ifd, tmp_path):
    import cv2
    np.save(tmp_path / "env.npy", np.ones((8, 16, 3), np.float32))
    # an 8-bit albedo map (sRGB-encoded: 128 -> 0.2158 linear), constant
    cv2.imwrite(str(tmp_path / "albedo.png"), np.full((4, 8, 3), 128, np.uint8))
    np.save(tmp_path / "rough.npy", np.linspace(0.5, 0.9, 32, dtype=np.float32).reshape(4, 8))
    common = ["render", "--env", tmp_path / "env.npy", "--size", "24x24", "--no-background"]
    run_ifd(*common, "--brdf", "lambert", "--lmax", 4, "--albedo-map", tmp_path / "albedo.png",
            "-o", tmp_path / "a.npy")
    a = np.load(tmp_path / "a.npy")
    lit = a[a.sum(-1) > 0]
    srgb = 128 / 255
    want = ((srgb + 0.055) / 1.055) ** 2.4  # white furnace times the decoded albedo
    np.testing.assert_allclose(lit, want, rtol=1e-3)
    out = json.loads(run_ifd(*common, "--json", "--brdf", "ggx:alpha=0.5", "--lmax", 8, "--roughness-map",
                             tmp_path / "rough.npy", "--roughness-tables", 3, "-o", tmp_path / "r.npy").stdout)
    assert out["object_pixels"] > 100
    p = run_ifd(*common, "--brdf", "phong:s=8", "--lmax", 4, "--roughness-map", tmp_path / "rough.npy",
                "-o", tmp_path / "x.npy", check=False)
    assert p.returncode == 2 and "roughness" in p.stderr and "GGX, Ward or glTF" in p.stderr, p.stderr
    bad = np.full((4, 8), np.nan, np.float32)
    np.save(tmp_path / "nan.npy", bad)
    p = run_ifd(*common, "--brdf", "ggx:alpha=0.5", "--lmax", 4, "--roughness-map", tmp_path / "nan.npy",
                "-o", tmp_path / "x.npy", check=False)
    assert p.returncode == 2 and "nan.npy" in p.stderr, p.stderr


def test_render_refuses_a_table_of_another_degree_or_brdf(run_ifd, tmp_path):
    np.save(tmp_path / "env.npy", np.ones((8, 16, 3), np.float32))
    run_ifd("sphere", "brdf", "ggx:alpha=0.4", "--lmax", 6, "--theta-entries", 4, "-o", tmp_path / "t.lobes")
    common = ["render", "--env", tmp_path / "env.npy", "--size", "8x8", "--table", tmp_path / "t.lobes"]
    p = run_ifd(*common, "--brdf", "ggx:alpha=0.4", "--lmax", 8, "-o", tmp_path / "o.exr", check=False)
    assert p.returncode == 2 and "L = 6, not L = 8" in p.stderr and "t.lobes" in p.stderr, p.stderr
    p = run_ifd(*common, "--brdf", "ggx:alpha=0.2", "--lmax", 6, "-o", tmp_path / "o.exr", check=False)
    assert p.returncode == 2 and "ggx:alpha=0.4" in p.stderr, p.stderr
    (tmp_path / "junk.lobes").write_bytes(b"IFDLOBES\xff\xff\xff\x7f{")
    p = run_ifd("render", "--env", tmp_path / "env.npy", "--size", "8x8", "--table", tmp_path / "junk.lobes",
                "--brdf", "ggx:alpha=0.4", "--lmax", 6, "-o", tmp_path / "o.exr", check=False)
    assert p.returncode == 2 and "junk.lobes" in p.stderr and "truncated" in p.stderr, p.stderr


def test_render_gpu_matches_cpu(run_ifd, tmp_path):
    """`ifd render --gpu` (the WGSL kernels, f32) against the CPU path (f64) on the same views:
    both variants, a closed-form and an anisotropic table BRDF, a grey environment, and the
    roughness and albedo maps of a spatially varying BRDF, within 1e-3 of the object's maximum."""
    rng = np.random.default_rng(5)
    env = (rng.random((16, 32, 3)) ** 4 * 6).astype(np.float32)
    np.save(tmp_path / "env.npy", env)
    np.save(tmp_path / "grey.npy", env[..., :1])
    np.save(tmp_path / "rough.npy", np.linspace(0.3, 0.8, 64, dtype=np.float32).reshape(8, 8))
    np.save(tmp_path / "albedo.npy", rng.random((8, 8, 3)).astype(np.float32))
    cases = [
        ("env.npy", ["--brdf", "phong:s=40", "--lmax", 10, "--method", "isd-maps"]),
        ("env.npy", ["--brdf", "ggx:ax=0.2,ay=0.45", "--lmax", 6, "--scene", "torus"]),
        ("grey.npy", ["--brdf", "ward:alpha=0.3", "--lmax", 8, "--method", "isd-maps"]),
        ("env.npy", ["--brdf", "ggx:alpha=0.5", "--lmax", 6, "--roughness-map", tmp_path / "rough.npy",
                     "--roughness-tables", 3, "--albedo-map", tmp_path / "albedo.npy"]),
    ]
    for env_name, args in cases:
        common = ["render", "--env", tmp_path / env_name, "--size", "32x24", *args, "--mask", tmp_path / "m.npy"]
        run_ifd(*common, "-o", tmp_path / "cpu.npy")
        p = run_ifd(*common, "--gpu", "--json", "-o", tmp_path / "gpu.npy", check=False)
        if p.returncode != 0 and "no GPU adapter" in p.stderr and os.environ.get("IFD_GPU_TESTS") == "skip":
            pytest.skip("no GPU adapter (IFD_GPU_TESTS=skip)")
        assert p.returncode == 0, p.stderr
        report = json.loads(p.stdout)["gpu"]
        assert report["frames"] == 1 and report["adapter"], report
        cpu, gpu = np.load(tmp_path / "cpu.npy"), np.load(tmp_path / "gpu.npy")
        mask = np.load(tmp_path / "m.npy") > 0.5
        assert cpu.shape == gpu.shape and mask.sum() > 100, (cpu.shape, gpu.shape)
        obj = mask[..., 0] if mask.ndim == 3 else mask
        err = np.abs(gpu - cpu)[obj].max() / np.abs(cpu[obj]).max()
        assert err <= 1e-3, (args, err)
        np.testing.assert_array_equal(gpu[~obj], cpu[~obj])  # the background, copied through
    p = run_ifd("render", "--env", tmp_path / "env.npy", "--brdf", "lambert", "--method", "mc", "--gpu",
                "-o", tmp_path / "x.npy", check=False)
    assert p.returncode == 2 and "--gpu shades --method isd or isd-maps" in p.stderr, p.stderr
    assert not (tmp_path / "x.npy").exists()
