#!/usr/bin/env python3
"""The README's picture of how ifd works, drawn from real data:

1. a real fit (`ifd.decompose`, as `ifd decompose SPEC --json` gives it): the filter
   as a sum of displaced isotropic Gaussians, one circle per term (radius its sigma);
2. the image prefiltered once per width the sum uses (the stack's levels), each level
   computed by ifd itself (a one-term decomposition reads exactly one level);
3. the filtered image (a per-pixel angle and scale: a swirl), with the displaced lookups that make
   two of its pixels.

Before drawing, it checks the picture's claim: one output pixel, summed by hand from
the levels at the displaced positions, equals `ifd.filter`'s pixel.

    .venv/bin/python docs/figures/how_it_works.py            # writes docs/how-it-works.png

Needs the Python module (`import ifd`) and matplotlib; runs in a few seconds.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

import ifd  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]
SPEC = "gauss:sx=32,sy=5,theta=30"
TOL = 0.05


def level(img, sigma):
    """The image correlated with an isotropic Gaussian of `sigma` px: one stack level."""
    return ifd.filter(img, ifd.Decomposition.from_terms(np.array([[1.0, 0.0, 0.0, sigma]])))


def bilinear(a, x, y):
    """`a` read at the fractional pixel (x, y) (x right, y down)."""
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0
    return ((1 - fx) * (1 - fy) * a[y0, x0] + fx * (1 - fy) * a[y0, x0 + 1]
            + (1 - fx) * fy * a[y0 + 1, x0] + fx * fy * a[y0 + 1, x0 + 1])


def rotate(x, y, deg):
    """Offsets (x right, y down) turned `deg` counter-clockwise on screen."""
    t = np.radians(deg)
    return x * np.cos(t) + y * np.sin(t), -x * np.sin(t) + y * np.cos(t)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", default=str(ROOT / "docs" / "how-it-works.png"))
    a = ap.parse_args()

    img = plt.imread(ROOT / "testdata" / "camera.png").astype(np.float32)  # (512, 512) in [0, 1]
    if img.ndim == 3:
        img = img[..., 0]
    d = ifd.decompose(SPEC, tol=TOL)
    w, cx, cy, sig = d.terms.T
    widths = np.unique(sig)
    levels = {s: level(img, s) for s in widths}

    # a per-pixel angle: the tangent to circles around the centre (`ifd field swirl`)
    h, wd = img.shape
    yy, xx = np.mgrid[0:h, 0:wd]
    angle = (90 - np.degrees(np.arctan2(yy - h / 2, xx - wd / 2))).astype(np.float32)
    # and a per-pixel scale, growing from the centre (`ifd field distance`)
    dist = np.hypot(yy - h / 2, xx - wd / 2)
    scale = (0.6 + 0.8 * dist / dist.max()).astype(np.float32)
    out = ifd.filter(img, d, angle=angle, scale=scale)

    # the claim: out(p) = sum_t w_t level_{s_p sigma_t}(p + s_p R(theta_p) c_t)
    px, py = 150, 330
    sp = float(scale[py, px])
    dx, dy = rotate(sp * cx, sp * cy, angle[py, px])
    by_hand = sum(wt * bilinear(level(img, sp * s), px + ox, py + oy) for wt, s, ox, oy in zip(w, sig, dx, dy))
    diff = abs(by_hand - out[py, px])
    print(f"{SPEC}: {len(w)} terms, {len(widths)} widths; pixel ({px}, {py}): "
          f"lookups {by_hand:.5f}, ifd.filter {out[py, px]:.5f} (bilinear reads here, ifd's own differ)")
    assert diff < 2e-3 * max(1.0, abs(out[py, px])), diff

    cmap = plt.get_cmap("viridis")
    colour = {s: cmap(i / max(1, len(widths) - 1)) for i, s in enumerate(widths)}
    fig, ax = plt.subplots(1, 3, figsize=(12.6, 4.5), gridspec_kw={"width_ratios": [1, 1.25, 1]})

    # 1. the fit
    r = int(np.ceil(np.abs(np.r_[cx, cy]).max() + 3 * sig.max()))
    gy, gx = np.mgrid[-r:r + 1, -r:r + 1].astype(float)
    k = sum(wt * np.exp(-((gx - x) ** 2 + (gy - y) ** 2) / (2 * s * s)) / (2 * np.pi * s * s)
            for wt, x, y, s in zip(w, cx, cy, sig))
    ax[0].imshow(k, cmap="gray", extent=(-r - 0.5, r + 0.5, r + 0.5, -r - 0.5))
    for wt, x, y, s in zip(w, cx, cy, sig):
        ax[0].add_patch(Circle((x, y), s, fill=False, lw=0.6 + 2.5 * abs(wt) / np.abs(w).max(),
                               ec=colour[s], ls="-" if wt > 0 else "--"))
    ax[0].set_title(f"1. fit once: the filter = {len(w)} displaced\nisotropic Gaussians "
                    f"({len(widths)} widths; dashed: negative)", fontsize=10)
    ax[0].set_xlabel(f"{SPEC}, {100 * d.report['rel_l2_error']:.0f}% fit error", fontsize=9)

    # 2. the stack: the image prefiltered once per width (four of them shown)
    crop = (slice(60, 220), slice(190, 350))
    shown = widths[np.round(np.linspace(0, len(widths) - 1, 4)).astype(int)]
    for i, s in enumerate(shown):
        x0, y0 = 170 * (i % 2), 170 * (i // 2)
        ax[1].imshow(levels[s][crop], cmap="gray", vmin=0, vmax=1, extent=(x0, x0 + 160, y0 + 160, y0))
        ax[1].add_patch(plt.Rectangle((x0, y0), 160, 160, fill=False, ec=colour[s], lw=3))
        ax[1].text(x0 + 6, y0 + 8, f"σ = {s:.1f} px", color="white", fontsize=9, va="top",
                   bbox={"fc": colour[s], "ec": "none", "pad": 1.5})
    ax[1].set_xlim(-3, 333)
    ax[1].set_ylim(333, -3)
    ax[1].axis("off")
    ax[1].set_title("2. prefilter once: the image blurred at each\nwidth the sum uses "
                    "(the stack's levels)", fontsize=10)

    # 3. the output: each pixel sums displaced lookups into the levels
    ax[2].imshow(out, cmap="gray", vmin=0, vmax=1)
    for qx, qy in ((px, py), (360, 140)):
        ox, oy = rotate(scale[qy, qx] * cx, scale[qy, qx] * cy, angle[qy, qx])
        ax[2].scatter(qx + ox, qy + oy, s=14 + 50 * np.abs(w) / np.abs(w).max(), c=[colour[s] for s in sig],
                      edgecolors="white", linewidths=0.4, zorder=3)
        ax[2].plot(qx, qy, "+", color="red", ms=10, mew=2, zorder=4)
    ax[2].set_title("3. filter: each output pixel (+) sums one lookup\nper term (dots), turned and "
                    "scaled per pixel", fontsize=10)
    ax[2].set_xlabel("out(p) = Σ w_t · level_σt(p + R(θ_p) s_p c_t)", fontsize=9)

    for x in ax:
        x.set_xticks([])
        x.set_yticks([])
    fig.tight_layout()
    fig.savefig(a.output, dpi=80)
    print(f"wrote {a.output}")


if __name__ == "__main__":
    main()
