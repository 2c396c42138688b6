"""Demosaicing and development of one huge mosaic held as a ``dask.array``.

Each chunk is demosaiced with a margin of neighbouring pixels
(``map_overlap``-style: overlap, run, trim) at least as wide as the method's
reach (:func:`imgform_rs.demosaic_halo`), so its interior sees exactly the pixels the
whole-image call sees. At the true image edges no margin is added: the chunk
starts at the edge, and the Rust kernel mirrors there just as it does for the
whole image. Chunk boundaries sit on multiples of the CFA period, so every
chunk has the pattern of the whole mosaic.

Two results also depend on the whole image, not on a neighbourhood: the
clamping methods (RCD, Menon, AHD) clamp to the mosaic's range, and the
development takes the brightest value of each CFA site as a white-level hint.
Both are functions of the per-site minima and maxima, so those are reduced
over the whole array first and written into the outermost rows (or columns)
of each chunk's margin: cells farther than the halo from every kept pixel,
which therefore change nothing but the range each chunk's call sees. That
makes every chunk's range the global one, and the result identical bit for
bit to the whole-image call.
"""

from __future__ import annotations

import dataclasses
import inspect
import itertools
import math
from typing import Any

import numpy as np

from . import _native, _samples
from .cfa import as_pattern, pattern_cells
from .demosaic import demosaic, demosaic_halo
from .develop import (
    _GREY_BLOCK,
    DEFAULT_DEMOSAIC,
    _grey_multipliers,
    _grey_sums,
    _white_range,
    develop,
)
from .raw import RawImage


def require_dask() -> Any:
    """``dask.array``, or an ImportError that names the extra to install."""
    try:
        import dask.array as da
    except ImportError as exc:
        raise ImportError(
            "this needs Dask, an optional dependency: pip install imgform-rs[dask]"
        ) from exc
    return da


def snap_chunks(chunks: tuple[int, ...], step: int, minimum: int) -> tuple[int, ...]:
    """Chunk sizes along one axis with every boundary on a multiple of
    ``step`` and every chunk at least ``minimum`` long (a neighbour's margin
    is taken from a single chunk), keeping the requested sizes roughly."""
    n = sum(chunks)
    cuts, last = [], 0
    for edge in np.cumsum(chunks)[:-1]:
        cut = round(int(edge) / step) * step
        if cut - last >= minimum and n - cut >= minimum:
            cuts.append(cut)
            last = cut
    bounds = [0, *cuts, n]
    return tuple(int(b - a) for a, b in itertools.pairwise(bounds))


def phase_extremes(mosaic: Any, period: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-site minima and maxima, each a ``(period, period)`` array.

    A NaN or an infinity anywhere shows in them (plain ``min``/``max``
    propagate NaN), so this pass over the whole mosaic, made anyway, also
    refuses a non-finite sample before any worker runs: a ValueError naming
    its row and column in the whole mosaic, as :func:`imgform_rs.demosaic`
    would (a worker would only know them within its chunk)."""
    import dask

    da = require_dask()
    cells = [(i, j) for i in range(period) for j in range(period)]
    reductions = [f(mosaic[i::period, j::period]) for i, j in cells for f in (da.min, da.max)]
    values = np.array(dask.compute(*reductions), mosaic.dtype).reshape(period, period, 2)
    if not np.isfinite(values).all():
        y, x = _first_bad(mosaic, lambda b: ~np.isfinite(b))
        value = float(mosaic[y, x].compute())
        raise ValueError(
            "the mosaic must hold finite numbers, got "
            f"{'NaN' if math.isnan(value) else value} at row {y}, column {x}"
        )
    # Beyond float32's range is check_range's to refuse, as demosaic does.
    if _native.DEMOSAIC_SAMPLE_LIMIT < np.abs(values.astype(np.float64)).max() <= _samples.F32_MAX:
        y, x = _first_bad(mosaic, lambda b: np.abs(b) > _native.DEMOSAIC_SAMPLE_LIMIT)
        raise ValueError(
            f"the mosaic's samples must lie within ±2^100, got one beyond at row {y}, column "
            f"{x} (sums of its neighbours would overflow float32)"
        )
    return values[..., 0], values[..., 1]


def _first_bad(mosaic: Any, bad_of: Any) -> tuple[int, int]:
    """Row and column of the first sample ``bad_of`` marks, in row-major
    order: the earliest of each chunk's first one (a second pass, made only
    when the extremes show there is one)."""

    def first(block: np.ndarray, block_info: Any = None) -> np.ndarray:
        (y0, _), (x0, _) = block_info[0]["array-location"]
        bad = bad_of(block)
        i = int(np.argmax(bad))
        hit = divmod(i, block.shape[1]) if bad.flat[i] else (np.inf, np.inf)
        return np.array([[[y0 + hit[0], x0 + hit[1]]]], np.float64)

    hits = mosaic.map_blocks(first, new_axis=2, chunks=(1, 1, 2), dtype=np.float64).compute()
    y, x = min(map(tuple, hits.reshape(-1, 2)))
    return int(y), int(x)


def _with_extremes(block: np.ndarray, extremes: tuple, period: int, side: str) -> np.ndarray:
    """``block`` with the per-site minima and maxima written into its
    outermost ``2 * period`` rows (or columns) on ``side``. Both ends of a
    margin are multiples of the period, so each value lands on its own site."""
    if side == "none":
        return block
    out = block.copy()
    lo, hi = extremes
    # Columns are handled as the rows of the transposed view.
    across = side in ("left", "right")
    view, lo, hi = (out.T, lo.T, hi.T) if across else (out, lo, hi)
    p = period
    start = 0 if side in ("top", "left") else view.shape[0] - 2 * p
    view[start : start + p, :p] = lo
    view[start + p : start + 2 * p, :p] = hi
    return out


def _margin_side(loc: tuple[int, int], num: tuple[int, int]) -> str:
    """A side of the block that has a margin, or "none" for a lone block."""
    for axis, (before, after) in enumerate((("top", "bottom"), ("left", "right"))):
        if loc[axis] > 0:
            return before
        if loc[axis] < num[axis] - 1:
            return after
    return "none"


def map_cfa(mosaic: Any, period: int, halo: int, step: int, block_fn: Any, dtype: Any) -> Any:
    """Runs ``block_fn(block) -> (h, w, 3)`` over overlapping chunks of the
    mosaic (margins of the halo plus the extremes' rows) and trims them."""
    da = require_dask()
    depth = math.ceil((halo + 2 * period) / period) * period
    chunks = tuple(snap_chunks(c, step, depth) for c in mosaic.chunks)
    if chunks != mosaic.chunks:
        mosaic = mosaic.rechunk(chunks)
    extremes = phase_extremes(mosaic, period)
    # Other dtypes are converted block by block (elementwise, so the chunks
    # still agree bit for bit); their range is checked here, before any worker.
    _samples.check_range(extremes[0].min(), extremes[1].max(), mosaic.dtype, "mosaic")

    def run(block: np.ndarray, block_info: Any = None) -> np.ndarray:
        info = block_info[0]
        side = _margin_side(info["chunk-location"], info["num-chunks"])
        return block_fn(_with_extremes(block, extremes, period, side))

    # An axis in one chunk has no neighbour to borrow from (and may be
    # shorter than the margin).
    depths = {axis: depth if len(c) > 1 else 0 for axis, c in enumerate(chunks)}
    padded = da.overlap.overlap(mosaic, depth=depths, boundary="none")
    rgb = padded.map_blocks(
        run, new_axis=2, chunks=(*padded.chunks, (3,)), dtype=dtype, meta=np.empty((0, 0, 0), dtype)
    )
    return da.overlap.trim_internal(rgb, {**depths, 2: 0}, boundary="none")


def _check_mosaic(mosaic: Any, dtypes: tuple | None) -> None:
    """Refuses what is not a 2-D dask array of ``dtypes`` (None: any dtype
    :func:`imgform_rs.demosaic` takes)."""
    da = require_dask()
    if not isinstance(mosaic, da.Array):
        raise TypeError(f"mosaic must be a dask.array.Array, got {type(mosaic).__name__}")
    if mosaic.ndim != 2:
        raise ValueError(f"mosaic must have shape (H, W), got shape {mosaic.shape}")
    if any(math.isnan(c) for axis in mosaic.chunks for c in axis):
        # Boolean indexing and the like leave sizes Dask learns only by computing.
        raise ValueError(
            f"mosaic has unknown chunk sizes, got chunks {mosaic.chunks}; call "
            "mosaic.compute_chunk_sizes() first"
        )
    if dtypes is None:
        _samples.check_dtype(mosaic.dtype, "mosaic")
    elif mosaic.dtype not in dtypes:
        names = ", ".join(np.dtype(t).name for t in dtypes)
        raise TypeError(f"mosaic must be {names}, got dtype {mosaic.dtype}")


def demosaic_dask(
    mosaic: Any, pattern: Any, method: str = "bilinear", *, white_level: float | None = None
) -> Any:
    """:func:`imgform_rs.demosaic` for a ``dask.array`` mosaic, chunk by chunk.

    The result equals ``demosaic(mosaic.compute(), pattern, method,
    white_level=white_level)`` bit for bit, for any chunking: every chunk sees
    the mosaic's extremes, so also its default white level. Chunk boundaries
    are moved to multiples of the CFA period (2 for Bayer, 6 for X-Trans) and
    chunks shorter than the margin are merged with a neighbour. The per-site
    minima and maxima are computed at once (one pass over the mosaic, which
    also finds a NaN or an infinity before any worker runs); the demosaic
    itself stays lazy.

    Parameters
    ----------
    mosaic : dask.array.Array, shape (H, W), integer or float
        Any dtype :func:`imgform_rs.demosaic` takes, converted as it says.
    pattern : str or array_like
        As for :func:`imgform_rs.demosaic`.
    method : str
        One of :data:`imgform_rs.DEMOSAIC_METHODS`.
    white_level : float, optional
        As for :func:`imgform_rs.demosaic`.

    Returns
    -------
    dask.array.Array, shape (H, W, 3), same dtype

    Raises
    ------
    ImportError
        Without Dask (``pip install imgform-rs[dask]``).
    TypeError
        For something other than a dask array of a supported dtype, a
        method that is not a str, or a white level that is not a number.
    ValueError
        For another shape, a mosaic smaller than one CFA tile, unknown chunk
        sizes (call ``compute_chunk_sizes()`` first), an unknown method or
        pattern, a white level :func:`imgform_rs.demosaic` refuses, or a NaN
        or an infinity (the message names the first one's row and column in
        the whole mosaic).

    Examples
    --------
    >>> import dask.array as da
    >>> raw = da.from_array(np.arange(400, dtype=np.uint16).reshape(20, 20), chunks=7)
    >>> out = demosaic_dask(raw, "RGGB", "malvar2004")
    >>> bool((out.compute() == demosaic(raw.compute(), "RGGB", "malvar2004")).all())
    True
    """
    _check_mosaic(mosaic, None)
    if not isinstance(method, str):
        raise TypeError(f"method must be a str, got {method!r}")
    pat = as_pattern(pattern)
    period = pattern_cells(pat).shape[0]
    halo = demosaic_halo(method, pat)
    if min(mosaic.shape) < period:
        raise ValueError(
            f"demosaic_dask needs a mosaic of at least one full CFA tile, {period}x{period} "
            f"pixels, got {mosaic.shape}"
        )
    # Fail now, not in a worker: one tile through the native checks refuses
    # a method that cannot demosaic this pattern (X-Trans).
    demosaic(np.zeros((6, 6), mosaic.dtype), pat, method, white_level=white_level)

    def block_fn(block: np.ndarray) -> np.ndarray:
        return demosaic(block, pat, method, white_level=white_level)

    return map_cfa(mosaic, period, halo, period, block_fn, mosaic.dtype)


_DEVELOP_OPTIONS = set(inspect.signature(develop).parameters) - {"source", "orientation"}
"""The keywords :func:`develop_dask` passes on to :func:`imgform_rs.develop`."""


def _grey_world(raw: RawImage, cfa: Any) -> np.ndarray:
    """LibRaw's grey-world multipliers reduced over the chunks of ``cfa``."""
    white = _white_range(raw)

    def partial(block: np.ndarray, block_info: Any = None) -> np.ndarray:
        (y0, _), (x0, _) = block_info[0]["array-location"]
        return _grey_sums(block, raw, y0, x0, white)[None, None]

    sums = cfa.map_blocks(partial, new_axis=(2, 3), chunks=(1, 1, 4, 2), dtype=np.float64)
    return _grey_multipliers(sums.sum(axis=(0, 1)).compute())


def _orient_lazy(rgb: Any, flip: int) -> Any:
    """LibRaw's flip code on a dask array: columns, rows, then transpose."""
    if flip & 1:
        rgb = rgb[:, ::-1]
    if flip & 2:
        rgb = rgb[::-1]
    return rgb.transpose(1, 0, 2) if flip & 4 else rgb


def develop_dask(
    raw: RawImage, *, chunks: Any = 2048, orientation: str = "auto", **develop_kwargs: Any
) -> Any:
    """:func:`imgform_rs.develop` for one huge raw, chunk by chunk.

    Identical bit for bit to ``develop(raw, ...)``. The global quantities are
    reduced over the whole mosaic first: the per-site extremes (white-level
    hint and demosaic range) and, for ``white_balance="auto"`` or a file
    without an as-shot balance, LibRaw's grey world; then every chunk is
    developed with those.

    Parameters
    ----------
    raw : RawImage
        From :func:`imgform_rs.load_raw`; its ``cfa`` may be a NumPy array or
        a ``dask.array`` (then its chunks are kept, snapped as below).
    chunks : int or tuple
        Chunk shape for a NumPy ``cfa``; boundaries move to multiples of 8
        (24 for X-Trans).
    orientation : {"auto", "none"}
    **develop_kwargs
        ``demosaic``, ``white_balance``, ``color``, ``tone``, ``exposure``,
        ``highlights``, ``bps`` as for :func:`imgform_rs.develop`, checked
        here, before any chunk is developed. ``lens_correction`` only
        ``"off"`` (or None): vignetting and distortion are functions of the
        whole image's coordinates, and distortion reads pixels far beyond a
        chunk's margin, so a chunk cannot be corrected on its own; use
        :func:`imgform_rs.develop` for a corrected picture.

    Returns
    -------
    dask.array.Array, shape (H, W, 3), uint8 / uint16 / float32

    Raises
    ------
    TypeError
        For something other than a RawImage, or an option
        :func:`imgform_rs.develop` does not have.
    ValueError
        For non-square photosites (``pixel_aspect != 1``), ``exposure="auto"``,
        lens corrections, or options that :func:`imgform_rs.develop` refuses.

    Examples
    --------
    >>> import tempfile
    >>> from imgform_rs import load_raw
    >>> from imgform_rs.dng import write_dng
    >>> cfa = (np.arange(48 * 40) % 3000 + 100).astype(np.uint16).reshape(48, 40)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_dng(f"{d}/a.dng", cfa, "RGGB", white_level=4095, black_level=64)
    ...     raw = load_raw(f"{d}/a.dng")
    >>> out = develop_dask(raw, chunks=16, white_balance="auto").compute()
    >>> bool((out == develop(raw, white_balance="auto")).all())
    True
    """
    da = require_dask()
    if not isinstance(raw, RawImage):
        raise TypeError(f"raw must be a RawImage (see load_raw), got {type(raw).__name__}")
    if raw.pixel_aspect != 1:
        raise ValueError(
            f"develop_dask needs square photosites, got pixel_aspect {raw.pixel_aspect}; "
            "use develop for such (small, old) sensors"
        )
    if orientation not in ("auto", "none"):
        raise ValueError(f'orientation must be "auto" or "none", got {orientation!r}')
    exposure = develop_kwargs.get("exposure")
    if isinstance(exposure, str) and exposure == "auto":
        # Each chunk would brighten by its own histogram.
        raise ValueError(
            'develop_dask takes exposure in stops; exposure="auto" needs the whole '
            "image's histogram: use develop"
        )
    unknown = sorted(set(develop_kwargs) - _DEVELOP_OPTIONS)
    if unknown:
        raise TypeError(
            f"develop_dask got unknown options {unknown}; it takes {sorted(_DEVELOP_OPTIONS)}"
        )
    lens = develop_kwargs.get("lens_correction", "off")
    if lens is not None and not (isinstance(lens, str) and lens == "off"):
        # Each chunk would be corrected as if it were a whole image centred on itself.
        given = repr(lens) if isinstance(lens, str) else f"a {type(lens).__name__}"
        raise ValueError(
            f'develop_dask takes lens_correction="off" only, got {given}: vignetting and '
            "distortion are functions of the whole image's coordinates, and distortion "
            "reads pixels far beyond a chunk's margin; use develop(raw, "
            "lens_correction=...) for a corrected picture"
        )
    period = raw.channel_tile.shape[0]
    step = math.lcm(period, _GREY_BLOCK)
    # Fail now, not in a worker: develop checks every option against this
    # raw's metadata, and one tile of photosites develops in 1-2 ms. Its
    # dtype is the output's.
    tile = dataclasses.replace(raw, cfa=np.zeros((step, step), np.uint16))
    dtype = develop(tile, orientation="none", **develop_kwargs).dtype
    sizes = chunks if isinstance(chunks, tuple) else (chunks,)
    if any(isinstance(n, (int, np.integer)) and n == 0 for n in sizes):
        # Dask divides by it: a ZeroDivisionError that names nothing.
        raise ValueError(f"chunks must be sizes > 0 (or -1 for a whole axis), got {chunks!r}")
    cfa = raw.cfa if isinstance(raw.cfa, da.Array) else da.from_array(raw.cfa, chunks=chunks)
    _check_mosaic(cfa, (np.uint16,))
    cfa = cfa.rechunk(tuple(snap_chunks(c, step, 1) for c in cfa.chunks))
    meta: dict[str, Any] = {"flip": 0, "pixel_aspect": 1.0}
    wb = develop_kwargs.get("white_balance", "camera")
    no_shot = isinstance(wb, str) and wb == "camera" and raw.camera_white_balance[0] <= 1e-5
    if (isinstance(wb, str) and wb == "auto") or no_shot:
        # The chunks get the global balance as their "as shot" one.
        meta["camera_white_balance"] = _grey_world(raw, cfa)
        develop_kwargs["white_balance"] = "camera"
    template = dataclasses.replace(raw, cfa=np.zeros((0, 0), np.uint16), **meta)
    method = develop_kwargs.get("demosaic", DEFAULT_DEMOSAIC)
    halo = demosaic_halo(method, raw.pattern)

    def block_fn(block: np.ndarray) -> np.ndarray:
        chunk = dataclasses.replace(template, cfa=block)
        return develop(chunk, orientation="none", **develop_kwargs)

    rgb = map_cfa(cfa, period, halo, step, block_fn, dtype)
    return _orient_lazy(rgb, raw.flip) if orientation == "auto" else rgb
