"""Filtering images larger than one machine, or one core, with Dask.

Filtering is local: an output pixel reads the input within the filter's
reach (the farthest term centre, scaled) plus 5 of the widest term's sigma
(the Gaussian tails beyond are below 4e-6 of their peak). So an image can be
cut into chunks, each filtered with that much halo from its neighbours
(``dask.array.map_overlap``), and the pieces give the whole image's result
to about 1e-5. Three things make the pieces agree with one call:

* the halo is the filter's own (:meth:`ifd.Decomposition.halo`), rounded up
  to a multiple of the alignment below;
* chunk origins, halo included, are multiples of the coarsest subsampling
  factor of the scale stack (the ``alignment``), so every chunk's subsampled
  levels have their samples where the whole image's are;
* every chunk plans with the whole image's scale range, so all read the same
  levels.

Chunks take ``boundary='none'``: no padding is added at the image's true
edges, where each chunk's own border rule (reflect-101 by default) then acts
exactly as the whole image's does. (Dask's ``'reflect'`` repeats the edge
pixel, which is not reflect-101.) Each chunk is told its global offset and
checks its alignment.

A :class:`ifd.Decomposition` pickles (as its JSON text), so the same code runs
on a distributed cluster::

    from dask.distributed import Client
    client = Client("tcp://scheduler:8786")   # or Client() for a local cluster
    img = dask.array.from_zarr("huge.zarr")   # (H, W) or (H, W, C)
    out = ifd.dask.filter(img, d, angle=angle_map, chunks=4096)
    out.to_zarr("filtered.zarr")              # computed on the workers

Workers need ``ifd`` installed (``pip install ./crates/ifd-py``).
"""

from __future__ import annotations

from typing import Optional as _Optional, Union as _Union

import numpy as _np

from . import Decomposition as _Decomposition, _ifd, _image

# the __future__ import binds `annotations`: not part of the API
del annotations

__all__ = ["filter", "plan"]


def _round_up(n: int, a: int) -> int:
    return -(-n // a) * a


def _aligned_chunks(size: int, chunk: int, align: int, depth: int) -> tuple:
    """Chunks of an axis of ``size``: multiples of ``align``, at least ``depth`` long."""
    c = max(_round_up(chunk, align), _round_up(max(depth, 1), align))
    chunks = [c] * (size // c)
    if size % c:
        rest = size % c
        if chunks and rest < depth:
            # A last chunk shorter than the halo: merge it into the one before.
            chunks[-1] += rest
        else:
            chunks.append(rest)
    return tuple(chunks)


def _range(a) -> tuple[float, float]:
    import dask.array as da

    if isinstance(a, da.Array):
        lo, hi = da.compute(a.min(), a.max())
    else:
        arr = _np.asarray(a)
        lo, hi = arr.min(), arr.max()
    return float(lo), float(hi)


def plan(
    shape: tuple,
    decomposition: _Decomposition,
    angle_varies: bool,
    scale_range: tuple[float, float],
    border: str = "reflect101",
    *,
    interp: str = "auto",
    eval_budget: _Optional[float] = None,
) -> tuple[int, int]:
    """The ``(halo, alignment)`` of chunked filtering of an image of ``shape``.

    ``halo`` is a multiple of ``alignment``; chunk sizes must be too.
    """
    h, w = shape[0], shape[1]
    c = shape[2] if len(shape) == 3 else 1
    align = _ifd.filter_alignment(
        decomposition,
        (h, w, c),
        (float(scale_range[0]), float(scale_range[1])),
        angle_varies,
        border=border,
        interp=interp,
        eval_budget=eval_budget,
    )
    halo = _round_up(decomposition.halo(float(scale_range[1])), align)
    return halo, align


def filter(  # noqa: A001
    image,
    decomposition: _Decomposition,
    angle: _Union[float, _np.ndarray, "dask.array.Array"] = 0.0,  # noqa: F821
    scale: _Union[float, _np.ndarray, "dask.array.Array"] = 1.0,  # noqa: F821
    border: str = "reflect101",
    *,
    chunks: int = 2048,
    interp: str = "auto",
    eval_budget: _Optional[float] = None,
):
    """:func:`ifd.filter` over a Dask array: a lazy ``dask.array.Array`` of float32.

    ``image`` (numpy or Dask, ``(H, W)`` or ``(H, W, C)``) is rechunked into
    square chunks of about ``chunks`` pixels per side, aligned as the module
    docs explain; ``angle`` and ``scale`` are numbers or ``(H, W)`` maps
    (numpy or Dask), chunked alike. The result equals one ``ifd.filter``
    call to about 1e-5 of the image's range. Call ``.compute()`` (or store
    it) to run it.
    """
    import dask.array as da

    if isinstance(image, da.Array):
        img = image.astype(_np.float32) if image.dtype != _np.float32 else image
        if image.dtype == _np.uint8:
            img = img / _np.float32(255.0)
        elif image.dtype == _np.uint16:
            img = img / _np.float32(65535.0)
    else:
        img = da.from_array(_image(image, "image"), chunks=-1)
    if img.ndim not in (2, 3):
        raise ValueError(f"image: expected an (H, W) or (H, W, C) array, got shape {img.shape}")
    squeeze = img.ndim == 2
    if squeeze:
        img = img[:, :, None]
    h, w, c = img.shape

    def as_map(v, name):
        if _np.isscalar(v) or (isinstance(v, _np.ndarray) and v.ndim == 0):
            return float(v), None
        m = v if isinstance(v, da.Array) else da.from_array(_np.asarray(v), chunks=-1)
        if m.shape != (h, w):
            raise ValueError(f"{name}: the map is {m.shape} but the image is {(h, w)}")
        return None, m.astype(_np.float32)[:, :, None]

    a_const, a_map = as_map(angle, "angle")
    s_const, s_map = as_map(scale, "scale")
    s_range = (s_const, s_const) if s_map is None else _range(s_map)
    if not all(_np.isfinite(s_range)) or s_range[0] <= 0:
        raise ValueError(f"scale: the scales span {s_range}; they must be finite and positive")
    halo, align = plan(
        (h, w, c), decomposition, a_map is not None, s_range, border,
        interp=interp, eval_budget=eval_budget,
    )
    rows = _aligned_chunks(h, chunks, align, halo)
    cols = _aligned_chunks(w, chunks, align, halo)
    arrays = [img.rechunk((rows, cols, c))]
    for m in (a_map, s_map):
        if m is not None:
            arrays.append(m.rechunk((rows, cols, 1)))
    row_starts = _np.concatenate([[0], _np.cumsum(rows)])
    col_starts = _np.concatenate([[0], _np.cumsum(cols)])

    def block(*parts, block_info=None):
        # The chunk's global offset (halo included): where its stack's
        # samples are, which must be where the whole image's are.
        i, j = block_info[None]["chunk-location"][:2]
        y0 = max(int(row_starts[i]) - halo, 0)
        x0 = max(int(col_starts[j]) - halo, 0)
        if y0 % align or x0 % align:
            raise RuntimeError(
                f"ifd.dask: chunk ({i}, {j}) starts at ({y0}, {x0}), not a multiple of {align}"
            )
        tile = _np.ascontiguousarray(parts[0])
        k = 1
        amap = smap = None
        if a_map is not None:
            amap = _np.ascontiguousarray(parts[k][:, :, 0])
            k += 1
        if s_map is not None:
            smap = _np.ascontiguousarray(parts[k][:, :, 0])
        return _ifd.filter(
            tile,
            decomposition,
            angle=0.0 if a_const is None else a_const,
            angle_map=amap,
            scale=1.0 if s_const is None else s_const,
            scale_map=smap,
            border=border,
            interp=interp,
            eval_budget=eval_budget,
            scale_range=s_range,
        )

    out = da.map_overlap(
        block,
        *arrays,
        depth={0: halo, 1: halo, 2: 0},
        boundary="none",
        trim=True,
        align_arrays=False,
        dtype=_np.float32,
        meta=_np.empty((0, 0, 0), _np.float32),
    )
    return out[:, :, 0] if squeeze else out
