"""Prokudin-Gorskii's camera, simulated spectrally: a ground truth for the
three-colour alignment (lecture sections 4 and 5, the lecture's Figure 5).

A scene (reflectance spectra, or linear sRGB upsampled to them) lit by CIE
daylight D65 is photographed three times, through red, green and blue
separation filters, onto one panchromatic glass plate; the camera moves a
little and the exposure errs a little between the shots. The developed
plate is scanned as a positive (its density), the three frames stacked
blue, green, red from the top as on Prokudin-Gorskii's plates. Then the
plate is split and aligned by :func:`~imgform_rs.colorize_plate`, turned
back into exposures through the plate's characteristic curve, and
colourised by a 3x3 matrix fitted on the ColorChecker; the shifts found and
the colours are compared with the truth.

The model, per filter ``f`` (R, G, B) and pixel:

``H_f = 2^EV_f ∫ E(λ) ρ(λ) T_f(λ) s(λ) dλ / ∫ E(λ) T_f(λ) s(λ) dλ``

with ``E`` the illuminant, ``ρ`` the scene's reflectance, ``T_f`` the filter's
transmittance and ``s`` the plate's spectral sensitivity: the denominator is
the *filter factor*, the longer exposure a photographer gives behind a
filter so that a white exposes every frame alike; ``EV_f`` is what the
exposure still errs by. The plate develops by :func:`imgform_rs.film.develop`
(its curve, halation and Poisson grain) and its scan reads
``base + D`` on a scale of :data:`SCAN_DENSITY_RANGE`.

Colourising inverts that: the scan's density through the inverse of the
plate's curve gives ``log10 H_f``, and ``XYZ = M H`` with ``M`` the least
squares fit of the 24 ColorChecker patches' noise-free ``H`` to their XYZ
(:func:`colour_matrix`). No 3x3 can be exact: the filtered plate's three
sensitivities ``E T_f s`` are not a linear mix of the CIE colour matching
functions (the Luther condition fails), which sets the colour error that
remains with a perfect alignment.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from . import film
from . import spectral as sp
from ._arrays import Float64Array, as_real, as_seed, integer, real
from .align import apply_warp, colorize_plate

Float32Array = npt.NDArray[np.float32]

#: The order of the three exposures in the colour channels of everything
#: here (R, G, B, as everywhere in imgform-rs). The plate holds them the
#: other way up: blue at the top.
CHANNELS = ("r", "g", "b")
_NAMES = ("red", "green", "blue")
#: The plate's frames from the top, as Prokudin-Gorskii's plates hold them.
PLATE_ORDER = ("b", "g", "r")
#: The densities the scan's 16-bit range spans: 0 -> 0, this -> 65535.
#: Wider than any density the panchromatic plate reaches (base + D_max, 2.7).
SCAN_DENSITY_RANGE = 4.0
#: The glass plate a frame spans, mm (Prokudin-Gorskii's 9 x 24 cm plates
#: held three frames of about 8 cm): it sets the pixel size for the plate's
#: grain and halation.
FRAME_WIDTH_MM = 80.0

#: Parameters of the separation filters, after the Wratten 25 (red), 58
#: (green) and 47 (blue) that tricolour work used: the red a long-pass edge
#: ``t / (1 + exp(-(λ - cut_on) / width))``, the green and blue Gaussian
#: bands ``t exp(-(λ - peak)² / 2 width²)``. Cut-on, peaks, widths and peak
#: transmittances are round numbers of ours in the ranges such filters
#: have; no published table is reproduced.
WRATTEN_LIKE: dict[str, dict[str, float]] = {
    "r": {"cut_on": 600.0, "width": 8.0, "peak_transmittance": 0.9},
    "g": {"peak": 530.0, "width": 30.0, "peak_transmittance": 0.6},
    "b": {"peak": 445.0, "width": 28.0, "peak_transmittance": 0.5},
}

#: The scene light: CIE daylight, and the white sRGB itself assumes.
ILLUMINANT = "D65"


def separation_filters(
    wl: Any = None, params: dict[str, dict[str, float]] | None = None
) -> Float64Array:
    """Transmittances (3, L) of the red, green and blue separation filters.

    Parameters
    ----------
    wl : array_like, optional
        The grid, nm (380..780 nm every 10 nm by default).
    params : dict, optional
        :data:`WRATTEN_LIKE` by default; ``"r"`` takes ``cut_on`` and
        ``width``, ``"g"`` and ``"b"`` ``peak`` and ``width`` (nm), each a
        ``peak_transmittance``.

    Raises
    ------
    ValueError
        For parameters whose filters are no transmittances: above 1, below
        0 or not finite (a width of 0) anywhere on the grid.

    Examples
    --------
    >>> T = separation_filters([450.0, 530.0, 650.0])
    >>> np.round(T, 3).tolist()
    [[0.0, 0.0, 0.898], [0.017, 0.6, 0.0], [0.492, 0.005, 0.0]]
    """
    grid = sp.wavelengths() if wl is None else sp.check_wavelengths(wl)
    p = WRATTEN_LIKE if params is None else params
    with np.errstate(all="ignore"):  # a width of 0 is reported below, not warned
        red = p["r"]["peak_transmittance"] / (
            1.0 + np.exp(-(grid - p["r"]["cut_on"]) / p["r"]["width"])
        )
        bands = [
            p[c]["peak_transmittance"] * film.gaussian(grid, p[c]["peak"], p[c]["width"])
            for c in "gb"
        ]
    return _check_filters(np.stack([red, *bands]), grid)


def _check_filters(filters: Any, wl: Float64Array) -> Float64Array:
    """Three transmittances on ``wl``, each in [0, 1] and not all zero."""
    arr = np.asarray(filters, dtype=np.float64)
    if arr.shape != (3, len(wl)):
        raise ValueError(
            f"filters must have shape (3, {len(wl)}): red, green and blue transmittances on "
            f"the grid of {len(wl)} wavelengths, got {arr.shape}"
        )
    for name, t in zip(_NAMES, arr, strict=True):
        bad = ~(np.isfinite(t) & (t >= 0.0) & (t <= 1.0))
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(
                f"the {name} filter's transmittance must lie in [0, 1]; at {wl[i]:g} nm it "
                f"is {t[i]:g}"
            )
    return arr


@dataclass(frozen=True)
class Camera:
    """Prokudin-Gorskii's camera: three separation filters and a plate.

    Parameters
    ----------
    wavelengths : array_like, shape (L,)
        The grid of everything spectral; 380..780 nm every 10 nm by default.
    filters : array_like, shape (3, L), optional
        Red, green, blue transmittances in [0, 1]; default
        :func:`separation_filters`.
    plate : str, Path or film.Stock
        A one-layer (black-and-white) negative stock; the generic
        panchromatic one by default (a flat band 400-660 nm).

    Raises
    ------
    ValueError
        Filters on another grid, outside [0, 1] or blind where the plate
        sees; a plate that is not a one-layer negative or whose grid differs.
    """

    wavelengths: Any = field(default_factory=sp.wavelengths)
    filters: Any = None
    plate: Any = "generic-bw-pan"

    def __post_init__(self) -> None:
        grid = sp.check_wavelengths(self.wavelengths)
        filters = separation_filters(grid) if self.filters is None else self.filters
        object.__setattr__(self, "wavelengths", grid)
        object.__setattr__(self, "filters", _check_filters(filters, grid))
        stock = film.load_stock(self.plate)
        if stock.kind != "negative" or len(stock.layers) != 1:
            raise ValueError(
                f"plate must be a one-layer (black-and-white) negative stock, got the "
                f"{len(stock.layers)}-layer {stock.kind} {stock.name!r}"
            )
        if not np.array_equal(stock.wavelengths, grid):
            raise ValueError(
                f"the plate {stock.name!r} is sampled on {len(stock.wavelengths)} wavelengths "
                f"{stock.wavelengths[0]:g}..{stock.wavelengths[-1]:g} nm; the camera's grid "
                f"has {len(grid)} ({grid[0]:g}..{grid[-1]:g} nm)"
            )
        object.__setattr__(self, "plate", stock)
        unseen = self._through_filters().sum(axis=0) <= 0
        if unseen.any():
            raise ValueError(
                f"the {_NAMES[int(np.argmax(unseen))]} filter passes no light the plate "
                "is sensitive to"
            )

    def _through_filters(self) -> Float64Array:
        """``E(λ) T_f(λ) s(λ)``, (L, 3): each filtered exposure's weight."""
        light = sp.illuminant(ILLUMINANT, self.wavelengths)
        sens = 10.0 ** self.plate.layers[0].log_sensitivity
        return (light * sens)[:, None] * self.filters.T

    def sensitivities(self) -> Float64Array:
        """Spectral weights (L, 3) with ``H = ∫ ρ(λ) w_f(λ) dλ`` (trapezoidal):
        ``E T_f s`` over its integral, so a perfect white exposes each frame
        to 1 (the filter factors applied)."""
        w = self._through_filters()
        return w / (sp.quadrature_weights(self.wavelengths) @ w)

    def filter_factors(self) -> Float64Array:
        """Each filter's factor (R, G, B): how much longer a frame is exposed
        behind it than without it, for the same exposure of a white."""
        w = sp.quadrature_weights(self.wavelengths)
        light = sp.illuminant(ILLUMINANT, self.wavelengths)
        open_gate = w @ (light * 10.0 ** self.plate.layers[0].log_sensitivity)
        return open_gate / (w @ self._through_filters())

    def exposures(self, scene: Any) -> Float32Array:
        """Noise-free exposures ``H`` (H, W, 3), R, G, B, of a scene: linear
        sRGB (H, W, 3) or reflectance (H, W, L) on the camera's grid."""
        arr = _scene(scene, self.wavelengths)
        if arr.shape[2] == len(self.wavelengths):
            return sp.integrate(arr, self.wavelengths, self.sensitivities())
        weights = sp.quadrature_weights(self.wavelengths)[:, None] * self.sensitivities()
        basis = sp.upsampling_basis(self.wavelengths)
        return (arr @ (basis.T @ weights).astype(np.float32)).astype(np.float32)


def _scene(scene: Any, wl: Float64Array) -> Float32Array:
    """A scene as a float32 (H, W, C) array, C = 3 (linear sRGB, clipped at
    0: the upsampling has no negative reflectance) or one per wavelength."""
    arr = np.asarray(scene)
    if arr.dtype.kind != "f":
        # An 8-bit picture read as reflectances up to 255 overexposed the
        # plates 128 times over.
        raise TypeError(
            f"scene must be float (linear sRGB or reflectances, white 1), got dtype "
            f"{arr.dtype}: divide an 8-bit picture by 255 (16-bit: 65535) and undo the "
            "sRGB transfer curve first"
        )
    if arr.ndim != 3 or arr.shape[2] not in (3, len(wl)):
        raise ValueError(
            f"scene must be linear sRGB (H, W, 3) or reflectance (H, W, {len(wl)}) on the "
            f"camera's grid, got shape {arr.shape}"
        )
    out = np.ascontiguousarray(arr, dtype=np.float32)
    if not np.isfinite(out).all():
        raise ValueError("scene must be finite")
    return np.maximum(out, 0.0) if arr.shape[2] == 3 else out


def scene_srgb(scene: Any, wl: Any = None) -> Float32Array:
    """The scene's own linear sRGB (H, W, 3) under D65: what the colourised
    plate is compared with. A linear sRGB scene is its own (clipped at 0);
    reflectances are integrated with the CIE 1931 observer."""
    grid = sp.wavelengths() if wl is None else sp.check_wavelengths(wl)
    arr = _scene(scene, grid)
    if arr.shape[2] == 3:
        return arr
    xyz = sp.integrate(arr, grid, _xyz_sensitivities(grid))
    return (xyz @ sp.XYZ_TO_SRGB.T.astype(np.float32)).astype(np.float32)


def mondrian(
    shape: tuple[int, int] = (96, 112), *, rectangles: int = 60, seed: int = 0, wl: Any = None
) -> Float32Array:
    """A spectral Mondrian (after Land and McCann's): ``rectangles`` random
    rectangles of the 24 ColorChecker reflectances over its neutral 6.5
    (patch 21), shape (H, W, L) float32.

    Sharp edges that every filter sees and no period (a chart's regular
    grid aliases the alignment at its pitch), with the colours the
    :func:`colour_matrix` is fitted on: a scene for checking the alignment
    and the colourisation apart from the 3x3's reach.

    Examples
    --------
    >>> m = mondrian((40, 50), seed=1)
    >>> m.shape, m.dtype, bool(0 <= m.min() and m.max() <= 1)
    ((40, 50, 41), dtype('float32'), True)
    """
    grid = sp.wavelengths() if wl is None else sp.check_wavelengths(wl)
    if not (isinstance(shape, (tuple, list)) and len(shape) == 2):
        raise ValueError(f"shape must be (height, width), got {shape!r}")
    h, w = (integer(v, "shape") for v in shape)
    count = integer(rectangles, "rectangles")
    if min(h, w) < 1 or count < 0:
        raise ValueError(f"shape must be positive and rectangles >= 0, got {shape}, {rectangles}")
    _, refl = sp.colorchecker(grid)
    rng = np.random.default_rng(as_seed(seed, "seed"))
    out = np.empty((h, w, len(grid)), np.float32)
    out[:] = refl[20]
    for _ in range(count):
        rh, rw = (int(rng.integers(max(2, n // 25), max(3, n // 3))) for n in (h, w))
        y, x = int(rng.integers(-rh // 2, h)), int(rng.integers(-rw // 2, w))
        out[max(y, 0) : y + rh, max(x, 0) : x + rw] = refl[rng.integers(len(refl))]
    return out


def _xyz_sensitivities(wl: Float64Array) -> Float64Array:
    """``x̄ȳz̄ E`` (L, 3) over ``∫ ȳ E dλ``: XYZ with the perfect white's Y = 1."""
    light, cmfs = sp.illuminant(ILLUMINANT, wl), sp.cie_cmfs(wl)
    return cmfs * light[:, None] / (sp.quadrature_weights(wl) @ (cmfs[:, 1] * light))


def colour_matrix(camera: Camera) -> sp.ColorFit:
    """The 3x3 from the three plates' exposures (R, G, B) to XYZ (D65, white
    Y = 1), fitted by least squares on the 24 ColorChecker patches (Ohta's
    reflectances) photographed without noise; ``XYZ_TO_SRGB @ matrix`` goes to
    linear sRGB (least squares commutes with that fixed 3x3). The fit's
    CIEDE2000 per patch is the colour error no 3x3 removes (see the module
    docstring).

    Examples
    --------
    >>> fit = colour_matrix(Camera())
    >>> fit.matrix.shape, round(fit.mean_delta_e, 2), round(fit.max_delta_e, 2)
    ((3, 3), 2.21, 7.63)
    """
    wl = camera.wavelengths
    _, refl = sp.colorchecker(wl)
    weights = sp.quadrature_weights(wl)[:, None]
    xyz_w = weights * _xyz_sensitivities(wl)
    return sp.fit_color_matrix(
        refl @ (weights * camera.sensitivities()), refl @ xyz_w, xyz_w.sum(axis=0)
    )


# --- the plate -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Plate:
    """A simulated glass plate and the truth behind it.

    Attributes
    ----------
    image : ndarray, uint16, shape (3 (h + 2 border), w + 2 border)
        The scan, a positive: ``65535 (base + D) / SCAN_DENSITY_RANGE``,
        frames blue, green, red from the top, each in an unexposed border.
    offsets : dict
        Where each exposure's frame (h x w) sat in the scene: ``{"r": (dy,
        dx), ...}`` from the scene's centred frame, in pixels.
    exposure_ev : dict
        Each exposure's error, stops.
    margin : int
        The scene pixels beyond the centred frame on every side (the
        largest offset the scene allows).
    border : int
        The unexposed border around each frame, pixels.
    rotation : dict
        Each exposure's turn about its frame's centre, radians (positive
        from +x towards +y); 0 for all unless :func:`photograph` was given
        some.
    """

    image: npt.NDArray[np.uint16] = field(repr=False)
    offsets: dict[str, tuple[int, int]]
    exposure_ev: dict[str, float]
    margin: int
    border: int
    rotation: dict[str, float] = field(default_factory=lambda: dict.fromkeys(CHANNELS, 0.0))

    @property
    def frame_shape(self) -> tuple[int, int]:
        """(h, w) of one exposure."""
        rows, cols = self.image.shape
        return rows // 3 - 2 * self.border, cols - 2 * self.border

    def true_shifts(self, reference: str = "b") -> dict[str, tuple[int, int]]:
        """The shifts :func:`~imgform_rs.colorize_plate` should find: the
        ``np.roll`` amounts landing each frame on ``reference``'s.

        Frame ``c`` shows scene row ``y + o_c``; rolled by ``o_c - o_ref`` it
        shows ``y + o_ref``, the reference's.
        """
        ref = self.offsets[_channel(reference)]
        return {c: (o[0] - ref[0], o[1] - ref[1]) for c, o in self.offsets.items()}

    def true_matrices(self, reference: str = "b") -> dict[str, Float64Array]:
        """The warps ``colorize_plate(..., motion="euclidean")`` should find:
        per frame the 2x3 :attr:`~imgform_rs.Alignment.matrix` taking a
        reference pixel ``p = (x, y)`` to the frame's pixel showing the same
        scene point.

        Frame ``c`` shows the scene at ``R_c (p - k) + k + t_c`` (``k`` the
        frame's centre, ``t_c`` its offset in the scene): so
        ``p' = R_c⁻¹ (R_ref (p - k) + t_ref - t_c) + k``.
        """
        ref = _channel(reference)
        h, w = self.frame_shape
        k = np.array([(w - 1) / 2, (h - 1) / 2])
        out = {}
        for c, (dy, dx) in self.offsets.items():
            back = _rotation(-self.rotation[c])
            linear = back @ _rotation(self.rotation[ref])
            ry, rx = self.offsets[ref]
            move = back @ np.array([rx - dx, ry - dy], np.float64)
            out[c] = np.hstack([linear, (move + k - linear @ k)[:, None]])
        return out


def _rotation(angle: float) -> Float64Array:
    """The 2x2 rotation by ``angle`` (from +x towards +y) in (x, y)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _channel(name: str) -> str:
    if name not in CHANNELS:
        raise ValueError(f'reference must be "r", "g" or "b", got {name!r}')
    return name


def _int_pair(value: Any, name: str) -> tuple[int, int]:
    try:
        dy, dx = (operator.index(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair of integers (dy, dx), got {value!r}") from None
    return int(dy), int(dx)


def _offsets(shifts: Any, margin: int, rng: np.random.Generator) -> dict[str, tuple[int, int]]:
    """The exposures' offsets: given, or uniform integers in [-margin, margin]."""
    if shifts is None:
        drawn = rng.integers(-margin, margin + 1, size=(3, 2))
        return {c: (int(d[0]), int(d[1])) for c, d in zip(CHANNELS, drawn, strict=True)}
    if not isinstance(shifts, dict) or set(shifts) != set(CHANNELS):
        raise ValueError(f'shifts must be a dict with keys "r", "g", "b", got {shifts!r}')
    out = {c: _int_pair(shifts[c], f"shifts[{c!r}]") for c in CHANNELS}
    for c, (dy, dx) in out.items():
        if max(abs(dy), abs(dx)) > margin:
            raise ValueError(
                f"shift {c!r} = {(dy, dx)} is too large for the plate: the scene has only "
                f"{margin} pixels beyond the frame (margin); shifts must lie in "
                f"[-{margin}, {margin}]"
            )
    return out


def _exposure_errors(exposure_ev: Any, spread: float, rng: np.random.Generator) -> dict[str, float]:
    """Each exposure's error in stops: given, or uniform in [-spread, spread]."""
    if exposure_ev is not None:
        return _checked_errors(exposure_ev)
    spread = real(spread, "ev_spread")
    if not (np.isfinite(spread) and 0 <= spread <= film.MAX_EV):
        raise ValueError(
            f"ev_spread must be a finite number of stops from 0 to {film.MAX_EV:g}, got {spread!r}"
        )
    return {c: float(e) for c, e in zip(CHANNELS, rng.uniform(-spread, spread, 3), strict=True)}


def _checked_errors(exposure_ev: Any) -> dict[str, float]:
    """``{"r": ev, "g": ev, "b": ev}``, finite floats within film's range of
    ``MAX_EV`` stops either way (beyond it, ``2**ev`` overflows a float)."""
    if not isinstance(exposure_ev, dict) or set(exposure_ev) != set(CHANNELS):
        raise ValueError(f'exposure_ev must be a dict with keys "r", "g", "b", got {exposure_ev!r}')
    out = {c: real(exposure_ev[c], f'exposure_ev["{c}"]') for c in CHANNELS}
    if not all(np.isfinite(v) and abs(v) <= film.MAX_EV for v in out.values()):
        raise ValueError(
            f"exposure_ev must be finite numbers of stops in [-{film.MAX_EV:g}, "
            f"{film.MAX_EV:g}], got {exposure_ev!r}"
        )
    return out


def photograph(
    scene: Any,
    camera: Camera | None = None,
    *,
    shifts: dict[str, Any] | None = None,
    margin: int | None = None,
    exposure_ev: dict[str, float] | None = None,
    ev_spread: float = 0.2,
    border: int | None = None,
    rotation: dict[str, float] | None = None,
    grain: bool = True,
    seed: int = 0,
) -> Plate:
    """Photographs ``scene`` three times through the camera's filters onto
    one plate, develops and scans it.

    Each exposure sees the frame of the scene offset by its camera motion
    (an integer translation, so the true shifts are exact), is exposed with
    its filter factor and an error of ``exposure_ev`` stops, and lands in its
    place on the plate: blue at the top, then green, then red, each inside
    ``border`` unexposed pixels. The whole plate is developed at once by
    :func:`imgform_rs.film.develop` (halation, and Poisson grain seeded by
    ``seed``).

    Parameters
    ----------
    scene : ndarray, (H, W, 3) linear sRGB or (H, W, L) reflectance
        Lit by D65. The frame is the scene less ``margin`` on every side.
    camera : Camera, optional
    shifts : dict, optional
        ``{"r": (dy, dx), "g": ..., "b": ...}``: where each exposure's frame
        sat, integers in ``[-margin, margin]``; drawn from ``seed`` if not
        given.
    margin : int, optional
        Scene pixels beyond the frame; default 2 % of the scene's shorter
        side (at least 1), so frames differ by up to 4 %, the order of
        Prokudin-Gorskii's own shifts.
    exposure_ev : dict, optional
        Each exposure's error in stops, at most :data:`imgform_rs.film.MAX_EV`
        (100) either way, film's own range; drawn uniformly in ``[-ev_spread,
        ev_spread]`` from ``seed`` if not given (``ev_spread`` likewise at
        most 100).
    border : int, optional
        Unexposed plate around each frame; default 2 % of the frame's
        shorter side (at least 1). Border plus the largest shift between
        two frames (plus 1 for gradient features, whose Sobel taps reach a
        pixel further) must stay inside :func:`~imgform_rs.align`'s 10 %
        crop of a third, or the border's edge joins the comparison and
        pulls the shift towards its own.
    rotation : dict, optional
        ``{"r": radians, ...}``: each exposure turned about its frame's
        centre (the camera rolled a little between the shots); the frame is
        then resampled bilinearly from the scene's exposure
        (:func:`~imgform_rs.apply_warp`), which the offset plus the
        rotation's reach must keep inside the scene. None: no rotation, the
        frames are exact crops.
    grain : bool
        The plate's Poisson grain.
    seed : int
        Seeds the shifts, exposure errors and grain: one seed, one plate.

    Returns
    -------
    Plate

    Raises
    ------
    ValueError
        A scene of the wrong shape or with non-finite values; shifts too
        large for the plate (beyond ``margin``); a margin that leaves a
        frame smaller than 16 x 16 pixels; bad exposure errors.
    TypeError
        A scene that is not of floats (an 8-bit picture is not reflectances).

    Examples
    --------
    >>> scene = np.random.default_rng(0).uniform(0.05, 0.9, (40, 48, 3))
    >>> plate = photograph(scene, margin=3, border=2, seed=1)
    >>> plate.image.shape, plate.image.dtype, plate.frame_shape
    ((114, 46), dtype('uint16'), (34, 42))
    """
    cam = Camera() if camera is None else camera
    exposures = cam.exposures(scene)
    height, width = exposures.shape[:2]
    m = max(1, round(0.02 * min(height, width))) if margin is None else integer(margin, "margin")
    h, w = height - 2 * m, width - 2 * m
    if m < 0 or min(h, w) < 16:
        raise ValueError(
            f"margin {m} must be >= 0 and leave a frame of at least 16 x 16 pixels in the "
            f"{height} x {width} scene"
        )
    seed = as_seed(seed, "seed")
    rng = np.random.default_rng(seed)
    offsets = _offsets(shifts, m, rng)
    errors = _exposure_errors(exposure_ev, ev_spread, rng)
    b = max(1, round(0.02 * min(h, w))) if border is None else integer(border, "border")
    if b < 0:
        raise ValueError(f"border must be >= 0, got {b}")
    turns = _rotations(rotation, offsets, (h, w), m)
    plate = _exposed_plate(exposures, offsets, errors, turns, (h, w), m, b)
    scan = _developed_scan(plate, cam.plate, grain, seed)
    return Plate(scan, offsets, errors, m, b, turns)


def _rotations(
    rotation: Any, offsets: dict[str, tuple[int, int]], frame: tuple[int, int], margin: int
) -> dict[str, float]:
    """Each exposure's rotation, checked: finite, and with its offset
    keeping the turned frame (and the bilinear taps) inside the scene."""
    if rotation is None:
        return dict.fromkeys(CHANNELS, 0.0)
    if not isinstance(rotation, dict) or set(rotation) != set(CHANNELS):
        raise ValueError(f'rotation must be a dict with keys "r", "g", "b", got {rotation!r}')
    out = {c: real(rotation[c], f'rotation["{c}"]') for c in CHANNELS}
    h, w = frame
    for c, angle in out.items():
        # A corner of the frame moves by at most |angle| x the half-diagonal.
        reach = abs(angle) * np.hypot(h - 1, w - 1) / 2 + 1
        if not np.isfinite(angle) or max(map(abs, offsets[c])) + reach > margin:
            raise ValueError(
                f"rotation {c!r} = {angle!r} rad with shift {offsets[c]} reaches "
                f"{max(map(abs, offsets[c])) + reach:.1f} px beyond the frame; the scene's "
                f"margin is {margin} px"
            )
    return out


def _frame(
    exposure: Float32Array, offset: tuple[int, int], angle: float, frame: tuple[int, int]
) -> Float32Array:
    """The (h, w) part of one filter's ``exposure`` an exposure sees: a crop
    at ``offset`` (exact), or turned by ``angle`` about the frame's centre
    ``k``, frame pixel ``p`` reading the scene at ``R (p - k) + k + offset``."""
    h, w = frame
    y, x = offset
    if angle == 0.0:
        return exposure[y : y + h, x : x + w]
    turn = _rotation(angle)
    k = np.array([(w - 1) / 2, (h - 1) / 2])
    matrix = np.hstack([turn, (k + [x, y] - turn @ k)[:, None]])
    return apply_warp(exposure, matrix)[:h, :w]


def _exposed_plate(
    exposures: Float32Array,
    offsets: dict[str, tuple[int, int]],
    errors: dict[str, float],
    turns: dict[str, float],
    frame: tuple[int, int],
    margin: int,
    border: int,
) -> Float32Array:
    """The plate's exposure (3 (h + 2 border), w + 2 border, 1): each
    filter's frame of the scene at its offset and rotation, times its
    exposure error, in its third (blue at the top); 0 on the unexposed
    border."""
    h, w = frame
    third = h + 2 * border
    plate = np.zeros((3 * third, w + 2 * border, 1), np.float32)
    for i, c in enumerate(PLATE_ORDER):
        offset = (margin + offsets[c][0], margin + offsets[c][1])
        channel = np.ascontiguousarray(exposures[..., CHANNELS.index(c)])
        seen = _frame(channel, offset, turns[c], frame)
        plate[i * third + border : i * third + border + h, border : border + w, 0] = (
            seen * 2.0 ** errors[c]
        )
    return plate


def _developed_scan(
    plate: Float32Array, stock: film.Stock, grain: bool, seed: int
) -> npt.NDArray[np.uint16]:
    """The plate developed (curve, halation, grain) and scanned: base plus
    density on the 16-bit scale of :data:`SCAN_DENSITY_RANGE`, rounded."""
    dens = film.develop(
        plate, stock, couplers=False, grain=grain, seed=seed, frame_width_mm=FRAME_WIDTH_MM
    )[..., 0]
    total = dens + float(stock.base_density.mean())
    scan = np.floor(np.clip(total / SCAN_DENSITY_RANGE, 0.0, 1.0) * 65535.0 + 0.5)
    return scan.astype(np.uint16)


# --- colourising ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Colourised:
    """:func:`colourise`'s result.

    Attributes
    ----------
    rgb : ndarray, float32, (h, w, 3)
        Linear sRGB, not clipped (the 3x3 can leave the gamut).
    shifts : dict
        What :func:`~imgform_rs.colorize_plate` found, ``(dy, dx)`` per channel.
    origin : tuple of int
        The reference third's pixel that ``rgb[0, 0]`` shows.
    reference : str
        The channel the others were aligned onto.
    """

    rgb: Float32Array = field(repr=False)
    shifts: dict[str, tuple[int, int]]
    origin: tuple[int, int]
    reference: str


def exposure_from_scan(scan: Any, camera: Camera) -> Float32Array:
    """Plate exposures ``H`` of scan values: the density ``65535``-scaled by
    :data:`SCAN_DENSITY_RANGE`, less the base, through the inverse of the
    plate's characteristic curve (exact: the curve is piecewise linear and
    strictly rising). Densities beyond the curve's ends give its end
    exposures."""
    layer = camera.plate.layers[0]
    base = float(camera.plate.base_density.mean())
    density = as_real(scan, "scan", np.float64) * (SCAN_DENSITY_RANGE / 65535.0) - base
    return (10.0 ** np.interp(density, layer.density, layer.log_exposure)).astype(np.float32)


def colourise(
    plate: Any,
    camera: Camera | None = None,
    *,
    reference: str = "b",
    exposure_ev: dict[str, float] | None = None,
    matrix: Any = None,
    metric: str = "ncc",
    features: str = "gradient",
    max_shift: int | None = None,
) -> Colourised:
    """Splits, aligns and colourises a scanned plate of :func:`photograph`.

    :func:`~imgform_rs.colorize_plate` aligns the frames (``frame=False``:
    the result is the area all three cover, border included);
    :func:`exposure_from_scan` turns them into exposures, which are divided
    by ``2^exposure_ev`` (the exposures' errors, when known: otherwise
    their colour cast stays) and mapped to linear sRGB by ``XYZ_TO_SRGB @
    matrix``.

    Parameters
    ----------
    plate : Plate or ndarray (3 H, W) uint16
    camera : Camera, optional
    reference : {"b", "g", "r"}
    exposure_ev : dict, optional
        ``{"r": ev, ...}``; nominal exposures (0) if not given.
    matrix : array_like (3, 3), optional
        Exposures to XYZ; :func:`colour_matrix` of the camera by default.
    metric, features, max_shift
        As in :func:`~imgform_rs.colorize_plate`. Gradient features by
        default: the red and blue frames of saturated colours are
        anti-correlated (a blue patch is bright behind the blue filter and
        dark behind the red), which misleads intensity NCC; gradient
        magnitudes are alike in every frame.

    Returns
    -------
    Colourised
        Translations only: a plate photographed with ``rotation`` is
        colourised as well as a shift allows (align its frames with
        ``colorize_plate(..., motion="euclidean")``).

    Raises
    ------
    TypeError
        A scan that is not uint16.
    ValueError
        An unknown reference, exposure errors that are not a dict of three
        finite numbers, a matrix that is not a finite 3x3, and everything
        :func:`~imgform_rs.colorize_plate` refuses.
    """
    cam = Camera() if camera is None else camera
    image = plate.image if isinstance(plate, Plate) else np.asarray(plate)
    if image.dtype != np.uint16:
        raise TypeError(f"plate must be a uint16 scan from photograph, got dtype {image.dtype}")
    ref = _channel(reference)
    errors = dict.fromkeys(CHANNELS, 0.0) if exposure_ev is None else _checked_errors(exposure_ev)
    to_xyz = colour_matrix(cam).matrix if matrix is None else np.asarray(matrix, np.float64)
    if to_xyz.shape != (3, 3) or not np.isfinite(to_xyz).all():
        raise ValueError(f"matrix must be a finite 3x3 array, got shape {to_xyz.shape}")
    aligned, shifts = colorize_plate(
        image, reference=ref, metric=metric, features=features, max_shift=max_shift, frame=False
    )
    gains = np.array([2.0 ** -float(errors[c]) for c in CHANNELS], np.float32)
    exposure = exposure_from_scan(aligned, cam) * gains
    to_srgb = (sp.XYZ_TO_SRGB @ to_xyz).T.astype(np.float32)
    origin = (max(s[0] for s in shifts.values()), max(s[1] for s in shifts.values()))
    rgb = (exposure @ to_srgb).astype(np.float32)
    found = {c: (int(s[0]), int(s[1])) for c, s in shifts.items()}
    return Colourised(rgb, found, origin, ref)


# --- against the truth ---------------------------------------------------------------------


@dataclass(frozen=True)
class Comparison:
    """A colourised plate against its scene.

    Attributes
    ----------
    true_shifts, found_shifts : dict
        :meth:`Plate.true_shifts` and :attr:`Colourised.shifts`.
    scene : ndarray, float32, (h, w, 3)
        The scene's linear sRGB over the area the result covers inside
        every frame (borders left out).
    rgb : ndarray, float32, (h, w, 3)
        The colourised result over that area.
    delta_e : ndarray, float64, (h, w)
        CIEDE2000 per pixel (D65 white), unclipped colours.
    scene_origin : tuple of int
        The scene pixel that ``scene[0, 0]`` and ``rgb[0, 0]`` show.
    """

    true_shifts: dict[str, tuple[int, int]]
    found_shifts: dict[str, tuple[int, int]]
    scene: Float32Array = field(repr=False)
    rgb: Float32Array = field(repr=False)
    delta_e: Float64Array = field(repr=False)
    scene_origin: tuple[int, int] = (0, 0)

    @property
    def shifts_exact(self) -> bool:
        """Whether every shift was recovered exactly."""
        return self.true_shifts == self.found_shifts

    @property
    def mean_delta_e(self) -> float:
        return float(self.delta_e.mean())

    @property
    def max_delta_e(self) -> float:
        return float(self.delta_e.max())

    def report(self) -> str:
        """The comparison in a few lines."""
        rows = [
            f"  {c.upper()}: true {self.true_shifts[c]}, found {self.found_shifts[c]}"
            for c in CHANNELS
        ]
        verdict = "exact" if self.shifts_exact else "NOT exact"
        return "\n".join(
            [f"shifts ({verdict}):", *rows]
            + [
                f"CIEDE2000 against the scene over {self.delta_e.size} px: mean "
                f"{self.mean_delta_e:.2f}, max {self.max_delta_e:.2f}"
            ]
        )


def compare(
    result: Colourised, plate: Plate, scene: Any, camera: Camera | None = None
) -> Comparison:
    """Compares :func:`colourise`'s ``result`` with the scene ``plate`` was
    photographed from.

    ``result.rgb[y, x]`` is the reference third's pixel ``origin + (y, x)``;
    channel ``c`` has image there from row ``border + d_c`` on (its shift
    ``d_c``), so the rows all three cover start ``border`` into the result
    and span ``h - (max d - min d)``; likewise the columns. Those pixels
    show the scene at the reference exposure's offset.

    Raises
    ------
    ValueError
        A result whose shape does not match the plate (another plate's).
    """
    cam = Camera() if camera is None else camera
    h, w = plate.frame_shape
    dys = [s[0] for s in result.shifts.values()]
    dxs = [s[1] for s in result.shifts.values()]
    rows, cols = h - (max(dys) - min(dys)), w - (max(dxs) - min(dxs))
    b, m = plate.border, plate.margin
    if result.rgb.shape[:2] != (rows + 2 * b, cols + 2 * b) or min(rows, cols) < 1:
        raise ValueError(
            f"the result ({result.rgb.shape[0]} x {result.rgb.shape[1]}) does not come from "
            f"this plate's frames of {h} x {w} with shifts {result.shifts}"
        )
    oy, ox = plate.offsets[result.reference]
    y0, x0 = m + oy + result.origin[0], m + ox + result.origin[1]
    reference = scene_srgb(scene, cam.wavelengths)[y0 : y0 + rows, x0 : x0 + cols]
    got = result.rgb[b : b + rows, b : b + cols]
    to_xyz = np.linalg.inv(sp.XYZ_TO_SRGB)
    white = to_xyz @ np.ones(3)
    de = sp.delta_e2000(got.astype(np.float64) @ to_xyz.T, reference @ to_xyz.T, white)
    truth = plate.true_shifts(result.reference)
    return Comparison(truth, result.shifts, reference, got, de, (int(y0), int(x0)))


@dataclass(frozen=True)
class Experiment:
    """:func:`experiment`'s plate, result and comparison."""

    plate: Plate = field(repr=False)
    result: Colourised = field(repr=False)
    comparison: Comparison


def experiment(
    scene: Any,
    camera: Camera | None = None,
    *,
    reference: str = "b",
    known_exposures: bool = True,
    features: str = "gradient",
    **photograph_args: Any,
) -> Experiment:
    """Prokudin-Gorskii's process end to end: :func:`photograph`,
    :func:`colourise`, :func:`compare`.

    Parameters
    ----------
    scene, camera
        As for :func:`photograph`.
    reference : {"b", "g", "r"}
        The frame the others are aligned onto.
    known_exposures : bool
        Divide out each exposure's error (as from an exact record of the
        exposure times); otherwise the colourist assumes nominal exposures
        and the errors tint the result.
    features : {"gradient", "intensity"}
        What :func:`~imgform_rs.colorize_plate` compares (see :func:`colourise`).
    **photograph_args
        ``shifts``, ``margin``, ``exposure_ev``, ``ev_spread``, ``border``,
        ``grain``, ``seed``.

    Examples
    --------
    >>> run = experiment(mondrian((72, 80), seed=3), seed=3)
    >>> run.comparison.shifts_exact, run.result.shifts == run.plate.true_shifts("b")
    (True, True)
    """
    cam = Camera() if camera is None else camera
    plate = photograph(scene, cam, **photograph_args)
    errors = plate.exposure_ev if known_exposures else None
    result = colourise(plate, cam, reference=reference, exposure_ev=errors, features=features)
    return Experiment(plate, result, compare(result, plate, scene, cam))
