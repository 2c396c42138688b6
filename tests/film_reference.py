"""The film model of ``imgform_rs.film`` written again in plain NumPy.

An independent reference for the tests (the Rust kernels must agree with it)
and the peer of ``benchmarks/film.py``: what a straightforward NumPy
simulator of the same model does, chunked so that its (pixels, L) spectra
fit in memory. It reads the stock's data but none of the package's kernels:
curves by ``np.interp`` on the stated samples, DIR pre-correction by
inverting ``u(x) = x - Σ A D(x)`` with ``np.interp``, blur by shifted sums of
a reflect-padded array, Beer-Lambert with ``10 **``.
"""

from __future__ import annotations

import numpy as np

from imgform_rs import film

#: Pixels per chunk of the spectral steps: 2^18 x 41 float64 is 86 MB.
CHUNK = 1 << 18


def gaussian_taps(sigma: float) -> np.ndarray:
    """Normalised Gaussian taps, centre first, out to 3 sigma."""
    k = np.arange(int(np.ceil(3 * sigma)) + 1)
    raw = np.exp(-0.5 * (k / sigma) ** 2)
    return raw / (raw[0] + 2 * raw[1:].sum())


def blur(planes: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur of (H, W, n) with mirrored edges."""
    taps = gaussian_taps(sigma)
    r = len(taps) - 1
    out = planes
    for axis in (1, 0):
        pad = [(0, 0)] * 3
        pad[axis] = (r, r)
        p = np.pad(out, pad, mode="reflect")
        n = out.shape[axis]
        out = sum(
            w
            * (
                np.take(p, range(r - t, r - t + n), axis)
                + np.take(p, range(r + t, r + t + n), axis)
            )
            if t
            else w * np.take(p, range(r, r + n), axis)
            for t, w in enumerate(taps)
        )
    return out


def develop(exposure: np.ndarray, stock: film.Stock, frame_width_mm: float = 36.0) -> np.ndarray:
    """Densities of exposures (H, W, n), with the stock's halation and couplers."""
    pixel_um = frame_width_mm * 1000.0 / exposure.shape[1]
    exposure = exposure.astype(np.float64)
    if stock.halation.any():
        a = stock.halation
        exposure = (1 - a) * exposure + a * blur(exposure, stock.halation_um / pixel_um)
    logh = np.log10(np.maximum(exposure, 1e-30))
    layers = stock.layers
    dens = np.stack([lay.curve(logh[..., i]) for i, lay in enumerate(layers)], -1)
    a = stock.coupler_matrix
    if not a.any():
        return dens
    mins = np.array([lay.density.min() for lay in layers])
    sigma = stock.coupler_diffusion_um / pixel_um
    donors = dens - mins
    if sigma > 0:
        donors = blur(donors, sigma)
    inhibited = logh - donors @ a.T
    out = np.empty_like(dens)
    for i, lay in enumerate(layers):
        x = lay.log_exposure
        stated = np.stack([other.curve(x) - m for other, m in zip(layers, mins, strict=True)], -1)
        u = x - stated @ a[i]
        out[..., i] = np.interp(inhibited[..., i], u, lay.density)
    return out


def transmit(density: np.ndarray, stock: film.Stock, response: np.ndarray) -> np.ndarray:
    """``Σ 10^-D(λ) R(λ)`` for densities (H, W, n) and responses (m, L)."""
    masks = np.array([lay.mask_density for lay in stock.layers])
    dyes = np.array([lay.dye_density for lay in stock.layers]) - masks
    base = stock.base_density + stock.dye_max @ masks
    flat = density.reshape(-1, density.shape[-1])
    out = np.empty((len(flat), len(response)))
    for s in range(0, len(flat), CHUNK):
        out[s : s + CHUNK] = 10.0 ** -(base + flat[s : s + CHUNK] @ dyes) @ response.T
    return out.reshape(*density.shape[:-1], len(response))


def negative_print(rgb: np.ndarray, negative: film.Stock, paper: film.Stock) -> np.ndarray:
    """Linear sRGB -> the print's paper densities, balanced for mid grey."""
    exposure = rgb @ film.exposure_matrix(negative).T
    neg = develop(exposure, negative)
    fil = film.balance_print(negative, paper)
    filters = np.array([fil.yellow, fil.magenta, fil.cyan]) @ film.dichroic_filters(
        negative.wavelengths
    )
    light = fil.exposure * film._print_light(negative, paper) * 10.0**-filters
    return develop(transmit(neg, negative, light), paper)
