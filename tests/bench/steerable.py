"""The strongest baselines for a filter rotated (and scaled) per pixel: a
steerable basis, and blended bins, both with the image spectrum computed once.

Both apply a kernel family k(theta, s) -- the kernel rotated by theta (degrees,
counter-clockwise on screen, period 180 for a point-symmetric kernel) and
scaled by s -- at a different (theta, s) at every pixel, as exact correlation
would (out(p) = sum_x k_{theta(p), s(p)}(x) img(p + x), reflect-101 borders,
every family member sampled on the same (2r+1)^2 window and normalised to sum
1), written as a careful numpy/scipy user would write them. Each has a fit
(the basis or the bins' kernels; per filter family), a prepare (the kernels'
spectra at the padded image size; per image size) and an apply (per image;
the timed work: padding, one forward DFT, one spectrum product and one
inverse DFT per basis kernel or bin, the per-pixel weights and the
accumulation).

Steerable basis (Freeman and Adelson 1991; Perona 1995, deformable kernels).
The family is sampled at `n_angles` angles over the period (90 over 180
degrees) and, with a scale range, at `n_scales` log-spaced scales (8):
k_i, i = 1..n. A rank-K approximation k_i ~ sum_k w_k(i) b_k is chosen to
minimise the expected squared error of the *filtered image* rather than of
the kernel: for an image with power spectrum P(f), the output error of a
kernel error e is E|e * img|^2 = sum_f P(f) |E(f)|^2 (Parseval), so the
error to minimise over the family is

    sum_i sum_f P(f) |K_i(f) - sum_k w_k(i) B_k(f)|^2,

a weighted least-squares problem, whose solution is the SVD of the stacked
*whitened* family: A = [sqrt(P) K_1, ..., sqrt(P) K_n] (a column per family
member, a row per frequency), A = U S V^T, and the best rank K is A V_K V_K^T.
With P(f) = 1 / (|f|^2 + f0^2) (the natural-image spectrum, f in cycles per
pixel, f0 = 1/1024 by default: about one cycle per 1024-px image; 1 / (2r +
1) gave 0.4-0.5 dB less at K = 16 with the 2:1 scale map on camera and
astronaut at 1024^2, 1/64 and 1/16 up to 2 dB less) this is the SVD
"weighted by a natural image spectrum". Since A V_K V_K^T = sum_k (A V_k) V_k^T and A V_k is the
whitened spectrum of b_k = sum_i V[i, k] k_i, the basis kernels are plain
linear combinations of the family's kernels on the same window (the whitening
is never inverted) and the weights of family member i are w_k(i) = V[i, k].
The SVD is computed as the eigendecomposition of the Gram matrix G = Re(A^H
A) (n x n, float64; the same V and S^2), with the kernels' DFTs on a grid of
2(2r+1) - 1 rounded up to a fast size, so that the inner product is that of
linear (not circular) correlation: G[i, j] = sum_f c_f P(f) Re(K_i(f)
conj(K_j(f))), over the half spectrum of `rfft2`, c_f = 2 for the columns
whose conjugates are not stored.

The weights as functions of angle: a truncated Fourier series in 2 theta,
fitted to the n_angles samples of each weight (the DFT of the samples). The
SVD returns the two weights of a (nearly) degenerate pair of singular values
-- the cos and sin of one harmonic, for a family invariant under rotation --
in an arbitrary rotation of the pair; they are rotated back (relative gap
<= `gap_tol`; the span, hence the approximation, is unchanged) so that each
weight holds about one trig term. Dropping the term (cos or sin of harmonic h)
of weight k adds S_k^2 times that term's energy in V[:, k] (summed over the
scales) to the weighted family error (the U_k are orthonormal), so the terms
are dropped smallest first while the added error stays below `weight_tol`
(0.1) times the error of the rank-K truncation itself (the sum of the
dropped S^2). With a scale range each kept Fourier coefficient is a function
of log scale: the not-a-knot cubic spline through its `n_scales` samples
(scipy's CubicSpline default; written here in the truncated power basis 1, x,
x^2, x^3, (x - x_q)^3_+, x the normalised log scale in [0, 1], x_q the
spline's knots). Scales outside the range are clamped to it.

Per pixel: w_k(p) = sum over its kept terms of trig(h, theta(p)) u_kh(s(p)).
Angle only, the trig terms are computed per pixel (np.cos / np.sin of 2 h
theta, once per harmonic) and summed with their constant coefficients. With
a scale range each w_k(theta, s) is tabulated at the fit on `table` = (1024
angles over the period, 64 log scales) from the series and the splines, and
read per pixel with cv2.remap (bilinear, float maps computed once per image;
a 256 KB table stays in a core's L2: 2.6 ms a remap at 1024^2 against 3.6
ms with 2048 x 128, the same PSNR to 0.01 dB at K = 24, as with 512 x 32),
one remap per basis kernel. The output is sum_k w_k(p) (b_k corr img)(p)
(cv2.accumulateProduct), divided by the truncated basis' DC gain at that
pixel, sum_k w_k(p) sum(b_k) (its own few trig terms, or table), so that a
constant image is reproduced exactly.

Blended bins. The kernel rotated into `ka` angle bins (i * 180 / ka degrees)
and, with a scale range, scaled into `ks` log-spaced scale bins over it; each
bin's kernel is the family member itself (on the full window, sum 1). Each
bin is applied through one spectrum product and inverse DFT with the one
forward DFT of the padded image, and every pixel blends the two nearest angle
bins linearly (wrapping at the period), and with scale bins the 2 x 2 nearest
angle x log-scale bins bilinearly: out(p) = sum_b w_b(p) (k_b corr img)(p),
the weights a partition of unity.

The DFTs (both methods): the image padded by r with reflect-101 (OpenCV's
BORDER_REFLECT_101; numpy's "reflect") and then to a fast size (scipy.fft's
next_fast_len) in float32, `scipy.fft.rfft2` with workers=1 (one thread;
faster here than cv2.dft once the product and cropping are counted); a basis
kernel's spectrum is conj(DFT of the kernel wrapped around the origin), so
that the product is correlation; the inverse transform is two 1-D passes, the
second (irfft along rows) only on the rows of the output that are kept.
Everything per image is float32 / complex64.
"""

import math

import numpy as np
import scipy.fft as sfft

# ---------------------------------------------------------------------------
# kernel families


def gauss_kernel_at(sx, sy, r):
    """The anisotropic Gaussian gauss:sx=SX,sy=SY: a function (theta_deg, s)
    -> its (2r+1)^2 window (float64, sum 1), rotated by theta and scaled by s
    exactly as `curves_vs_opencv.exact_reference` samples it (y the row
    offset, downwards; theta counter-clockwise on screen)."""
    y, x = np.mgrid[-r : r + 1, -r : r + 1].astype(np.float64)

    def at(theta_deg, s=1.0):
        t = math.radians(theta_deg)
        c, sn = math.cos(t), math.sin(t)
        u = (c * x - sn * y) / (sx * s)
        v = (sn * x + c * y) / (sy * s)
        k = np.exp(-0.5 * (u * u + v * v))
        return k / k.sum()

    at.r = r
    return at


def array_kernel_at(kernel):
    """Any kernel array (square, odd size 2r+1, centred): a function
    (theta_deg, s) -> the kernel rotated by theta and scaled by s about its
    centre (cv2.warpAffine, cubic interpolation, zero outside), on the same
    window, normalised to sum 1."""
    import cv2

    k0 = np.asarray(kernel, np.float64)
    if k0.ndim != 2 or k0.shape[0] != k0.shape[1] or k0.shape[0] % 2 == 0:
        raise ValueError("kernel: a square array of odd size")
    r = k0.shape[0] // 2

    def at(theta_deg, s=1.0):
        m = cv2.getRotationMatrix2D((float(r), float(r)), float(theta_deg), float(s))
        k = cv2.warpAffine(k0, m, k0.shape[::-1], flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_CONSTANT)
        return k / k.sum()

    at.r = r
    return at


def log_scales(smin, smax, n):
    """n scales spaced evenly in log scale over [smin, smax] (one: smax)."""
    if n == 1:
        return np.array([float(smax)])
    return np.exp(np.linspace(math.log(smin), math.log(smax), n))


# ---------------------------------------------------------------------------
# the SVD (fit)


def weighted_gram(kernels, f0=None, grid=None, chunk=48):
    """G = Re(A^H A) for the whitened spectra A of `kernels` (n, 2r+1, 2r+1):
    sum over the frequencies f of the DFT grid (`grid`, default
    next_fast_len(2 (2r+1) - 1)) of P(f) Re(K_i conj K_j), P = 1 / (|f|^2 +
    f0^2), f0 = 1/1024 by default. float64; the spectra are computed
    `chunk` kernels at a time into n x grid^2 reals."""
    n, size = kernels.shape[0], kernels.shape[1]
    f0 = 1.0 / 1024 if f0 is None else f0
    m = grid or sfft.next_fast_len(2 * size - 1, real=True)
    fy = sfft.fftfreq(m)[:, None]
    fx = sfft.rfftfreq(m)[None, :]
    c = np.full(fx.shape, 2.0)
    c[:, 0] = 1.0
    if m % 2 == 0:
        c[:, -1] = 1.0
    w = np.sqrt(c / (fx * fx + fy * fy + f0 * f0)).ravel()
    nf = w.size
    a = np.empty((n, 2 * nf))  # real and imaginary parts side by side
    for i0 in range(0, n, chunk):
        s = sfft.rfft2(kernels[i0 : i0 + chunk], s=(m, m), axes=(1, 2), workers=1).reshape(-1, nf)
        s *= w
        a[i0 : i0 + chunk, :nf] = s.real
        a[i0 : i0 + chunk, nf:] = s.imag
    return a @ a.T


def _harmonic_energy(vs, n_angles):
    """Fourier coefficients in 2 theta of weight samples vs (ns, na, K):
    (cos, sin) coefficients (ns, H+1, K) each with H = na // 2 - 1 (the
    Nyquist term left out), and each harmonic's energy summed over the
    scales, (H+1, K), as a share of the samples' squared norm (Parseval)."""
    f = np.fft.rfft(vs, axis=1)  # (ns, na//2 + 1, K)
    h = n_angles // 2 - 1 if n_angles % 2 == 0 else n_angles // 2
    f = f[:, : h + 1]
    cc = 2.0 * f.real / n_angles
    ss = -2.0 * f.imag / n_angles
    cc[:, 0] = f[:, 0].real / n_angles
    ss[:, 0] = 0.0
    # sum_i v_i^2 = n (c0^2 + 1/2 sum_h (c_h^2 + s_h^2)) (+ the Nyquist term)
    e = n_angles * (cc**2 + ss**2) / 2.0
    e[:, 0] = n_angles * cc[:, 0] ** 2
    return cc, ss, e.sum(axis=0)


def _spline_basis(x, knots):
    """The truncated power basis of the not-a-knot cubic spline through
    `knots` (sorted, in [0, 1]): rows 1, x, x^2, x^3 (fewer for fewer than 4
    knots), then (x - knots[q])^3_+ for the knots that are real knots of the
    not-a-knot spline (all but the first two and the last two)."""
    x = np.asarray(x)
    nk = len(knots)
    deg = min(3, nk - 1)
    rows = [x**d if d else np.ones_like(x) for d in range(deg + 1)]
    for q in range(2, nk - 2):
        rows.append(np.maximum(x - knots[q], 0.0) ** 3)
    return np.stack(rows)


def _align_pairs(vk, lam, ns, n_angles, gap_tol):
    """Rotate the weights of nearly equal singular values pairwise (relative
    gap <= gap_tol: the cos / sin pairs of one harmonic of a rotation
    invariant family, which the SVD returns in an arbitrary rotation) so
    that one of the two holds as little of the pair's main harmonic's sine
    as possible: then each weight has about one harmonic. The span, hence
    the rank-K approximation, is unchanged."""
    k = vk.shape[1]
    i = 0
    while i < k - 1:
        if lam[i] - lam[i + 1] > gap_tol * lam[i]:
            i += 1
            continue
        cc, ss, e = _harmonic_energy(vk[:, i : i + 2].reshape(ns, n_angles, 2), n_angles)
        e = e.sum(axis=1)
        e[0] = 0.0
        h = int(np.argmax(e))
        sv = ss[:, h, :]  # (ns, 2)
        wv, q = np.linalg.eigh(sv.T @ sv)
        q0 = q[:, 0]  # least sine
        rot = np.array([[q0[0], -q0[1]], [q0[1], q0[0]]])
        vk[:, i : i + 2] = vk[:, i : i + 2] @ rot
        i += 2
    return vk


class Steerable:
    """A fitted steerable basis: see `fit_steerable`."""


def family_svd(kernel_at, scale_range=None, n_angles=90, n_scales=8, f0=None, grid=None, period=180.0):
    """The weighted SVD of the sampled family (the part of the fit shared by
    every K): the family `kernel_at` (a function (theta_deg, s) -> (2r+1)^2
    window with attribute r, e.g. `gauss_kernel_at`) at `n_angles` angles
    over `period` and, when `scale_range` = (smin, smax) is given, times
    `n_scales` log-spaced scales; the eigendecomposition of its Gram matrix
    weighted by 1/(|f|^2 + f0^2) (see the module's docstring). A dict: the
    family (n, 2r+1, 2r+1), the squared singular values (descending) and
    the right singular vectors (n, n), the sampling, and its wall time."""
    import time

    t0 = time.perf_counter()
    angles = np.arange(n_angles) * (period / n_angles)
    scales = log_scales(*scale_range, n_scales) if scale_range else np.array([1.0])
    fam = np.stack([kernel_at(a, s) for s in scales for a in angles])  # (ns * na, size, size)
    lam, v = np.linalg.eigh(weighted_gram(fam, f0=f0, grid=grid))
    order = np.argsort(lam)[::-1]
    return {
        "fam": fam,
        "lam": np.maximum(lam[order], 0.0),
        "v": v[:, order],
        "r": kernel_at.r,
        "n_angles": n_angles,
        "n_scales": len(scales),
        "scale_range": tuple(scale_range) if scale_range else None,
        "period": period,
        "seconds": time.perf_counter() - t0,
    }


def fit_steerable(kernel_at, k, scale_range=None, n_angles=90, n_scales=8, f0=None, grid=None, weight_tol=0.1,
                  gap_tol=1e-3, table=(1024, 64), period=180.0, svd=None):
    """Fit a rank-`k` steerable basis of the family `kernel_at` (see
    `family_svd`, whose result may be passed as `svd` to share it between
    several k; then the sampling arguments are its own): the basis kernels
    from the weighted SVD, the weights' truncated Fourier series in 2 theta
    and cubic splines in log scale (see the module's docstring). Returns a
    `Steerable` with the basis kernels (k, 2r+1, 2r+1, float64), their sums,
    the singular values (all of them), the kept terms, and the fit's wall
    time (`seconds`, the SVD's included; `svd_seconds` that part)."""
    import time

    if svd is None:
        svd = family_svd(kernel_at, scale_range, n_angles, n_scales, f0, grid, period)
    t0 = time.perf_counter()
    fam, lam, v = svd["fam"], svd["lam"], svd["v"]
    r, n_angles, ns, scale_range, period = svd["r"], svd["n_angles"], svd["n_scales"], svd["scale_range"], svd["period"]
    n = fam.shape[0]
    if not 1 <= k <= n:
        raise ValueError(f"k: 1..{n}")
    vk = _align_pairs(v[:, :k].copy(), lam, ns, n_angles, gap_tol)
    basis = np.tensordot(vk.T, fam, axes=1)  # (k, size, size): b_k = sum_i V[i, k] k_i
    trunc_err = float(lam[k:].sum())

    # the weights' Fourier series in 2 theta; drop (cos or sin) terms smallest first
    cc, ss, _ = _harmonic_energy(vk.reshape(ns, n_angles, k), n_angles)  # (ns, H+1, k)
    ecs = np.stack([(cc**2).sum(axis=0), (ss**2).sum(axis=0)]) * (n_angles / 2.0)  # (2, H+1, k)
    ecs[0, 0] *= 2.0  # the constant term: n c0^2
    cost = ecs * lam[None, None, :k]  # added weighted error of dropping (part, h, k)
    budget = weight_tol * trunc_err if trunc_err > 0 else 1e-12 * lam[0]
    keep = np.ones(cost.shape, bool)
    keep[1, 0] = False  # no sin(0)
    cost[1, 0] = 0.0
    spent = 0.0
    for idx in np.argsort(cost, axis=None):
        c = cost.flat[idx]
        if spent + c > budget:
            break
        spent += c
        keep.flat[idx] = False
    # pairs: (basis index, harmonic, part 0 cos / 1 sin), coefficient samples over the scales
    pairs, samples = [], []
    for kk in range(k):
        for h in range(cost.shape[1]):
            for part, co in ((0, cc), (1, ss)):
                if keep[part, h, kk]:
                    pairs.append((kk, h, part))
                    samples.append(co[:, h, kk])
    samples = np.array(samples).T  # (ns, npairs)

    m = Steerable()
    m.kind = "steerable"
    m.r, m.k, m.period = r, k, period
    m.n_angles, m.n_scales = n_angles, ns
    m.scale_range = tuple(scale_range) if scale_range else None
    m.basis = basis
    m.sums = basis.sum(axis=(1, 2))
    m.singular_values = np.sqrt(lam)
    m.truncation_error = trunc_err / float(lam.sum())  # relative weighted family error (squared)
    m.weight_error = spent / float(lam.sum())
    m.pairs = pairs
    m.pairs_of = [[p for p, q in enumerate(pairs) if q[0] == kk] for kk in range(k)]
    m.fold = np.ones(k)
    m.harmonics = sorted({h for _, h, _ in pairs})
    if ns > 1:
        # w_k(theta, s) tabulated on `table` = (angles over the period, log
        # scales over the range) nodes, from the Fourier series and the
        # splines, for cv2.remap (bilinear); one more column closes the period
        knots = np.linspace(0.0, 1.0, ns)
        coef = np.linalg.solve(_spline_basis(knots, knots).T, samples)  # (nbasis, npairs)
        nt, nsx = table
        u = _spline_basis(np.linspace(0.0, 1.0, nsx), knots).T @ coef  # (nsx, npairs)
        x2 = np.arange(nt + 1) * (2 * np.pi / nt)
        tabs = np.zeros((k, nsx, nt + 1))
        for p, (kk, h, part) in enumerate(pairs):
            trig = np.cos(h * x2) if part == 0 else np.sin(h * x2)
            tabs[kk] += u[:, p, None] * trig[None, :]
        m.tables = tabs.astype(np.float32)
        m.dc_table = np.tensordot(m.sums, tabs, axes=1).astype(np.float32)
        m.spline_coef = coef
        m.knots = knots
    else:
        m.const = samples[0]
        for kk, ps in enumerate(m.pairs_of):
            if len(ps) == 1:
                m.fold[kk] = samples[0, ps[0]]
        # the DC gain as a function of angle: sum_k sums_k w_k(theta), by harmonic
        dc = {}
        for p, (kk, h, part) in enumerate(pairs):
            dc[(h, part)] = dc.get((h, part), 0.0) + m.sums[kk] * samples[0, p]
        big = max(abs(v) for v in dc.values())
        m.dc_terms = [(h, part, c) for (h, part), c in sorted(dc.items()) if abs(c) > 1e-9 * big]
    m.svd_seconds = svd["seconds"]
    m.seconds = time.perf_counter() - t0 + svd["seconds"]
    return m


class Bins:
    """Fitted bins: see `fit_bins`."""


def fit_bins(kernel_at, ka, ks=1, scale_range=None, period=180.0):
    """The kernel rotated into `ka` angle bins (i * period / ka) and, with
    `scale_range` = (smin, smax), scaled into `ks` log-spaced scale bins
    (ks >= 2) over it. Returns a `Bins` with the kernels (ks, ka, 2r+1,
    2r+1) and the fit's wall time."""
    import time

    t0 = time.perf_counter()
    if scale_range is None:
        ks = 1
    elif ks < 2:
        raise ValueError("ks: at least 2 scale bins with a scale range")
    scales = log_scales(*scale_range, ks) if scale_range else np.array([1.0])
    b = Bins()
    b.kind = "bins"
    b.r, b.ka, b.ks, b.period = kernel_at.r, ka, ks, period
    b.scale_range = tuple(scale_range) if scale_range else None
    b.kernels = np.stack([np.stack([kernel_at(i * period / ka, s) for i in range(ka)]) for s in scales])
    b.seconds = time.perf_counter() - t0
    return b


# ---------------------------------------------------------------------------
# per image size: the kernels' spectra


def padded_size(shape, r):
    """The DFT size of an image padded by r on every side: next_fast_len."""
    return tuple(sfft.next_fast_len(n + 2 * r, real=True) for n in shape)


def kernel_spectra(kernels, shape, r):
    """conj(rfft2) of each (2r+1)^2 kernel wrapped around the origin of the
    padded grid of an image of `shape`: multiplying the image's spectrum by
    it is correlation. complex64, (n, L0, L1 // 2 + 1)."""
    l0, l1 = padded_size(shape, r)
    kernels = np.asarray(kernels).reshape(-1, 2 * r + 1, 2 * r + 1)
    out = np.empty((len(kernels), l0, l1 // 2 + 1), np.complex64)
    buf = np.zeros((l0, l1))
    for i, k in enumerate(kernels):
        buf[:] = 0.0
        buf[: 2 * r + 1, : 2 * r + 1] = k
        out[i] = np.conj(sfft.rfft2(np.roll(buf, (-r, -r), axis=(0, 1)), workers=1))
    return out


def prepare(model, shape):
    """The model's kernel spectra for images of `shape` (per image size; the
    fit's second part): (n, ...) complex64, basis kernels in order, or bins
    in (scale, angle) order."""
    if model.kind == "steerable":
        # a basis kernel whose weight is one term c trig(h, theta) is scaled
        # by c here, so that its weight per pixel is trig itself
        return kernel_spectra(model.basis * model.fold[:, None, None], shape, model.r)
    return kernel_spectra(model.kernels, shape, model.r)


# ---------------------------------------------------------------------------
# per image (timed)


def _forward(img, r):
    """The image padded by r with reflect-101, then to the fast size
    (reflecting further at the bottom and right: those rows and columns only
    ever reach outputs that are cropped away), and its rfft2 (complex64)."""
    h, w = img.shape
    l0, l1 = padded_size(img.shape, r)
    import cv2

    pad = cv2.copyMakeBorder(img.astype(np.float32, copy=False), r, l0 - h - r, r, l1 - w - r, cv2.BORDER_REFLECT_101)
    return sfft.rfft2(pad, workers=1, overwrite_x=True)


def _trig(model, angles, harmonics):
    """cos(2 h theta) and sin(2 h theta) (period 180) per pixel, float32,
    for each harmonic h >= 1 in `harmonics`."""
    x2 = angles.astype(np.float32) * np.float32(2 * np.pi / model.period)
    out = {}
    for h in harmonics:
        if h:
            a = x2 * np.float32(h)
            out[h] = (np.cos(a), np.sin(a))
    return out


def _wrap(x, period):
    """x (float32) wrapped into [0, period] in place (x - floor(x / period)
    period: numpy's float % is ten times slower)."""
    y = x * np.float32(1.0 / period)
    np.floor(y, out=y)
    y *= np.float32(period)
    x -= y
    return x


def _remap_maps(model, angles, scales):
    """cv2.remap's maps into the model's (log scale x angle) tables: x the
    angle in table columns, y the clamped normalised log scale in rows."""
    smin, smax = model.scale_range
    nsx, nt1 = model.tables.shape[1:]
    mx = _wrap(angles.astype(np.float32) * np.float32((nt1 - 1) / model.period), nt1 - 1)
    my = np.log(scales.astype(np.float32))
    my -= np.float32(math.log(smin))
    my *= np.float32((nsx - 1) / (math.log(smax) - math.log(smin)))
    np.clip(my, 0, nsx - 1, out=my)
    return mx, my


def steerable_weights(model, angles, scales=None):
    """The per-pixel weights w_k(p) (k, h, w) float32 and the DC gain (h, w)
    of `model` at the angle map (degrees) and scale map (None: scale 1), as
    `apply_steerable` computes them (one at a time there)."""
    import cv2

    ws = []
    if model.scale_range:
        mx, my = _remap_maps(model, angles, np.ones_like(angles) if scales is None else scales)
        for t in model.tables:
            ws.append(cv2.remap(t, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE))
        dc = cv2.remap(model.dc_table, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.stack(ws), dc
    trig = _trig(model, angles, model.harmonics)
    wbuf = np.empty(angles.shape, np.float32)
    for kk in range(model.k):
        ws.append(_angle_weight(model, kk, trig, wbuf).copy())
    return np.stack(ws), _angle_dc(model, trig, angles.shape)


def _angle_weight(model, kk, trig, wbuf):
    """w_k (angle-only model) into `wbuf`: the sum of its kept harmonics."""
    wbuf[:] = 0.0
    for p in model.pairs_of[kk]:
        _, h, part = model.pairs[p]
        c = float(model.const[p])
        if h:
            cv2_scale_add(trig[h][part], c, wbuf)
        else:
            wbuf += np.float32(c)
    return wbuf


def cv2_scale_add(src, c, dst):
    """dst += c * src in one pass (cv2.scaleAdd)."""
    import cv2

    cv2.scaleAdd(src, c, dst, dst=dst)


def _angle_dc(model, trig, shape):
    """The DC gain of an angle-only model per pixel (float32)."""
    dc = np.zeros(shape, np.float32)
    for h, part, c in model.dc_terms:
        if h:
            cv2_scale_add(trig[h][part], float(c), dc)
        else:
            dc += np.float32(c)
    return dc


def apply_steerable(model, spectra, img, angles, scales=None, x=None, mask=None):
    """The steerable basis applied to `img` (2-D float) with per-pixel
    `angles` (degrees) and `scales` (None: 1); `spectra` from `prepare`.
    float32 output; every step is per-image work: the padded image's DFT,
    per basis kernel a spectrum product, an inverse DFT, its weight at every
    pixel and the accumulation out += w_k f_k, then out /= DC gain.

    Several families on one image (a family per region): `x`, the padded
    image's DFT (`_forward(img, model.r)`), computed once for every family
    of the same radius, and `mask` (uint8, nonzero where this family
    applies): the accumulation is then restricted to those pixels, the
    others left 0."""
    import cv2

    h, w = img.shape
    r = model.r
    if x is None:
        x = _forward(img, r)
    n1 = padded_size(img.shape, r)[1]
    out = np.zeros((h, w), np.float32)
    buf = np.empty_like(x)
    wbuf = np.empty((h, w), np.float32)
    if model.scale_range:
        mx, my = _remap_maps(model, angles, np.ones_like(angles) if scales is None else scales)
        dc = cv2.remap(model.dc_table, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    else:
        trig = _trig(model, angles, model.harmonics)
        dc = _angle_dc(model, trig, (h, w))
    for kk in range(model.k):
        f = _inv(x, spectra[kk], buf, r, h, w, n1)
        if model.scale_range:
            cv2.remap(model.tables[kk], mx, my, cv2.INTER_LINEAR, dst=wbuf, borderMode=cv2.BORDER_REPLICATE)
        else:
            pk = model.pairs_of[kk]
            if len(pk) == 1:  # one term, its constant folded into the spectrum (`prepare`)
                _, hh, part = model.pairs[pk[0]]
                if hh:
                    cv2.accumulateProduct(f, trig[hh][part], out, mask)
                else:
                    cv2.accumulate(f, out, mask)
                continue
            _angle_weight(model, kk, trig, wbuf)
        cv2.accumulateProduct(f, wbuf, out, mask)
    out /= dc
    return out


def _inv(x, spec, buf, r, h, w, n1):
    """(kernel corr image) on the image's own pixels: the spectrum product
    into `buf`, the inverse DFT along columns, then along rows only for the
    kept rows; an (h, w) view."""
    np.multiply(x, spec, out=buf)
    z = sfft.ifft(buf, axis=0, workers=1, overwrite_x=True)
    return sfft.irfft(z[r : r + h], n=n1, axis=1, workers=1)[:, r : r + w]


def apply_bins(model, spectra, img, angles, scales=None):
    """Blended bins applied to `img` with per-pixel `angles` (degrees) and
    `scales` (None: 1); `spectra` from `prepare`. Linear weights between the
    two nearest angle bins (wrapping at the period), bilinear over the 2 x 2
    nearest angle x log-scale bins. float32 output.

    Every pixel's cell (the bins below it in angle and log scale) and its
    corner weights are computed once; each bin's output is then accumulated,
    times the corner's weight, into the pixels of the (up to 4) cells that
    read it (cv2.accumulateProduct with the cell's mask); a bin no pixel
    reads is skipped."""
    import cv2

    h, w = img.shape
    r, ka, ks = model.r, model.ka, model.ks
    x = _forward(img, r)
    n1 = padded_size(img.shape, r)[1]
    pa = _wrap(angles.astype(np.float32) * np.float32(ka / model.period), ka)
    i0 = pa.astype(np.int32)  # floor: pa >= 0
    fa = pa - i0.astype(np.float32)
    i0 %= ka  # pa may round up to ka
    if ks > 1:
        smin, smax = model.scale_range
        q = np.log((np.ones_like(angles) if scales is None else scales).astype(np.float32))
        q -= np.float32(math.log(smin))
        q *= np.float32((ks - 1) / (math.log(smax) - math.log(smin)))
        np.clip(q, 0, ks - 1, out=q)
        j0 = np.minimum(q.astype(np.int32), ks - 2)
        fs = q - j0.astype(np.float32)
        cell = i0 * (ks - 1) + j0
        ga = np.float32(1) - fa
        gs = np.float32(1) - fs
        corner = {(0, 0): ga * gs, (1, 0): fa * gs, (0, 1): ga * fs, (1, 1): fa * fs}
        ncell = ka * (ks - 1)
    else:
        cell = i0
        corner = {(0, 0): np.float32(1) - fa, (1, 0): fa}
        ncell = ka
    present = np.bincount(cell.ravel(), minlength=ncell) > 0
    cell = cell.astype(np.uint16 if ncell < 65536 else np.int32)
    out = np.zeros((h, w), np.float32)
    buf = np.empty_like(x)
    mask = np.empty((h, w), bool)
    for j in range(ks):
        for i in range(ka):
            parts = []
            for (da, ds), wt in corner.items():
                ci, cj = (i - da) % ka, j - ds
                if ks > 1:
                    if not 0 <= cj <= ks - 2:
                        continue
                    c = ci * (ks - 1) + cj
                else:
                    c = ci
                if present[c]:
                    parts.append((c, wt))
            if not parts:
                continue
            f = _inv(x, spectra[j * ka + i], buf, r, h, w, n1)
            for c, wt in parts:
                np.equal(cell, c, out=mask)
                cv2.accumulateProduct(f, wt, out, mask=mask.view(np.uint8))
    return out
