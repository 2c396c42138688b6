"""Finishing a colourised plate: white balance and contrast stretch.

The three exposures of a glass plate were developed and scanned with
different densities, so the stacked channels rarely have a neutral balance or
use the full range. Both corrections are global affine maps per channel,
estimated on a grid of ~``GRID_SIDE`` samples across the shorter side (a
percentile of 10 million pixels is no better than one of 100 thousand).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ._arrays import real, require_finite

GRID_SIDE = 512


def auto_balance(
    rgb: Any, *, contrast: bool = True, white_balance: bool = True, clip: float = 0.005
) -> np.ndarray:
    """White-balance and contrast-stretch an (H, W, 3) colour image.

    ``white_balance`` scales each channel so its mean equals the mean of the
    three (the grey-world assumption: a scene averages to grey).
    ``contrast`` then maps the ``clip`` and ``1 - clip`` quantiles of the
    channels' mean to black and white, with one gain and offset for all
    three channels so hues do not change.

    Parameters
    ----------
    rgb : ndarray (H, W, 3), uint8, uint16 or float32
    contrast, white_balance : bool
    clip : float in [0, 0.5)
        Fraction of samples allowed to saturate at each end.

    Returns
    -------
    ndarray, same shape and dtype
        Integer images are rounded and clipped to their range; float images
        are clipped to [0, 1].

    Raises
    ------
    ValueError
        An image that is not (H, W, 3) or is empty, a NaN or infinite
        sample, or ``clip`` outside [0, 0.5).
    TypeError
        An unsupported dtype, or a ``clip`` that is not a real number.

    Examples
    --------
    >>> grey = np.repeat([[40], [200]], 2, axis=1).astype(np.float32)
    >>> img = np.stack([0.5 * grey, grey, 0.25 * grey], axis=-1).astype(np.uint8)
    >>> auto_balance(img)[:, 0]
    array([[  0,   0,   0],
           [255, 255, 255]], dtype=uint8)
    """
    img = np.asarray(rgb)
    if img.dtype not in (np.uint8, np.uint16, np.float32):
        raise TypeError(f"rgb must be uint8, uint16 or float32, got dtype {img.dtype}")
    if img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
        raise ValueError(f"rgb must be a non-empty (H, W, 3) image, got shape {img.shape}")
    # One NaN or infinity would make the means and quantiles, so every
    # channel's gain, NaN.
    require_finite(img, "rgb")
    clip = real(clip, "clip")
    if not 0 <= clip < 0.5:
        raise ValueError(f"clip must be in [0, 0.5), got {clip}")
    top = float(np.iinfo(img.dtype).max) if img.dtype.kind == "u" else 1.0
    step = max(1, min(img.shape[:2]) // GRID_SIDE)
    grid = img[::step, ::step].astype(np.float64).reshape(-1, 3)
    gain = np.ones(3)
    if white_balance:
        means = grid.mean(axis=0)
        gain = np.where(means > 0, means.mean() / np.maximum(means, 1e-12), 1.0)
    offset = 0.0
    if contrast:
        lo, hi = np.quantile((grid * gain).mean(axis=1), [clip, 1 - clip])
        if hi > lo:
            gain, offset = gain * top / (hi - lo), -lo * top / (hi - lo)
    out = img.astype(np.float32) * gain.astype(np.float32) + np.float32(offset)
    np.clip(out, 0, top, out=out)
    if img.dtype.kind == "u":
        return np.floor(out + 0.5).astype(img.dtype)
    return out
