"""The scanning frame of an aligned glass plate: which outer rows and columns
are scanner border, margin or the frame lines of the three exposures.

Only the outer ``FRAME_SEARCH`` of each side can be frame, so only those bands
are read at full resolution along the side's normal; along the side they are
sampled every ``step`` pixels, and the statistics of the whole plate (the
percentile stretch, the median row's disagreement) come from a grid of one
pixel in ``step x step``. ``step`` keeps ~``GRID_SIDE`` samples across the
shorter side, so a full-resolution plate costs about as much as a 256-pixel
thumbnail while every crop decision is still made per full-resolution row.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: Fraction of each side inspected for the scanning frame: the black border
#: and white margin of the published scans stay within the outer ~6 % of a
#: channel.
FRAME_SEARCH = 0.08

#: Samples kept across the shorter side for the plate-wide statistics and
#: along each band: a row of 256 samples estimates a mean or a quartile to
#: ~1/16 of its spread, far finer than the thresholds below.
GRID_SIDE = 256

#: Mean level (after the 1st..99th percentile stretch) below which a row is
#: scanner border, and above which it is the white margin.
DARK, BRIGHT = 0.1, 0.95

#: How far the 75th percentile of a row's channel disagreement may exceed the
#: median row's before the row counts as misregistered frame lines.
DISAGREEMENT = 0.05


def _stretch(grid: np.ndarray) -> tuple[float, float]:
    """Offset and scale mapping the 1st..99th percentiles of ``grid`` to 0..1."""
    lo, hi = np.percentile(grid, [1, 99])
    return float(lo), 1.0 / max(float(hi - lo), 1e-12)


def _band(chans: Sequence[np.ndarray], stretch, rows: slice, cols: slice) -> np.ndarray:
    """The stretched channels over ``rows x cols``, shape (3, h, w), float32."""
    return np.stack(
        [
            (c[rows, cols].astype(np.float32) - lo) * scale
            for c, (lo, scale) in zip(chans, stretch, strict=True)
        ]
    )


def _level_and_spread(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel: the channels' mean, and their mean absolute deviation from it."""
    mean = n.mean(axis=0)
    return mean, np.abs(n - mean).mean(axis=0)


def _frame_rows(n: np.ndarray, median_disagreement: float) -> np.ndarray:
    """Which rows of a band (3, rows, samples), outermost row first, are frame."""
    mean, spread = _level_and_spread(n)
    level = mean.mean(axis=1)
    disagree = np.percentile(spread, 75, axis=1)
    return (level < DARK) | (level > BRIGHT) | (disagree - median_disagreement > DISAGREEMENT)


def _depth(frame_rows: np.ndarray) -> int:
    """Rows to cut: up to and including the innermost frame row."""
    bad = np.flatnonzero(frame_rows)
    return int(bad[-1]) + 1 if bad.size else 0


def frame_box(rgb: np.ndarray) -> tuple[int, int, int, int]:
    """The rows ``top:bottom`` and columns ``left:right`` of an aligned plate
    ``rgb`` (H, W, 3) that lie inside the scanning frame.

    Each channel is stretched so its 1st..99th percentiles span 0..1; a
    pixel's disagreement is the mean absolute difference of its channels from
    their mean. Within the outer ``FRAME_SEARCH`` of each side, a row
    (column) counts as frame when its mean level is near black (< 0.1) or near
    white (> 0.95) (the scanner's border and margin), or when the 75th
    percentile of its disagreement exceeds the median row's by more than 0.05
    (where the frame lines and damaged edges of the three exposures fall
    apart after alignment, leaving coloured stripes). The crop keeps what
    lies inside the innermost such row. Scene content rarely trips this: a bright sky is
    below 0.95 after the stretch and its channels agree.
    """
    return channels_frame_box([rgb[..., c] for c in range(3)])


def channels_frame_box(chans: Sequence[np.ndarray]) -> tuple[int, int, int, int]:
    """:func:`frame_box` of three aligned (H, W) channels given apart (views
    of a plate need not be stacked first)."""
    h, w = chans[0].shape
    step = max(1, min(h, w) // GRID_SIDE)
    grid = [c[::step, ::step].astype(np.float32) for c in chans]
    stretch = [_stretch(g) for g in grid]
    _, spread = _level_and_spread(
        np.stack([(g - lo) * s for g, (lo, s) in zip(grid, stretch, strict=True)])
    )
    median_rows = float(np.median(np.percentile(spread, 75, axis=1)))
    median_cols = float(np.median(np.percentile(spread, 75, axis=0)))
    by, bx = int(FRAME_SEARCH * h), int(FRAME_SEARCH * w)
    every = slice(None, None, step)

    def rows_depth(rows: slice) -> int:
        return _depth(_frame_rows(_band(chans, stretch, rows, every), median_rows))

    def cols_depth(cols: slice) -> int:
        band = _band(chans, stretch, every, cols).transpose(0, 2, 1)
        return _depth(_frame_rows(band, median_cols))

    top = rows_depth(slice(0, by))
    bottom = h - rows_depth(_from_far_side(h, by))
    left = cols_depth(slice(0, bx))
    right = w - cols_depth(_from_far_side(w, bx))
    return top, bottom, left, right


def _from_far_side(size: int, n: int) -> slice:
    """The last ``n < size`` indices of an axis, outermost first."""
    return slice(size - 1, size - 1 - n, -1)
