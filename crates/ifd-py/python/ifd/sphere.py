"""The spherical half of ifd: SH of environment maps, SH rotation, spherical filter decompositions.

One SH convention everywhere: Sloan's graphics convention, orthonormal, flat
index ``l (l + 1) + m`` (pyshtools' real ``csphase=-1``). Directions have
``z`` up; row 0 of an equirectangular map is the zenith. Coefficient arrays
are float64, ``((L+1)^2, C)`` (or ``((L+1)^2,)``).

>>> import numpy as np, ifd
>>> env = np.ones((32, 64, 3), np.float32)
>>> c = ifd.sphere.sh(env, 2)
>>> c.shape
(9, 3)
>>> round(float(c[0, 0]), 4)  # int of Y_0^0 = sqrt(4 pi)
3.5449
"""

from __future__ import annotations

import os as _os
from typing import Union as _Union

import numpy as _np

from . import _ifd
from ._ifd import SphereDecomposition as Decomposition

# the __future__ import binds `annotations`: not part of the API
del annotations

__all__ = ["Decomposition", "decompose", "filter", "load", "rotate", "shade", "sh", "synthesize"]


def _coeffs(c, name: str) -> _np.ndarray:
    arr = _np.ascontiguousarray(_np.asarray(c), dtype=_np.float64)
    if arr.ndim not in (1, 2):
        raise ValueError(f"{name}: expected a ((L+1)^2,) or ((L+1)^2, C) array, got shape {arr.shape}")
    return arr


def sh(env, lmax: int, *, keep_negatives: bool = False, projection=None) -> _np.ndarray:
    """SH coefficients ``((L+1)^2, C)`` of an environment map (``ifd sphere sh``).

    ``env`` is equirectangular (``W = 2H``) or a cubemap strip (``W = 6H``,
    faces +X,-X,+Y,-Y,+Z,-Z), with the planar module's dtype rules. Negative
    samples are clamped to 0 unless ``keep_negatives``. ``projection``:
    ``"texel"`` (each texel integrated exactly, what the renderer and the IBL
    baker integrate; the default for 2:1 maps) or ``"centre"`` (pixel-centre
    quadrature with exact solid angles; the only rule for cube strips).
    """
    from . import _image

    return _ifd.sphere_sh(
        _image(env, "env"), int(lmax), keep_negatives=keep_negatives, projection=projection
    )


def synthesize(coeffs, width: int, height: int) -> _np.ndarray:
    """The ``height x width`` equirectangular map of SH coefficients (float32)."""
    return _ifd.sphere_synthesize(_coeffs(coeffs, "coeffs"), int(width), int(height))


def rotate(coeffs, zyz, method: str = "zhf") -> _np.ndarray:
    """Rotate SH coefficients: ``g(w) = f(R^T w)`` with ``R = Rz(a) Ry(b) Rz(c)`` (radians).

    ``method``: ``zhf`` (zonal harmonic factorization, ZHF Eq. 10),
    ``tailored`` (signal-tailored ZHF, Eq. 11) or ``reference``
    (Ivanic-Ruedenberg recurrences). Same shape as ``coeffs``.
    """
    a, b, c = (float(x) for x in zyz)
    return _ifd.sphere_rotate(_coeffs(coeffs, "coeffs"), (a, b, c), method=method)


def decompose(
    kernel: _Union[str, _np.ndarray],
    lmax: int,
    *,
    directions: str = "fibonacci",
    profile: str = "zonal",
    seed: int = 1,
    max_cond: float = 1e10,
) -> Decomposition:
    """Decompose a spherical filter into rotated lobes (``ifd sphere decompose``).

    ``kernel`` is a spec centred on +z (``phong:s=32``, ``vmf:kappa=50``,
    ``gauss:s=0.2``, ``aniso-gauss:s1=0.3,s2=0.05``) or SH coefficients.
    ``directions``: ``fibonacci``, ``shared``, ``optimized``,
    ``optimized-shared`` or ``random``; ``profile``: ``zonal``, ``legendre``,
    ``phong``, ``gauss``, ``vmf`` or ``hybrid``. ``lmax`` is at most 40.
    """
    k = kernel if isinstance(kernel, str) else _coeffs(kernel, "kernel")
    return _ifd.sphere_decompose(
        k, int(lmax), directions=directions, profile=profile, seed=seed, max_cond=max_cond
    )


def filter(  # noqa: A001
    env,
    decomposition: Decomposition,
    size=None,
    *,
    raw: bool = False,
    keep_negatives: bool = False,
    projection=None,
) -> _np.ndarray:
    """Filter an environment map with a spherical decomposition (``ifd sphere filter``).

    Every output texel with direction ``w`` gets the kernel rotated to ``w``
    (frame ``R(w) = Rz(phi) Ry(theta)``, the kernel's x axis along the
    meridian; singular at the poles for anisotropic kernels) applied to the
    map, by the decomposition's rotated lobes (ISD Eq. 6/13/14). The kernel
    is normalised to unit integral unless ``raw``. ``size`` is the output's
    ``(width, height)``, 2:1 or 6:1 (default the input's). ``projection`` as
    in :func:`sh`. Returns ``(H, W, C)`` float32; band-limited results may
    ring below zero.
    """
    from . import _image

    sz = None if size is None else (int(size[0]), int(size[1]))
    return _ifd.sphere_filter(
        _image(env, "env"),
        decomposition,
        size=sz,
        raw=raw,
        keep_negatives=keep_negatives,
        projection=projection,
    )


def shade(coeffs, brdf: str, normals, views, *, lmax=None, table=None, tangents=None) -> _np.ndarray:
    """Radiance leaving surface points lit by an environment, by ISD (Eq. 22).

    ``coeffs`` are the environment's SH coefficients (:func:`sh`);
    ``normals`` and ``views`` are ``(N, 3)`` world-space unit vectors
    (``views`` from the surface towards the viewer); ``brdf`` is a spec of
    ``ifd sphere brdf``: ``lambert``, ``phong:s=32`` (normalised, about the
    mirror direction, cosine folded in), ``blinn:s=64``, ``ggx:alpha=0.3``,
    ``ggx:ax=0.1,ay=0.4``, ``ward:ax=..,ay=..``, optional ``albedo=``. Lambert
    and Phong have closed-form lobe weights; the others need the lobe table
    ``ifd sphere brdf SPEC --lmax L -o t.lobes`` writes (``table``).
    ``tangents`` orient anisotropic BRDFs. ``lmax`` defaults to the
    coefficients' degree. Returns ``(N, C)`` float64.
    """
    import os as _os

    n = _np.ascontiguousarray(_np.asarray(normals), dtype=_np.float64)
    v = _np.ascontiguousarray(_np.asarray(views), dtype=_np.float64)
    t = None if tangents is None else _np.ascontiguousarray(_np.asarray(tangents), dtype=_np.float64)
    path = None if table is None else _os.fspath(table)
    return _ifd.sphere_shade(_coeffs(coeffs, "coeffs"), brdf, n, v, lmax=lmax, table=path, tangents=t)


def load(path: _Union[str, _os.PathLike]) -> Decomposition:
    """Read a decomposition written by ``ifd sphere decompose`` or :meth:`Decomposition.save`."""
    return Decomposition.load(_os.fspath(path))
