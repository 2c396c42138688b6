"""Spherical aberration: geometric spot diagrams, diffraction PSFs and blur.

A lens whose rim bends light more than its centre focuses marginal rays nearer
than paraxial ones (longitudinal spherical aberration, LSA). :func:`spot_diagram`
and :func:`best_focus` trace that with rays; :func:`pupil_psf` computes the wave
optics PSF of the same error as a wavefront ``W(rho) = W020 rho^2 + W040 rho^4``;
:func:`strehl_ratio` measures its peak loss and :func:`render_aberrated` blurs an
image with it. Lengths are in one unit (millimetres in the examples).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import integer, real, require_finite

__all__ = [
    "SpotDiagram",
    "best_focus",
    "pupil_psf",
    "render_aberrated",
    "spot_diagram",
    "strehl_ratio",
]

Float64Array = npt.NDArray[np.float64]

#: Rays of :func:`best_focus` when none is given: at this count the plane is
#: within 1e-4 LSA of its many-ray limit (measured at f/2 against 2 M rays).
DEFAULT_RAYS = 4096


def _count(value: object, name: str) -> int:
    count = integer(value, name)
    if count < 1:
        raise ValueError(f"{name} must be >= 1, got {count}")
    return count


def _lens(f: object, f_number: object, spherical_lsa: object) -> tuple[float, float, float]:
    """The lens of :func:`spot_diagram` and :func:`best_focus`, checked to be
    numbers (the native layer checks their domains)."""
    return real(f, "f"), real(f_number, "f_number"), real(spherical_lsa, "spherical_lsa")


def _psf_array(psf: npt.ArrayLike, name: str) -> Float64Array:
    arr = np.asarray(psf)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be an array of real numbers, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 2-D array, got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float64)


def pupil_psf(
    *,
    n_pixels: int,
    pixel_pitch: float,
    f_number: float,
    wavelength: float,
    defocus: float = 0.0,
    spherical: float = 0.0,
    oversample: int | None = None,
) -> Float64Array:
    """Diffraction PSF of a circular pupil with defocus and spherical aberration.

    The pupil function ``exp(2 pi i W(rho))`` with ``W(rho) = defocus rho^2 +
    spherical rho^4`` (waves at the rim, ``rho`` the normalised pupil radius) is
    Fourier transformed with rustfft; the PSF is the squared modulus, integrated
    over each pixel by summing an ``oversample x oversample`` grid of samples at
    the sub-cell centres, and normalised to sum 1. With no aberration it is the
    Airy pattern, first dark ring at ``1.22 wavelength f_number``.

    The pupil is never undersampled: its sample count grows with the wavefront
    slope (a quarter wave at most between samples) and with the window (the
    periodic FFT window is at least twice the crop, so wrapped-around tails stay
    far from it). Sizes needing an FFT over 8192 samples are refused.

    Parameters
    ----------
    n_pixels : int
        Side of the square PSF, 1 to 1025. The optical axis is at the centre of
        the middle pixel when odd, at the corner of the four middle ones when
        even.
    pixel_pitch, f_number, wavelength : float
        Sensor pixel pitch, f-number and wavelength (same length unit), > 0.
    defocus, spherical : float
        ``W020`` and ``W040`` in waves, signed so that a ray's transverse error
        is ``-dW/drho``: moving the image plane ``dz`` away from the lens is
        ``W020 = dz / (8 N^2 wavelength)``, and ``spherical > 0`` is the
        under-corrected aberration of a simple positive lens, whose marginal
        focus lies ``spherical_lsa = 16 N^2 wavelength W040`` nearer the lens
        (:func:`spot_diagram`). Its sharpest PSF (least wavefront variance) is
        at ``defocus = -spherical``, half way to the marginal focus; the least
        RMS spot is at ``-4/3 spherical``, two thirds of the way.
    oversample : int, optional
        Sub-samples per pixel and axis. At least ``ceil(2 pixel_pitch /
        (wavelength f_number))`` (the Nyquist rate of the PSF; coarser grids
        alias and are refused), at most 64. Default: ``ceil(8 pixel_pitch /
        (wavelength f_number))``, sub-samples an eighth of ``wavelength
        f_number`` apart, where the midpoint rule puts an in-focus peak
        0.4-0.6 % above the exact pixel integral (its error falls as the
        square of the spacing); where that FFT would outgrow the limit below,
        as coarse as ``ceil(4 pixel_pitch / (wavelength f_number))`` (2-2.5 %).

    Returns
    -------
    ndarray, float64, shape (n_pixels, n_pixels)
        The PSF, summing to 1.

    Raises
    ------
    TypeError
        ``n_pixels`` or ``oversample`` not an integer, another parameter not
        a real number (a str or a bool included).
    ValueError
        A parameter outside its domain, an undersampling ``oversample``, or a
        PSF too large for the FFT (the message says which).

    Examples
    --------
    >>> psf = pupil_psf(n_pixels=9, pixel_pitch=0.5e-3, f_number=4, wavelength=0.5e-3)
    >>> psf.shape, round(float(psf.sum()), 12), bool(psf[4, 4] == psf.max())
    ((9, 9), 1.0, True)
    """
    n = _count(n_pixels, "n_pixels")
    os_ = None if oversample is None else _count(oversample, "oversample")
    return _native.pupil_psf(
        n,
        real(pixel_pitch, "pixel_pitch"),
        real(f_number, "f_number"),
        real(wavelength, "wavelength"),
        real(defocus, "defocus"),
        real(spherical, "spherical"),
        os_,
    )


@dataclass(frozen=True)
class SpotDiagram:
    """Where the rays of :func:`spot_diagram` cross the image plane.

    Attributes
    ----------
    hits : ndarray, float64, shape (N, 2)
        ``(x, y)`` of each ray on the image plane.
    pupil : ndarray, float64, shape (N, 2)
        ``(x, y)`` where each ray crossed the lens; row 0 is the chief ray, row
        ``N - 1`` the marginal ray.
    rms_radius : float
        RMS distance of the hits from their centroid.
    image_plane : float
        Distance of the plane behind the lens.
    """

    hits: Float64Array
    pupil: Float64Array
    rms_radius: float
    image_plane: float


def spot_diagram(
    *, f: float, f_number: float, spherical_lsa: float, n_rays: int, image_plane: float
) -> SpotDiagram:
    """Trace rays of a distant on-axis point through a lens with spherical aberration.

    The ray entering at height ``h`` crosses the axis at ``f - spherical_lsa
    (h / h_max)^2`` (``h_max = f / (2 f_number)``): paraxial rays at ``f``, the
    marginal ray shifted by the whole ``spherical_lsa`` (towards the lens when
    positive). The full pupil is sampled, not a fan: ray ``k`` enters at radius
    ``h_max sqrt(k / (n_rays - 1))`` and ``k`` golden angles around the axis, so
    each ray stands for an equal area of the aperture and the RMS weighs the
    light correctly.

    Parameters
    ----------
    f, f_number : float
        Focal length and f-number, > 0.
    spherical_lsa : float
        Longitudinal aberration of the marginal ray, finite and < ``f``.
    n_rays : int
        Rays traced, >= 2.
    image_plane : float
        Distance of the image plane behind the lens, > 0.

    Returns
    -------
    SpotDiagram

    Raises
    ------
    TypeError
        ``n_rays`` not an integer, another parameter not a real number.
    ValueError
        A parameter outside its domain.

    Examples
    --------
    >>> spot = spot_diagram(f=50.0, f_number=2.0, spherical_lsa=0.3, n_rays=101, image_plane=49.7)
    >>> spot.hits.shape, bool(np.allclose(spot.hits[-1], 0.0))
    ((101, 2), True)
    """
    n = _count(n_rays, "n_rays")
    lens = _lens(f, f_number, spherical_lsa)
    plane = real(image_plane, "image_plane")
    hits, pupil, rms = _native.spot_diagram(*lens, n, plane)
    return SpotDiagram(hits, pupil, rms, plane)


def best_focus(
    *, f: float, f_number: float, spherical_lsa: float, n_rays: int = DEFAULT_RAYS
) -> float:
    """The image-plane distance of least RMS spot radius.

    Each hit of :func:`spot_diagram` is linear in the plane distance, so the mean
    squared spread is a quadratic in it, minimised in closed form for the same
    rays. For this aberration (LSA growing as ``h^2``) the plane lies two thirds
    of the way from the paraxial to the marginal focus, ``f - 2/3
    spherical_lsa``: the spread of the transverse error ``u (d + LSA u^2)`` over
    the pupil area, ``d^2/2 + 2 d LSA/3 + LSA^2/4``, is least at ``d = -2 LSA/3``.

    Parameters
    ----------
    f, f_number, spherical_lsa : float
        As :func:`spot_diagram`.
    n_rays : int, optional
        Rays traced, >= 2.

    Returns
    -------
    float
        Distance of the best plane behind the lens.

    Raises
    ------
    TypeError
        ``n_rays`` not an integer, another parameter not a real number.
    ValueError
        A parameter outside its domain.

    Examples
    --------
    >>> round(best_focus(f=50.0, f_number=2.0, spherical_lsa=0.3), 2)
    49.8
    """
    n = _count(n_rays, "n_rays")
    return float(_native.best_focus(*_lens(f, f_number, spherical_lsa), n))


def strehl_ratio(psf: npt.ArrayLike, reference: npt.ArrayLike) -> float:
    """Strehl ratio: the peak of ``psf`` relative to an aberration-free ``reference``.

    Each peak is taken relative to its own PSF's total energy, so the two need
    not be normalised alike; they must be sampled on the same grid (the same
    pixel pitch and size, as two :func:`pupil_psf` calls differing only in the
    aberration). For small errors it follows Marechal's ``exp(-(2 pi
    sigma)^2)``, ``sigma`` the RMS wavefront error in waves.

    Parameters
    ----------
    psf, reference : array_like, shape (H, W)
        Non-negative, finite intensities with a positive sum.

    Returns
    -------
    float

    Raises
    ------
    TypeError
        Non-numeric input.
    ValueError
        Shapes that differ or are not 2-D, negative or non-finite values.

    Examples
    --------
    >>> kw = dict(n_pixels=15, pixel_pitch=0.5e-3, f_number=4, wavelength=0.5e-3)
    >>> s = strehl_ratio(pupil_psf(spherical=0.1, **kw), pupil_psf(**kw))
    >>> 0.9 < s < 1.0
    True
    """
    return float(_native.strehl_ratio(_psf_array(psf, "psf"), _psf_array(reference, "reference")))


@overload
def render_aberrated(image: npt.NDArray[np.uint8], psf: npt.ArrayLike) -> npt.NDArray[np.uint8]: ...
@overload
def render_aberrated(
    image: npt.NDArray[np.uint16], psf: npt.ArrayLike
) -> npt.NDArray[np.uint16]: ...
@overload
def render_aberrated(
    image: npt.NDArray[np.float32], psf: npt.ArrayLike
) -> npt.NDArray[np.float32]: ...
def render_aberrated(image: np.ndarray, psf: npt.ArrayLike) -> np.ndarray:
    """Blur an image with a point spread function.

    The convolution ``out[p] = sum_i psf[i] image[p + c - i]``, anchor ``c =
    (kh // 2, kw // 2)`` (the centre of an odd PSF), with mirrored borders (as
    OpenCV's ``BORDER_REFLECT_101``). Sums are in float32; integer results are
    rounded half up and clamped. PSFs of up to 36 taps are summed directly,
    larger ones by overlap-save FFT tiles (rustfft), both in parallel over row
    bands, with results identical for any thread count. A delta PSF returns
    integer images bit for bit (float images too through the direct sum, to
    ~1e-6 through the FFT, whose rounding is relative to the image's largest
    magnitude: a pixel 1e9 times brighter than the rest shows its float32
    rounding across its tile). The PSF is used as given: one that sums to 1 keeps
    the brightness. OpenCV's ``filter2D`` computes a correlation: pass it
    ``psf[::-1, ::-1]`` to compare.

    Parameters
    ----------
    image : ndarray, uint8, uint16 or float32, shape (H, W) or (H, W, C)
        The sharp image.
    psf : array_like, shape (kh, kw)
        Finite weights, sides up to 1025 (for example from :func:`pupil_psf`).

    Returns
    -------
    ndarray
        The blurred image, same shape and dtype as ``image``.

    Raises
    ------
    TypeError
        ``image`` of an unsupported dtype, a non-numeric ``psf``.
    ValueError
        Wrong shapes, non-finite taps or samples, taps beyond float32's
        range, or a PSF side above 1025.

    Examples
    --------
    >>> img = np.zeros((5, 5), np.uint8)
    >>> img[2, 2] = 200  # a point of light spreads as the PSF, drawn upright
    >>> render_aberrated(img, [[0.0, 0.25, 0.0], [0.25, 0.5, 0.0], [0.0, 0.0, 0.0]])[1:4, 1:4]
    array([[  0,  50,   0],
           [ 50, 100,   0],
           [  0,   0,   0]], dtype=uint8)
    """
    # NaN or an infinity would spread over a whole FFT tile for large PSFs
    # (the direct sum only over the PSF's footprint): refused on both paths.
    require_finite(np.asarray(image), "image")
    taps = _psf_array(psf, "psf")
    top = float(np.abs(taps).max())
    if top > float(np.finfo(np.float32).max):
        # The kernel sums in float32: such a tap became inf, and the output NaN.
        raise ValueError(f"psf taps must lie within float32's range, got one of {top:g}")
    return _native.render_aberrated(image, taps)  # type: ignore[no-any-return]
