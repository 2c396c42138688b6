"""Dispersion: a glass's refractive index per wavelength, and the chromatic
aberrations it gives a lens (lecture sections 3.3 and 6).

A thin lens's power is proportional to ``n(λ) - 1`` (the lensmaker's equation),
so its focal length is ``f(λ) = f_d (n_d - 1) / (n(λ) - 1)``: blue, bent more,
focuses nearer the lens than red. Along the axis that is longitudinal chromatic
aberration (each wavelength defocused by its own amount, rendered through
:func:`imgform_rs.render_defocus`); across the field, lateral chromatic
aberration (each wavelength imaged at its own magnification, rendered through
:func:`imgform_rs.remap`).

A glass is given by its catalogue pair ``(n_d, V_d)`` (refractive index at the
helium d line and Abbe number), interpolated by a two-term Cauchy law, or by
its six Sellmeier coefficients, the form glass makers publish.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ._arrays import Float64Array, as_float_array, flag, real
from .optics import image_distance, render_defocus
from .remap import remap

#: Fraunhofer lines (nm) that define the Abbe number ``V_d = (n_d - 1) / (n_F - n_C)``.
LINE_D, LINE_F, LINE_C = 587.5618, 486.1327, 656.2725


def _positive(value: float, name: str) -> float:
    v = real(value, name)
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return v


@dataclass(frozen=True)
class Glass:
    """An optical glass: its refractive index at any wavelength.

    Build one with :meth:`from_abbe` (catalogue ``n_d`` and ``V_d``) or
    :meth:`from_sellmeier` (a glass maker's dispersion formula).

    Examples
    --------
    >>> bk7 = Glass.from_abbe(1.5168, 64.17)
    >>> round(float(bk7.index(LINE_D)), 6), round(bk7.abbe_number, 2)
    (1.5168, 64.17)
    """

    #: ``"cauchy"``: ``n = A + B / λ²`` (λ in µm), coefficients ``(A, B)``;
    #: ``"sellmeier"``: ``n² = 1 + Σ B_i λ² / (λ² - C_i)``, ``(B1, B2, B3, C1, C2, C3)``.
    law: str
    coefficients: tuple[float, ...]

    def __post_init__(self) -> None:
        counts = {"cauchy": 2, "sellmeier": 6}
        if self.law not in counts:
            raise ValueError(f'law must be "cauchy" or "sellmeier", got {self.law!r}')
        coeffs = as_float_array(self.coefficients, "coefficients")
        if coeffs.shape != (counts[self.law],) or not np.isfinite(coeffs).all():
            raise ValueError(
                f"a {self.law} glass needs {counts[self.law]} finite coefficients, "
                f"got {self.coefficients!r}"
            )
        if self.law == "sellmeier" and not (coeffs >= 0).all():
            # C_i are squared resonance wavelengths (µm²): never negative.
            raise ValueError(
                f"Sellmeier coefficients must be finite and >= 0, got {coeffs.tolist()}"
            )
        # Held as a tuple of floats however given: a list made the glass
        # unhashable and unequal to the same glass built from a tuple.
        object.__setattr__(self, "coefficients", tuple(coeffs.tolist()))
        # A glass bends light at the d line, where catalogues measure it:
        # an index of 1 there made focal lengths NaN.
        self.index(LINE_D)

    @classmethod
    def from_abbe(cls, n_d: float, abbe_number: float) -> Glass:
        """The Cauchy glass through ``n_d`` at the d line whose F - C index
        difference is ``(n_d - 1) / V_d``: two numbers pin the two terms."""
        n_d = real(n_d, "n_d")
        if not (np.isfinite(n_d) and n_d > 1):
            raise ValueError(f"n_d must be a refractive index > 1, got {n_d!r}")
        v_d = _positive(abbe_number, "abbe_number")
        um = 1e-3
        b = (n_d - 1) / v_d / ((LINE_F * um) ** -2 - (LINE_C * um) ** -2)
        return cls("cauchy", (n_d - b / (LINE_D * um) ** 2, b))

    @classmethod
    def from_sellmeier(cls, b: Any, c: Any) -> Glass:
        """A glass from its Sellmeier coefficients ``B1..B3`` and ``C1..C3``
        (µm², Schott's convention)."""
        bs, cs = as_float_array(b, "b"), as_float_array(c, "c")
        if bs.shape != (3,) or cs.shape != (3,):
            raise ValueError(f"b and c must hold 3 values each, got {bs.shape} and {cs.shape}")
        return cls("sellmeier", (*bs.tolist(), *cs.tolist()))

    def index(self, wavelength: Any) -> Float64Array:
        """Refractive index at ``wavelength`` (nm, array_like).

        A Sellmeier glass answers inside its transparent window only: between
        the two poles ``sqrt(C_i)`` (absorption bands) on either side of the
        d line, where its catalogue figures are measured. Across a pole the
        formula describes no glass: beyond N-BK7's infrared pole at 10.18 µm
        it still gives indices near 1.8, and at a pole it divides by 0.

        Raises
        ------
        ValueError
            A wavelength that is not finite and > 0, or one at or across a
            Sellmeier pole (an absorption band, where the formula says nothing).
        """
        wl = as_float_array(wavelength, "wavelength")
        if not (np.isfinite(wl).all() and (wl > 0).all()):
            raise ValueError("wavelengths must be finite and > 0 nm")
        um2 = (wl * 1e-3) ** 2
        if self.law == "cauchy":
            a, b = self.coefficients
            n = a + b / um2
            if not (n > 1).all():
                raise ValueError(
                    f"the Cauchy glass {self.coefficients!r} has no index > 1 at "
                    f"{float(wl.flat[np.argmax(n <= 1)]):g} nm: it describes no glass there"
                )
            return n
        bs, cs = np.array(self.coefficients[:3]), np.array(self.coefficients[3:])
        poles = np.sqrt(cs[bs > 0]) * 1e3
        below = poles[poles <= LINE_D].max(initial=0.0)
        above = poles[poles > LINE_D].min(initial=np.inf)
        if not ((wl > below) & (wl < above)).all():
            worst = float(wl.flat[np.argmax((wl <= below) | (wl >= above))])
            raise ValueError(
                f"{worst:g} nm is at or across a Sellmeier pole: the formula holds between "
                f"the poles at {below:g} and {above:g} nm around the d line (the glass's "
                "transparent window)"
            )
        n2 = 1 + np.sum(bs * um2[..., None] / (um2[..., None] - cs), axis=-1)
        if not (np.isfinite(n2) & (n2 > 1)).all():
            raise ValueError(
                "the Sellmeier formula has no finite index > 1 at some of these wavelengths "
                "(an absorption pole lies near them)"
            )
        return np.sqrt(n2)

    @property
    def abbe_number(self) -> float:
        """``V_d = (n_d - 1) / (n_F - n_C)``: the lower, the more dispersive."""
        n_d, n_f, n_c = self.index([LINE_D, LINE_F, LINE_C])
        return float((n_d - 1) / (n_f - n_c))


def focal_lengths(glass: Glass, wavelengths: Any, f_d: float) -> Float64Array:
    """Focal length (mm) of a thin lens of ``glass`` at each wavelength, the
    lens having focal length ``f_d`` at the d line (587.56 nm).

    Examples
    --------
    >>> f = focal_lengths(Glass.from_abbe(1.5168, 64.17), [LINE_F, LINE_C], 50.0)
    >>> round(float(f[1] - f[0]), 3)  # ~ f_d / V_d = 0.779
    0.774
    """
    f_d = _positive(f_d, "f_d")
    n = glass.index(wavelengths)
    return f_d * (glass.index(LINE_D) - 1) / (n - 1)


def focal_shift(glass: Glass, wavelengths: Any, f_d: float) -> Float64Array:
    """The lecture's Figure 4a: ``f(λ) - f_d`` (mm), the longitudinal
    chromatic aberration of a thin lens of ``glass`` for a distant object."""
    return focal_lengths(glass, wavelengths, f_d) - _positive(f_d, "f_d")


def _check_radiance(cube: npt.NDArray[np.float32]) -> None:
    """Radiance is finite and >= 0; the first bad pixel is named."""
    bad = ~(np.isfinite(cube) & (cube >= 0)).all(axis=2)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise ValueError(
            "radiance must be finite and >= 0 at every wavelength; pixel "
            f"(row {row}, column {col}) is not"
        )


def _grid(wavelengths: Any) -> Float64Array:
    """The wavelengths of a render: a grid as :func:`imgform_rs.spectral.
    check_wavelengths` takes it, or one wavelength (a monochromatic render:
    each wavelength is rendered on its own, so one needs no grid)."""
    from .spectral import check_wavelengths

    wl = as_float_array(wavelengths, "wavelengths")
    if wl.shape != (1,):
        return check_wavelengths(wl)
    if not (np.isfinite(wl[0]) and wl[0] > 0):
        raise ValueError(f"a wavelength must be finite and > 0 nm, got {wl[0]!r}")
    return wl


def render_dispersion(
    radiance: npt.NDArray[np.float32],
    wavelengths: Any,
    glass: Glass,
    *,
    f_d: float,
    N: float,
    focus_distance: float,
    depth: Any,
    pixel_pitch: float,
    lateral: bool = True,
) -> npt.NDArray[np.float32]:
    """A spectral image (H, W, L) as a thin lens of ``glass`` forms it.

    The sensor sits where the d line focuses ``focus_distance``; the aperture
    is ``f_d / N`` wide. Each wavelength ``λ`` then focuses the distance
    ``1 / (1/f(λ) - 1/v)`` instead and is defocused by
    :func:`imgform_rs.render_defocus` (longitudinal aberration); with
    ``lateral``, it is also magnified by ``f(λ) / f_d`` about the image centre,
    as by a lens whose stop lies in its front focal plane (chief rays leave
    parallel to the axis and land at ``f(λ) tan θ``).

    Parameters
    ----------
    radiance : ndarray, float32, shape (H, W, L)
        The pinhole (all in focus, undispersed) spectral image.
    wavelengths : array_like, shape (L,)
        Its grid, nm; one wavelength (L = 1) renders monochromatic light.
    glass : Glass
    f_d, N : float
        Focal length at the d line (mm) and f-number.
    focus_distance : float
        Distance the lens is focused at for the d line (mm), > ``f_d``.
    depth : array_like, shape (H, W) or scalar
        Distance of each pixel's surface (mm).
    pixel_pitch : float
        mm.
    lateral : bool
        Also render lateral chromatic aberration.

    Returns
    -------
    ndarray, float32, shape (H, W, L)

    Raises
    ------
    TypeError, ValueError
        A non-float32 or wrongly shaped image, negative or NaN radiance (the
        first bad pixel is named), a grid that is not strictly increasing or
        does not match the image, a depth map of another shape, or a
        wavelength whose focal length reaches the sensor (it focuses nothing).
    """
    if not isinstance(glass, Glass):
        raise TypeError(f"glass must be a Glass, got {type(glass).__name__}")
    lateral = flag(lateral, "lateral")
    cube = np.asarray(radiance)
    if cube.dtype != np.float32 or cube.ndim != 3:
        raise TypeError(
            f"radiance must be a float32 (H, W, L) array, got {cube.dtype} of shape {cube.shape}"
        )
    wl = _grid(wavelengths)
    if wl.shape != (cube.shape[2],):
        raise ValueError(
            f"wavelengths must hold the image's {cube.shape[2]} samples, got shape {wl.shape}"
        )
    _check_radiance(cube)
    h, w = cube.shape[:2]
    depth_arr = as_float_array(depth, "depth")
    if depth_arr.ndim != 0 and depth_arr.shape != (h, w):
        raise ValueError(
            f"depth must be a scalar or an (H, W) = ({h}, {w}) map, got shape {depth_arr.shape}"
        )
    depth_map = np.broadcast_to(depth_arr, (h, w))
    f_d, N = _positive(f_d, "f_d"), _positive(N, "N")
    pitch, distance = real(pixel_pitch, "pixel_pitch"), real(focus_distance, "focus_distance")
    if not (np.isfinite(distance) and distance > f_d):
        raise ValueError(
            f"focus_distance must be finite and beyond the focal length f_d = {f_d:g} mm, "
            f"got {focus_distance!r}"
        )
    sensor = float(image_distance(f_d, distance))
    aperture = f_d / N
    fs = focal_lengths(glass, wl, f_d)
    if (fs >= sensor).any():
        worst = float(wl[np.argmax(fs)])
        raise ValueError(
            f"at {worst:g} nm the focal length reaches the sensor ({sensor:g} mm behind the "
            "lens): that wavelength focuses no object; focus nearer or use a less "
            "dispersive glass"
        )
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    cy, cx = (h - 1) / 2, (w - 1) / 2
    out = np.empty_like(cube)
    for i, f in enumerate(fs):
        plane = render_defocus(
            np.ascontiguousarray(cube[:, :, i]),
            depth_map,
            f=float(f),
            N=float(f) / aperture,
            focus_distance=1.0 / (1.0 / f - 1.0 / sensor),
            pixel_pitch=pitch,
        )
        if lateral:
            scale = np.float32(f / f_d)
            plane = remap(plane, (cx + (u - cx) / scale, cy + (v - cy) / scale))
        out[:, :, i] = plane
    return out
