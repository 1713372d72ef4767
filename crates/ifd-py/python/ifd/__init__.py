"""ifd: isotropic filter decomposition from Python.

Huge, anisotropic, rotated, scaled, spatially varying filters at the cost of a
few lookups per pixel. A filter is decomposed once into a sparse sum of
displaced isotropic Gaussians (:func:`decompose`); :func:`filter` then applies
any rotated and scaled copy of it at every pixel, with a per-pixel angle and
scale if you like.

Images are numpy arrays, ``(H, W)`` or ``(H, W, C)``, with the CLI's range
rules: float32/float64 are used as they are, uint8 maps to ``[0, 1]`` by /255
and uint16 by /65535 (as the CLI reads 8/16-bit PNG and TIFF files), linearly.
Results are float32. C-contiguous float32 images are not copied. Every call
releases the GIL while it works, so threads run in parallel.

Conventions are OpenCV's: filtering is correlation as in ``cv2.filter2D``,
``x`` is the column and ``y`` the row, angles are degrees counter-clockwise on
screen, the default border is reflect-101 (``cv2.BORDER_DEFAULT``).

>>> import numpy as np, ifd
>>> d = ifd.decompose("gauss:sx=12,sy=2,theta=0", tol=0.02)
>>> img = np.random.default_rng(0).random((128, 160), dtype=np.float32)
>>> angle = np.linspace(0, 180, 160, dtype=np.float32)[None, :].repeat(128, 0)
>>> out = ifd.filter(img, d, angle=angle)
>>> out.shape, out.dtype
((128, 160), dtype('float32'))

Errors: wrong dtypes, shapes, NaN, and bad parameters raise ``ValueError``
with the CLI's message; files that cannot be read or written raise
``OSError``.
"""

from __future__ import annotations

import os as _os
from typing import Optional as _Optional, Sequence as _Sequence, Union as _Union

import numpy as _np

from . import _ifd
from ._ifd import Decomposition, __version__

# the __future__ import binds `annotations`: not part of the API
del annotations

__all__ = [
    "Decomposition",
    "__version__",
    "compare",
    "decompose",
    "filter",
    "hessian",
    "last_call_seconds",
    "load",
    "smooth",
    "sphere",
]

_ArrayLike = _Union[_np.ndarray, "list[float]"]
_Field = _Union[float, _np.ndarray]


def _image(a: _ArrayLike, name: str) -> _np.ndarray:
    """A C-contiguous float32 (H, W) or (H, W, C) array: no copy when it already is one."""
    arr = _np.asarray(a)
    if arr.ndim not in (2, 3):
        raise ValueError(f"{name}: expected an (H, W) or (H, W, C) array, got shape {arr.shape}")
    if arr.dtype == _np.uint8:
        return _np.ascontiguousarray(arr, dtype=_np.float32) / _np.float32(255.0)
    if arr.dtype == _np.uint16:
        return _np.ascontiguousarray(arr, dtype=_np.float32) / _np.float32(65535.0)
    if arr.dtype in (_np.float32, _np.float64, _np.float16):
        return _np.ascontiguousarray(arr, dtype=_np.float32)
    raise ValueError(
        f"{name}: dtype {arr.dtype} is not supported (float32, float64, uint8 or uint16)"
    )


def _field(value: _Field, name: str) -> tuple[float, _Optional[_np.ndarray]]:
    """A constant (float) or a per-pixel (H, W) map, as the extension takes them."""
    if _np.isscalar(value) or (isinstance(value, _np.ndarray) and value.ndim == 0):
        v = float(value)  # type: ignore[arg-type]
        return v, None
    arr = _np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name}: dtype {arr.dtype} is not numeric")
    if arr.ndim != 2:
        raise ValueError(f"{name}: expected a number or an (H, W) map, got shape {arr.shape}")
    # Maps are data (degrees, scale factors): integer dtypes are read as
    # their values, never rescaled.
    return 0.0 if name == "angle" else 1.0, _np.ascontiguousarray(arr, dtype=_np.float32)


def decompose(
    spec_or_kernel: _Union[str, _ArrayLike],
    tol: float = 0.01,
    max_terms: _Optional[int] = None,
    *,
    levels: _Optional[int] = None,
    alpha: _Optional[float] = None,
    oversample: _Optional[int] = None,
    min_sigma: _Optional[float] = None,
    margin: _Optional[int] = None,
) -> Decomposition:
    """Decompose a 2D filter into a sparse sum of displaced isotropic Gaussians.

    ``spec_or_kernel`` is a built-in spec, as ``ifd decompose`` takes it::

        gauss:sx=24,sy=3,theta=30       anisotropic Gaussian (sigmas in px, sum 1)
        dgauss:order=xx|xy|yy,sigma=4   second derivative of a Gaussian
        log:sigma=4                     Laplacian of Gaussian
        gabor:sigma=8,freq=0.1,theta=0  Gabor (frequency in cycles/px)
        box:w=31,h=5,theta=20           rotated box (sum 1)
        disk:r=12                       disk (sum 1)
        line:len=41,width=1,theta=30    motion blur (sum 1)

    or a kernel array (odd height and width, centre in the middle, used as is).
    ``tol`` is the target relative L2 error; ``max_terms`` caps the terms;
    the keyword options are those of the CLI (``--levels``, ``--alpha``,
    ``--oversample``, ``--min-sigma``, ``--margin``).

    >>> d = decompose("gauss:sx=6,sy=2,theta=30")
    >>> d.report["rel_l2_error"] <= 0.01
    True
    """
    kw = dict(
        tol=tol,
        max_terms=max_terms,
        levels=levels,
        alpha=alpha,
        oversample=oversample,
        min_sigma=min_sigma,
        margin=margin,
    )
    if isinstance(spec_or_kernel, str):
        return _ifd.decompose_filter(spec_or_kernel, None, **kw)
    kernel = _np.ascontiguousarray(_np.asarray(spec_or_kernel), dtype=_np.float64)
    return _ifd.decompose_filter(None, kernel, **kw)


def load(path: _Union[str, _os.PathLike]) -> Decomposition:
    """Read a decomposition file written by ``ifd decompose`` or :meth:`Decomposition.save`."""
    return Decomposition.load(_os.fspath(path))


def filter(  # noqa: A001 (the name users expect, as cv2.filter2D's role)
    image: _ArrayLike,
    decomposition: _Union[Decomposition, str, _ArrayLike, _Sequence[_Union[Decomposition, str, _ArrayLike]]],
    angle: _Field = 0.0,
    scale: _Field = 1.0,
    border: str = "reflect101",
    *,
    interp: str = "auto",
    eval_budget: _Optional[float] = None,
    tol: float = 0.01,
    sigma_map: _Optional[_ArrayLike] = None,
    filter_map: _Optional[_ArrayLike] = None,
) -> _np.ndarray:
    """Filter ``image`` with ``decomposition`` rotated by ``angle`` and scaled by ``scale``.

    ``decomposition`` is a :class:`Decomposition`, or the filter itself: a
    spec such as ``"gauss:sx=16,sy=2,theta=30"`` or an odd-sized 2D kernel
    array (used as given: a kernel that does not sum to 1 changes the
    brightness), fitted at ``tol`` on first use and kept in the fit cache
    shared with ``ifd filter --kernel`` (``$IFD_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/ifd``, else ``~/.cache/ifd``), so that the next call
    with the same filter reads it back.

    ``angle`` (degrees, counter-clockwise on screen) and ``scale`` are numbers
    or per-pixel ``(H, W)`` maps. Each output pixel is
    ``sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t)``: one lookup per term
    into a stack prefiltered once by FFT, whatever the filter's size. The
    same steps as ``ifd filter`` (bitwise equal results). ``border`` is
    ``reflect101``, ``replicate``, ``wrap``, ``constant`` or
    ``constant:VALUE``. ``interp``/``eval_budget`` are the CLI's ``--interp``
    and ``--eval-budget``.

    With ``sigma_map`` (and ``decomposition="gauss"``, the only kernel it
    takes), each pixel gets its own normalised anisotropic Gaussian: an
    ``(H, W, 3)`` array of the standard deviation along the major axis, the
    one along the minor axis (pixels, ``0 < minor <= major``) and the major
    axis' angle in degrees counter-clockwise on screen; ``angle`` and
    ``scale`` must be left out. ``ifd filter --kernel gauss --sigma-map``
    (bitwise equal results), with the aspect bank ``ifd smooth`` uses.

    With ``filter_map``, ``decomposition`` is a list of filters (each a
    :class:`Decomposition`, a spec or a kernel array) and each pixel is
    filtered by the one ``filter_map`` gives it: an ``(H, W)`` array of labels
    (each pixel's filter number, counted from 0 in the list's order) or an
    ``(H, W, N)`` array of one weight per filter (the output the weighted
    sum). The image is prefiltered once for all of them; ``ifd filter
    --decomp ... --filter-map`` (bitwise equal results).

    Returns float32 of the image's shape.

    >>> import numpy as np
    >>> img = np.random.default_rng(0).random((64, 64), dtype=np.float32)
    >>> out = filter(img, "gauss:sx=4,sy=1,theta=30", angle=15.0)
    >>> out.shape
    (64, 64)
    >>> halves = (np.arange(64) >= 32).astype(np.float32)[None, :].repeat(64, axis=0)
    >>> filter(img, ["gauss:sx=4,sy=1", "gauss:sx=2,sy=2"], angle=15.0, filter_map=halves).shape
    (64, 64)
    """
    img = _image(image, "image")
    if filter_map is not None:
        if sigma_map is not None:
            raise ValueError("filter_map and sigma_map: give one of them")
        if isinstance(decomposition, (str, Decomposition)) or not isinstance(decomposition, (list, tuple)):
            raise ValueError("filter_map: give the filters as a list, one per label or weight")
        filters = [_as_decomposition(d, tol) for d in decomposition]
        fmap = _np.ascontiguousarray(_np.asarray(filter_map, dtype=_np.float32))
        return _ifd.filter_set(img, filters, fmap, **_pose(angle, scale, border, interp, eval_budget))
    if sigma_map is not None:
        if not (isinstance(decomposition, str) and decomposition == "gauss"):
            raise ValueError(
                f"sigma_map: the only kernel it takes is 'gauss', not {decomposition!r}"
            )
        if not (isinstance(angle, (int, float)) and angle == 0.0) or not (
            isinstance(scale, (int, float)) and scale == 1.0
        ):
            raise ValueError("sigma_map: angle and scale come from the map; leave them out")
        m = _np.ascontiguousarray(_np.asarray(sigma_map, dtype=_np.float32))
        return _ifd.filter_sigma_map(img, m, border=border)
    decomposition = _as_decomposition(decomposition, tol)
    return _ifd.filter(img, decomposition, **_pose(angle, scale, border, interp, eval_budget))


def _pose(angle, scale, border, interp, eval_budget) -> dict:
    """The keyword arguments of ``_ifd.filter`` and ``_ifd.filter_set``."""
    a, amap = _field(angle, "angle")
    s, smap = _field(scale, "scale")
    return dict(angle=a, angle_map=amap, scale=s, scale_map=smap, border=border, interp=interp,
                eval_budget=eval_budget)


def _as_decomposition(d, tol: float) -> Decomposition:
    """A filter argument as a decomposition: a spec or a kernel array is
    fitted at ``tol`` (or read from the fit cache)."""
    if isinstance(d, Decomposition):
        return d
    if isinstance(d, str):
        return _ifd.fit_cached(d, None, tol=tol)
    kernel = _np.ascontiguousarray(_np.asarray(d), dtype=_np.float64)
    return _ifd.fit_cached(None, kernel, tol=tol)


def hessian(image: _ArrayLike, sigma: float, border: str = "reflect101") -> _np.ndarray:
    """The Hessian of the image (channel mean) at scale ``sigma``, computed with IFD.

    Returns ``(H, W, 3)`` float32 with channels ``(Hxx, Hxy, Hyy)``, ``x`` the
    column, not scale-normalised, as ``ifd hessian``. Equals
    ``skimage.feature.hessian_matrix(img, sigma, mode='mirror',
    use_gaussian_derivatives=True)``, whose order is ``(Hrr, Hrc, Hcc) =
    (Hyy, Hxy, Hxx)``, to the decomposition's accuracy.
    """
    return _ifd.hessian(_image(image, "image"), float(sigma), border=border)


def smooth(
    image: _ArrayLike,
    sigma: float,
    max_aspect: float = 8.0,
    mode: str = "per-pixel",
    *,
    gamma: float = 1.0,
    epsilon: float = 0.02,
    hessian_sigma: _Optional[float] = None,
    strength: float = 1.0,
    border: str = "reflect101",
) -> _np.ndarray:
    """Edge-respecting anisotropic smoothing driven by the image Hessian (``ifd smooth``).

    The Gaussian's footprint is fixed by ``sigma`` (``sx * sy = sigma^2``,
    0.5 to 128 px: the standard deviation of the isotropic Gaussian whose
    noise reduction it matches; ``ifd smooth --sigma``); its aspect ratio grows from 1 in flat areas to
    ``max_aspect`` along strong, straight structures. ``mode`` is
    ``per-pixel`` (each pixel's own filter) or ``dab`` (the paper's brush dabs
    on a grid, blended). The filter decompositions are fitted on the first
    call (a few seconds) and kept for the process.
    """
    return _ifd.smooth(
        _image(image, "image"),
        float(sigma),
        max_aspect=max_aspect,
        gamma=gamma,
        epsilon=epsilon,
        hessian_sigma=hessian_sigma,
        strength=strength,
        mode=mode,
        border=border,
    )


def compare(
    a: _ArrayLike, b: _ArrayLike, data_range: _Optional[float] = None, *, crop_border: int = 0
) -> dict:
    """PSNR, SSIM and error statistics of ``b`` against the reference ``a`` (``ifd compare --json``).

    Defined exactly as scikit-image's ``peak_signal_noise_ratio`` and
    ``structural_similarity(gaussian_weights=True, sigma=1.5,
    use_sample_covariance=False)``. ``data_range`` defaults to 1 when both
    images lie in ``[0, 1]``, else ``max - min`` of ``a``. Identical images
    have ``psnr`` None and ``identical`` True. Per-channel numbers are in
    ``channels``.
    """
    return _ifd.compare(
        _image(a, "a"), _image(b, "b"), data_range=data_range, crop_border=crop_border
    )


def last_call_seconds() -> float:
    """Seconds the last :func:`filter`, :func:`hessian` or :func:`smooth` call spent in Rust."""
    return _ifd.last_call_seconds()


from . import sphere  # noqa: E402  (after the planar API it shares helpers with)
