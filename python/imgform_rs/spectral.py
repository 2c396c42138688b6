"""Spectral image formation: light, not RGB, onto the sensor (lecture sections 3.3 and 6).

A scene is spectral radiance ``L(λ)`` (W m⁻² sr⁻¹ nm⁻¹) sampled on a wavelength
grid in nanometres, as (H, W, L) float32 arrays. A camera channel ``c`` counts
photo-electrons at the rate

``r_c = A π T / (4 N²) ∫ L(λ) QE_c(λ) λ / (h c) dλ``

(pixel area ``A``, lens transmittance ``T`` and f-number ``N``, on axis; ``QE_c``
the channel's quantum efficiency x colour filter x IR-cut filter), a weighted
sum of samples computed in Rust. :class:`Sensor` turns rates into a raw frame
with exact Poisson shot noise, dark current, fixed patterns, read noise, full
well, gain and ADC; :func:`photon_transfer` measures a sensor back from flat
fields, as EMVA 1288 does for a real camera.

Data (CIE illuminants and colour matching functions, the ColorChecker's
reflectances, measured camera sensitivities, the Mallett-Yuksel 2019 basis)
come from colour-science, imported on first use only: ``import imgform_rs``
does not need it; install ``imgform-rs[spectral]`` for these functions.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import Float64Array, as_float_array, as_real, as_seed, flag
from ._samples import F32_MAX, to_kernel
from .cfa import as_pattern, pattern_cells

Float32Array = npt.NDArray[np.float32]
Rule = Literal["trapezoid", "riemann"]

#: Planck constant, J s, and speed of light, m/s (SI, exact).
PLANCK_H = 6.626_070_15e-34
SPEED_OF_LIGHT = 299_792_458.0

#: ColorChecker data set used by default: Ohta's measurements as colour-science ships them.
COLORCHECKER = "ColorChecker N Ohta"
#: Default camera of colour-science's measured sensitivities.
DEFAULT_CAMERA = "Nikon 5100 (NPL)"


def _colour() -> Any:
    """colour-science, imported on first use (it warns about matplotlib on import)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import colour
    except ImportError as exc:  # pragma: no cover - the test extra installs it
        raise ImportError(
            "imgform_rs.spectral needs colour-science for its data sets; "
            "install it with `pip install imgform-rs[spectral]`"
        ) from exc
    return colour


def wavelengths(start: float = 380.0, stop: float = 780.0, step: float = 10.0) -> Float64Array:
    """A uniform wavelength grid in nm, ``start`` to ``stop`` inclusive.

    Examples
    --------
    >>> wl = wavelengths()
    >>> len(wl), wl[0], wl[-1]
    (41, np.float64(380.0), np.float64(780.0))
    """
    if not all(np.isfinite(v) for v in (start, stop, step)) or step <= 0:
        raise ValueError(
            f"start, stop and step must be finite with step > 0, got start={start}, "
            f"stop={stop}, step={step}"
        )
    n = round((stop - start) / step)
    if not (n >= 1 and abs(start + n * step - stop) <= 1e-9 * abs(stop)):
        raise ValueError(
            f"stop - start must be a positive multiple of step, got start={start}, "
            f"stop={stop}, step={step}"
        )
    return start + step * np.arange(n + 1, dtype=np.float64)


def check_wavelengths(wl: Any) -> Float64Array:
    """``wl`` as a checked 1-D float64 grid: >= 2 finite, positive, strictly
    increasing samples (nm); any spacing is accepted.

    Raises
    ------
    ValueError
        Naming the offending sample.

    Examples
    --------
    >>> check_wavelengths([400, 500, 650]).tolist()
    [400.0, 500.0, 650.0]
    """
    arr = as_float_array(wl, "wavelengths")
    if arr.ndim != 1:
        raise ValueError(f"wavelengths must be a 1-D array, got shape {arr.shape}")
    _native.check_wavelengths(arr.tolist())
    return np.ascontiguousarray(arr)


def _check_int(value: Any, name: str, least: int) -> int:
    """``value`` as an int >= ``least``; a float such as 14.5 is refused,
    not truncated."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
    return int(value)


def _spectra(values: Any, wl: Float64Array, name: str) -> Float64Array:
    """A table (..., L) of spectra on ``wl``, finite and >= 0, as float64."""
    arr = as_float_array(values, name)
    if arr.ndim == 0 or arr.shape[-1] != len(wl):
        raise ValueError(
            f"{name} must have {len(wl)} samples along its last axis, one per "
            f"wavelength, got shape {arr.shape}"
        )
    _native.check_spectra(name, arr.ravel().tolist(), len(wl))
    return arr


def quadrature_weights(wl: Any, rule: Rule = "trapezoid") -> Float64Array:
    """Weights (nm) such that ``∫ f dλ ≈ Σ w_i f(λ_i)``.

    ``"trapezoid"`` works on any grid; ``"riemann"`` (each sample times the
    step, CIE 15 and colour-science's rule) needs a uniform one.

    Examples
    --------
    >>> quadrature_weights([400, 410, 430]).tolist()
    [5.0, 15.0, 10.0]
    """
    return np.array(_native.spectral_weights(check_wavelengths(wl).tolist(), rule))


def _resample(domain: Any, values: Any, wl: Float64Array, name: str) -> Float64Array:
    """Linear interpolation of tabulated data (domain (K,), values (K,) or
    (K, C)) onto ``wl``, refusing to extrapolate."""
    domain = np.asarray(domain, np.float64)
    values = np.asarray(values, np.float64)
    lo, hi = domain[0], domain[-1]
    if wl[0] < lo - 1e-9 or wl[-1] > hi + 1e-9:
        raise ValueError(
            f"{name} is tabulated from {lo:g} to {hi:g} nm; the grid {wl[0]:g}..{wl[-1]:g} nm "
            "reaches outside it"
        )
    if values.ndim == 1:
        return np.interp(wl, domain, values)
    return np.stack([np.interp(wl, domain, v) for v in values.T], axis=-1)


def _grid_or_default(wl: Any) -> Float64Array:
    return wavelengths() if wl is None else check_wavelengths(wl)


def blackbody(wl: Any, temperature: float) -> Float64Array:
    """Planck's spectral radiance of a black body, W m⁻² sr⁻¹ nm⁻¹.

    Computed in Rust with the CODATA 2018 radiation constants.

    Examples
    --------
    >>> L = blackbody([500.0, 600.0], 5778.0)  # the Sun's surface
    >>> (L / 1e4).round(3).tolist()
    [2.638, 2.453]
    """
    grid = check_wavelengths(wl)
    return np.array(_native.blackbody(grid.tolist(), float(temperature)))


def illuminant(name: str, wl: Any = None) -> Float64Array:
    """A CIE illuminant's relative spectral power on ``wl``, on the scale of
    its table.

    The scale is the table's own, as colour-science ships it: 100 at 560 nm
    for A, E and the D series, but 102.8 for B, 16.16 for FL2, 2.83 for FL11
    and 14.23 for LED-B1 there. Only relative power is meaningful: scale a
    spectrum to a luminance with :func:`luminance_scale`, or to Y = 1 with
    :func:`xyz_weights`, whatever its table's scale.

    Parameters
    ----------
    name : str
        A key of colour-science's ``SDS_ILLUMINANTS``: "A", "D50", "D65",
        "FL1" .. "FL12", "LED-B1" .. "LED-V2", ...
    wl : array_like, optional
        Wavelength grid (nm); 380..780 nm in 10 nm steps by default.

    Examples
    --------
    >>> round(float(illuminant("D65", [560.0, 600.0])[0]), 6)
    100.0
    >>> round(float(illuminant("FL2", [560.0, 600.0])[0]), 2)
    16.16
    """
    grid = _grid_or_default(wl)
    colour = _colour()
    if name not in colour.SDS_ILLUMINANTS:
        raise ValueError(
            f"unknown illuminant {name!r}; accepted: {', '.join(colour.SDS_ILLUMINANTS)}"
        )
    sd = colour.SDS_ILLUMINANTS[name]
    return _resample(sd.wavelengths, sd.values, grid, f"illuminant {name}")


def colorchecker(wl: Any = None, name: str = COLORCHECKER) -> tuple[tuple[str, ...], Float64Array]:
    """The 24 ColorChecker patches' reflectances, row by row from dark skin.

    Returns
    -------
    names : tuple of str
    reflectance : ndarray, float64, shape (24, L)

    Examples
    --------
    >>> names, R = colorchecker()
    >>> names[18], R.shape, bool((R >= 0).all() and (R <= 1).all())
    ('white 9.5 (.05 D)', (24, 41), True)
    """
    grid = _grid_or_default(wl)
    colour = _colour()
    if name not in colour.SDS_COLOURCHECKERS:
        raise ValueError(
            f"unknown ColorChecker {name!r}; accepted: {', '.join(colour.SDS_COLOURCHECKERS)}"
        )
    sds = colour.SDS_COLOURCHECKERS[name]
    refl = [_resample(sd.wavelengths, sd.values, grid, f"{name}") for sd in sds.values()]
    return tuple(sds), np.stack(refl)


def camera_sensitivities(name: str = DEFAULT_CAMERA, wl: Any = None) -> Float64Array:
    """A camera's measured relative spectral sensitivities (R, G, B), shape (L, 3).

    From colour-science's ``MSDS_CAMERA_SENSITIVITIES`` (each channel's peak
    is about 1): the product of quantum efficiency, colour filter and IR-cut
    filter up to one scale, which :class:`SpectralCamera` sets with its peak
    quantum efficiency.

    Examples
    --------
    >>> camera_sensitivities().shape
    (41, 3)
    """
    grid = _grid_or_default(wl)
    colour = _colour()
    if name not in colour.MSDS_CAMERA_SENSITIVITIES:
        raise ValueError(
            f"unknown camera {name!r}; accepted: {', '.join(colour.MSDS_CAMERA_SENSITIVITIES)}"
        )
    msds = colour.MSDS_CAMERA_SENSITIVITIES[name]
    return _resample(msds.wavelengths, msds.values, grid, f"camera {name}")


def cie_cmfs(wl: Any = None) -> Float64Array:
    """The CIE 1931 2° colour matching functions x̄, ȳ, z̄ on ``wl``, shape (L, 3)."""
    grid = _grid_or_default(wl)
    cmfs = _colour().MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return _resample(cmfs.wavelengths, cmfs.values, grid, "the CIE 1931 CMFs")


def integrate(spectra: Any, wl: Any, sensitivities: Any, *, rule: Rule = "trapezoid") -> Any:
    """``∫ spectrum(λ) s_c(λ) dλ`` for every spectrum and channel, in Rust.

    Parameters
    ----------
    spectra : ndarray, shape (H, W, L), (N, L) or (L,)
        Non-negative spectra on ``wl``. float32 (H, W, L) images go to the
        kernel without a copy; anything else is converted to float32 first.
    wl : array_like, shape (L,)
        Wavelength grid, nm.
    sensitivities : array_like, shape (L, C)
        Channel sensitivities (colour-science's layout), non-negative.
    rule : {"trapezoid", "riemann"}
        Quadrature, see :func:`quadrature_weights`.

    Returns
    -------
    ndarray, float32, shape (..., C)
        Accumulated in float64 per pixel, rounded once to float32.

    Raises
    ------
    TypeError, ValueError
        Wrong shapes or dtypes, mismatched grids, negative or NaN samples,
        or integrals beyond float32's range (the first bad pixel is named).

    Examples
    --------
    >>> wl = wavelengths(400, 700, 100)
    >>> integrate(np.ones((1, 1, 4), np.float32), wl, np.ones((4, 1))).item()
    300.0
    """
    grid = check_wavelengths(wl)
    sens = as_float_array(sensitivities, "sensitivities")
    if sens.ndim != 2 or sens.shape[0] != len(grid):
        raise ValueError(
            f"sensitivities must have shape (L, C) = ({len(grid)}, C) for a grid of "
            f"{len(grid)} wavelengths, got {sens.shape}"
        )
    arr = np.asarray(spectra)
    if arr.ndim not in (1, 2, 3):
        raise ValueError(f"spectra must have shape (H, W, L), (N, L) or (L,), got {arr.shape}")
    if arr.shape[-1] != len(grid):
        raise ValueError(
            f"spectra have {arr.shape[-1]} samples per pixel but the grid has {len(grid)} "
            "wavelengths"
        )
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"spectra must be real numbers, got dtype {arr.dtype}")
    lead = arr.shape[:-1]
    flat = _as_float32(arr, "spectra")
    cube = flat.reshape((-1, 1, len(grid))) if arr.ndim < 3 else flat
    response = np.ascontiguousarray((sens * quadrature_weights(grid, rule)[:, None]).T)
    out = _native.spectral_integrate(cube, response).reshape(*lead, sens.shape[1])
    _require_in_float32(out)
    return out


def _as_float32(arr: np.ndarray, name: str) -> np.ndarray:
    """``arr`` as float32 for a kernel: floats through :func:`_samples.to_kernel`,
    which refuses finite values beyond float32's range (the cast would make them
    inf, and the kernel call them non-finite); integers as they are."""
    return to_kernel(arr, name) if arr.dtype.kind == "f" else arr.astype(np.float32)


def _require_in_float32(out: np.ndarray) -> None:
    """Refuses integrals beyond float32's range, which would come back as inf."""
    if not np.isfinite(out).all():
        at = tuple(int(i) for i in np.argwhere(~np.isfinite(out))[0][:-1])
        raise ValueError(
            f"the spectrum at index {at} integrates beyond float32's range "
            f"(largest {F32_MAX:.4g}); scale the spectra down"
        )


@dataclass(frozen=True)
class Sensor:
    """A sensor's noise and read-out model (charges in e-, levels in DN).

    Per pixel: the signal (rate x exposure time) times the fixed gain
    ``1 + prnu z``, plus dark charge, is drawn as an exact Poisson count and
    clipped at ``full_well``; the fixed offsets (``dsnu`` per pixel,
    ``column_noise`` per column) and Gaussian read noise are added; the ADC
    multiplies by ``analog_gain / electrons_per_dn``, adds ``black_level``,
    rounds and clips to ``2**bit_depth - 1``. Fixed patterns depend on
    ``pattern_seed`` only (one sensor), temporal noise on the frame's seed.

    The defaults are a 4 µm CMOS pixel: 20 000 e- full well, 2.5 e- read noise,
    14 bits with 1.28 e-/DN above a black level of 512: a gain at which the
    ADC records the whole well, as at a camera's base ISO. The well fills
    15 625 DN of the 15 871 between the black level and the white level
    16 383, so :attr:`saturation` is the full well.

    Examples
    --------
    >>> s = Sensor(read_noise=0.0)
    >>> raw = s.capture_rates(np.full((4, 4), 1000.0, np.float32), exposure_time=0.01)
    >>> raw.dtype, bool(abs(raw.mean() - (512 + 10 / 1.28)) < 5)
    (dtype('uint16'), True)
    >>> s.saturation
    20000.0
    """

    full_well: float = 20_000.0
    read_noise: float = 2.5
    electrons_per_dn: float = 1.28
    analog_gain: float = 1.0
    black_level: int = 512
    bit_depth: int = 14
    dark_current: float = 0.5
    temperature: float = 25.0
    reference_temperature: float = 25.0
    doubling_temperature: float = 6.3
    dsnu: float = 0.0
    prnu: float = 0.0
    column_noise: float = 0.0
    pattern_seed: int = 0

    def __post_init__(self) -> None:
        _check_int(self.bit_depth, "bit_depth", 1)
        _check_int(self.black_level, "black_level", 0)
        self.native(seed=0, exposure_time=1.0)  # validates every parameter

    @property
    def white_level(self) -> int:
        """The largest raw value, ``2**bit_depth - 1``."""
        return (1 << self.bit_depth) - 1

    @property
    def dn_per_electron(self) -> float:
        """EMVA 1288's system gain ``K``: ``analog_gain / electrons_per_dn``."""
        return self.analog_gain / self.electrons_per_dn

    @property
    def saturation(self) -> float:
        """The largest signal the sensor records, e-: the full well, or less
        when the ADC clips first (``(white_level - black_level) /
        dn_per_electron``)."""
        return min(self.full_well, (self.white_level - self.black_level) / self.dn_per_electron)

    def native(self, *, seed: int, exposure_time: float) -> _native.NativeSensor:
        """The validated native sensor for one frame."""
        as_seed(seed, "seed")
        as_seed(self.pattern_seed, "pattern_seed")
        return _native.NativeSensor(
            exposure_time=float(exposure_time),
            full_well=float(self.full_well),
            read_noise=float(self.read_noise),
            electrons_per_dn=float(self.electrons_per_dn),
            analog_gain=float(self.analog_gain),
            black_level=int(self.black_level),
            bit_depth=int(self.bit_depth),
            dark_current=float(self.dark_current),
            temperature=float(self.temperature),
            reference_temperature=float(self.reference_temperature),
            doubling_temperature=float(self.doubling_temperature),
            dsnu=float(self.dsnu),
            prnu=float(self.prnu),
            column_noise=float(self.column_noise),
            seed=int(seed),
            pattern_seed=int(self.pattern_seed),
        )

    def capture_rates(
        self, rates: Any, *, exposure_time: float, seed: int = 0
    ) -> npt.NDArray[np.uint16]:
        """One frame of a field of mean photo-electron rates (e-/s), shape (H, W).

        Examples
        --------
        >>> Sensor(read_noise=0, dark_current=0).capture_rates(
        ...     np.zeros((2, 2), np.float32), exposure_time=1.0).tolist()
        [[512, 512], [512, 512]]
        """
        arr = np.asarray(rates)
        if arr.dtype.kind not in "iuf":
            raise TypeError(f"rates must be real numbers, got dtype {arr.dtype}")
        native = self.native(seed=seed, exposure_time=exposure_time)
        return native.capture_rates(_as_float32(arr, "rates"))


def auto_exposure(
    rates: Any,
    sensor: Sensor,
    *,
    target: float = 0.18,
    percentile: float | None = None,
) -> float:
    """The exposure time (s) that puts a scene's signal at ``target`` of the
    sensor's :attr:`Sensor.saturation`, as a camera's meter does.

    Parameters
    ----------
    rates : array_like, e-/s
        The scene's noise-free photo-electron rates, any shape: e.g.
        :meth:`SpectralCamera.camera_rates` of a radiance image (every
        channel counts), or the rates of a mosaic.
    sensor : Sensor
    target : float
        Fraction of saturation in (0, 1]: 0.18 puts the mean at "middle grey";
        with a percentile, 1.0 just avoids clipping it.
    percentile : float, optional
        Meter a percentile of the rates (0-100, e.g. 99 to protect highlights)
        instead of their mean.

    Raises
    ------
    ValueError
        A target or percentile out of range, negative or NaN rates, or a
        black scene (nothing to meter).

    Examples
    --------
    >>> round(auto_exposure(np.full((2, 2), 1000.0), Sensor(full_well=10_000)), 4)
    1.8
    """
    arr = as_float_array(rates, "rates")
    if arr.size == 0 or not (np.isfinite(arr).all() and (arr >= 0).all()):
        raise ValueError("rates must be a non-empty array of finite values >= 0 (e-/s)")
    if not (np.isfinite(target) and 0 < target <= 1):
        raise ValueError(f"target must be a fraction of saturation in (0, 1], got {target!r}")
    if percentile is None:
        level = float(arr.mean())
    elif np.isfinite(percentile) and 0 <= percentile <= 100:
        level = float(np.percentile(arr, percentile))
    else:
        raise ValueError(f"percentile must be in [0, 100], got {percentile!r}")
    if not level > 0:
        raise ValueError("the scene is black where it is metered: no exposure reaches the target")
    return target * sensor.saturation / level


def exposure_bracket(exposure_time: float, stops: Any = (-2.0, 0.0, 2.0)) -> list[float]:
    """Exposure times ``exposure_time * 2**stop`` for each of ``stops`` (EV).

    Examples
    --------
    >>> exposure_bracket(0.01, (-1, 0, 1))
    [0.005, 0.01, 0.02]
    """
    if not (np.isfinite(exposure_time) and exposure_time > 0):
        raise ValueError(f"exposure_time must be a finite number > 0, got {exposure_time!r}")
    steps = as_float_array(stops, "stops")
    if steps.ndim != 1 or not np.isfinite(steps).all():
        raise ValueError(f"stops must be a 1-D sequence of finite EV steps, got {stops!r}")
    with np.errstate(over="ignore", under="ignore"):
        times = [float(exposure_time * 2.0**s) for s in steps]
    if not all(np.isfinite(t) and t > 0 for t in times):
        # 2**1100 overflows and 2**-1100 underflows: no time a Sensor takes.
        raise ValueError(
            f"stops {steps.tolist()} take exposure_time {exposure_time!r} beyond a finite time > 0"
        )
    return times


def flat_pair_stats(a: Any, b: Any) -> tuple[float, float, float]:
    """Mean, temporal variance and spatial variance (DN, DN², DN²) of two
    frames of one flat field.

    The temporal variance is ``var(a - b) / 2`` (fixed patterns cancel in
    the difference); the spatial one is that of ``(a + b) / 2`` over the
    pixels. Sums are exact integers, so results do not depend on threads.

    Examples
    --------
    >>> a = np.array([[10, 12]], np.uint16); b = np.array([[12, 10]], np.uint16)
    >>> flat_pair_stats(a, b)
    (11.0, 2.0, 0.0)
    """
    frames = []
    for name, f in (("a", a), ("b", b)):
        arr = np.asarray(f)
        if arr.dtype != np.uint16:
            raise TypeError(f"frame {name} must be a uint16 raw, got dtype {arr.dtype}")
        if arr.ndim != 2:
            raise ValueError(f"frame {name} must be one frame (H, W), got shape {arr.shape}")
        frames.append(arr)
    return _native.flat_pair_stats(frames[0], frames[1])


class PhotonTransfer(NamedTuple):
    """The result of :func:`photon_transfer` (EMVA 1288 names in brackets).

    Attributes
    ----------
    mean : ndarray, float64
        Dark-subtracted mean signal per exposure, DN (μ_y - μ_y.dark).
    variance : ndarray, float64
        Temporal variance per exposure, DN² (σ²_y).
    conversion_gain : float
        Fitted slope, DN per e- (the system gain K).
    read_noise : float
        ``sqrt(σ²_y.dark - 1/12) / K`` from the dark pair of the shortest
        exposure, e- (σ_d; the 1/12 DN² is the ADC's quantisation noise): the
        line's intercept measured directly rather than extrapolated. The
        shortest exposure is the one of least signal, wherever its pairs
        stand in the lists; its dark pair holds the least dark charge.
    full_well : float
        Mean signal where the variance peaks, over K, e- (μ_e.sat).
    dsnu : float
        Spatial standard deviation of that dark pair's mean minus its
        residual temporal part, e- (DSNU1288).
    prnu : float
        Same for the brightest fitted exposure, over its mean signal, as a
        fraction (PRNU1288 / 100).
    fitted : ndarray, bool
        The exposures inside the fit (mean up to 70 % of saturation).
    """

    mean: Float64Array
    variance: Float64Array
    conversion_gain: float
    read_noise: float
    full_well: float
    dsnu: float
    prnu: float
    fitted: npt.NDArray[np.bool_]


def _check_pairs(pairs: list[Any]) -> None:
    """Every exposure a pair of 2-D frames, all of one shape (one sensor)."""
    shapes = set()
    for i, pair in enumerate(pairs):
        if isinstance(pair, np.ndarray) or len(pair) != 2:
            raise ValueError(
                f"each exposure must be a pair (frame, frame) of 2-D raws; item {i} is not"
            )
        shapes.update(np.shape(frame) for frame in pair)
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(
            f"all flat and dark frames must be 2-D raws of one shape, got shapes {sorted(shapes)}"
        )


def photon_transfer(flats: Any, darks: Any) -> PhotonTransfer:
    """Photon-transfer analysis of flat-field and dark frame pairs.

    Parameters
    ----------
    flats, darks : sequence of (ndarray, ndarray)
        For each exposure, two uint16 frames of a uniform field and two dark
        frames at the same exposure time (EMVA 1288's sensitivity
        measurement). Exposures must reach saturation for the full well.

    Returns
    -------
    PhotonTransfer

    Notes
    -----
    The mean-variance line ``σ²_y - σ²_y.dark = K (μ_y - μ_y.dark)`` is fitted
    through the origin by least squares over the exposures whose mean lies
    below 70 % of the saturation mean (where the variance peaks), as EMVA 1288
    (release 4) prescribes. Extrapolating a free line to its intercept instead
    scatters the read noise by ±5-9 % between sets of 256 x 256 frames; the
    dark frames measure it to ~0.3 %.

    Raises
    ------
    ValueError
        Fewer than three exposures, mismatched pair counts, items that are
        not pairs, frames of different shapes, flats with no signal above
        their darks, a temporal variance that does not grow with the signal,
        or no exposure below 70 % of saturation.
    """
    flats, darks = list(flats), list(darks)
    if len(flats) != len(darks) or len(flats) < 3:
        raise ValueError(
            "photon_transfer needs one dark pair per flat pair and at least 3 exposures, "
            f"got {len(flats)} flat and {len(darks)} dark pairs"
        )
    _check_pairs(flats + darks)
    f = np.array([flat_pair_stats(a, b) for a, b in flats])
    d = np.array([flat_pair_stats(a, b) for a, b in darks])
    mean = f[:, 0] - d[:, 0]
    # A signal is a mean rise of at least the dark frames' own temporal noise
    # (one pixel's sigma); unlit flats differ from their darks by far less.
    if not (mean > np.sqrt(d[:, 1])).any():
        raise ValueError(
            "photon_transfer needs flats lit above the dark noise; no flat pair's mean "
            f"rises above its dark pair's by the darks' temporal sigma (largest rise "
            f"{mean.max():g} DN): no light reached the sensor"
        )
    var = f[:, 1]
    sat = int(np.argmax(var))
    fitted = mean <= 0.7 * mean[sat]
    if fitted.sum() < 2:
        raise ValueError("photon_transfer needs at least 2 exposures below 70 % of saturation")
    # Photon-induced variance against signal, a line through the origin.
    x, y = mean[fitted], var[fitted] - d[fitted, 1]
    K = float(np.dot(x, y) / np.dot(x, x))
    if not K > 0:
        raise ValueError(
            "photon_transfer needs a temporal variance that grows with the signal (shot "
            f"noise); the fitted gain is K = {K:g} DN/e-: these are not frames of a sensor's "
            "photo-electrons"
        )
    shortest = int(np.argmin(mean))
    read_noise = float(np.sqrt(max(d[shortest, 1] - 1.0 / 12.0, 0.0)) / K)
    # The pair mean keeps half of each frame's temporal variance.
    dsnu = float(np.sqrt(max(d[shortest, 2] - d[shortest, 1] / 2.0, 0.0)) / K)
    bright = int(np.flatnonzero(fitted)[np.argmax(mean[fitted])])
    spatial = f[bright, 2] - f[bright, 1] / 2.0 - (d[bright, 2] - d[bright, 1] / 2.0)
    prnu = float(np.sqrt(max(spatial, 0.0)) / mean[bright])
    return PhotonTransfer(mean, var, K, read_noise, float(mean[sat] / K), dsnu, prnu, fitted)


def cos4_falloff(
    height: int,
    width: int,
    *,
    focal_length: float,
    pixel_pitch: float,
    center: Any = None,
) -> Float32Array:
    """The natural falloff of image-plane irradiance, ``cos⁴ θ``, per pixel.

    A pixel ``r`` from the optical centre sees the scene along a chief ray at
    ``θ = atan(r / focal_length)`` (lens focused at infinity). Its irradiance
    is the on-axis ``π T L / (4 N²)`` times ``cos⁴ θ``: the exit pupil looks
    ``cos θ`` smaller, the ray meets the pixel ``cos θ`` obliquely, and the
    pupil is ``1 / cos θ`` farther away (squared). Computed as
    ``1 / (1 + r² / f²)²``, the same without trigonometry.

    Multiply a radiance image ``(H, W, L)`` by ``falloff[..., None]`` or a
    frame of rates ``(H, W)`` by ``falloff`` before the sensor reads it; or
    give :class:`SpectralCamera` a ``focal_length``, and its captures apply
    the same falloff inside the kernel without building this image.

    Parameters
    ----------
    height, width : int
        Image size, pixels.
    focal_length : float
        mm, > 0.
    pixel_pitch : float
        µm, > 0 (:class:`SpectralCamera`'s unit).
    center : (cx, cy), optional
        Optical centre in pixels; default the image centre.

    Returns
    -------
    ndarray, float32, shape (H, W)
        1 on the axis.

    Examples
    --------
    >>> f = cos4_falloff(3, 3, focal_length=1.0, pixel_pitch=1000.0)
    >>> f[1, 1], f[1, 2], round(float(f[0, 0]), 4)  # r = f: cos⁴ 45° = 1/4
    (np.float32(1.0), np.float32(0.25), 0.1111)
    """
    for name, value in (("focal_length", focal_length), ("pixel_pitch", pixel_pitch)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    if not all(isinstance(v, (int, np.integer)) and v > 0 for v in (height, width)):
        raise ValueError(f"height and width must be ints > 0, got {height!r} x {width!r}")
    if center is None:
        cx, cy = (width - 1) / 2, (height - 1) / 2
    else:
        c = as_float_array(center, "center")
        if c.shape != (2,) or not np.isfinite(c).all():
            raise ValueError(f"center must be two finite numbers (cx, cy), got {center!r}")
        cx, cy = c.tolist()
    scale = pixel_pitch * 1e-3 / focal_length
    ty = ((np.arange(height) - cy) * scale)[:, None] ** 2
    tx = ((np.arange(width) - cx) * scale)[None, :] ** 2
    return (1.0 / (1.0 + ty + tx) ** 2).astype(np.float32)


@dataclass(frozen=True)
class SpectralCamera:
    """A camera: lens, spectral sensitivities and :class:`Sensor`.

    Parameters
    ----------
    wavelengths : array_like, shape (L,)
        The grid of ``sensitivities`` and of every spectral image captured.
    sensitivities : array_like, shape (L, 3)
        R, G, B relative sensitivity (QE x colour filter x IR-cut) with peak
        ``peak_qe`` after scaling; e.g. :func:`camera_sensitivities`.
    sensor : Sensor
    pattern : str or array_like
        CFA pattern of pixel (0, 0) (Bayer names, "XTRANS", or a tile).
    pixel_pitch : float
        Pixel pitch, µm (the photodiode area is its square: fill factor 1,
        microlenses assumed).
    f_number, transmittance : float
        The lens: image-plane irradiance is ``π T L / (4 N²)`` on axis (off
        axis, times :func:`cos4_falloff`).
    focal_length : float, optional
        mm. When given, :meth:`capture` and :meth:`capture_rgb` dim every
        pixel by its :func:`cos4_falloff` about the image centre, inside the
        capture kernel (no falloff image, no extra pass). ``None`` (default):
        no falloff, as behind a telecentric lens.
    peak_qe : float
        Quantum efficiency at the sensitivities' maximum.
    rule : {"trapezoid", "riemann"}
        Quadrature over the grid.
    """

    wavelengths: Any = field(default_factory=wavelengths)
    sensitivities: Any = None
    sensor: Sensor = field(default_factory=Sensor)
    pattern: Any = "RGGB"
    pixel_pitch: float = 4.0
    f_number: float = 4.0
    transmittance: float = 0.9
    peak_qe: float = 0.5
    rule: Rule = "trapezoid"
    focal_length: float | None = None

    def __post_init__(self) -> None:
        grid = check_wavelengths(self.wavelengths)
        if self.sensitivities is None:
            sens = camera_sensitivities(DEFAULT_CAMERA, grid)
        else:
            given = as_float_array(self.sensitivities, "sensitivities")
            if given.shape != (len(grid), 3):
                raise ValueError(
                    f"sensitivities must have shape (L, 3) = ({len(grid)}, 3), a row of R, G, "
                    f"B per wavelength, got shape {given.shape}"
                )
            sens = _spectra(given.T, grid, "sensitivities").T
        if not (sens.max(axis=0) > 0).all():
            raise ValueError(
                "sensitivities must be > 0 somewhere in every channel (R, G, B), got a "
                f"channel of zeros (peaks {sens.max(axis=0).tolist()})"
            )
        pattern_cells(self.pattern)  # refuses an unknown CFA pattern by name
        quadrature_weights(grid, self.rule)  # refuses an unknown rule or a non-uniform riemann grid
        for name in ("pixel_pitch", "f_number", "peak_qe"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        if self.focal_length is not None and not (
            np.isfinite(self.focal_length) and self.focal_length > 0
        ):
            raise ValueError(
                f"focal_length must be None or a finite number > 0 (mm), got {self.focal_length!r}"
            )
        if not (np.isfinite(self.transmittance) and 0 < self.transmittance <= 1):
            raise ValueError(f"transmittance must be in (0, 1], got {self.transmittance!r}")
        object.__setattr__(self, "wavelengths", grid)
        object.__setattr__(self, "sensitivities", sens)

    def response(self) -> Float64Array:
        """Electrons per second per unit of radiance sample, shape (3, L).

        ``π T / (4 N²) · A · peak_qe · s_c(λ) / max s · λ / (h c) · w(λ)``, with
        radiance in W m⁻² sr⁻¹ nm⁻¹ and ``w`` the quadrature weights (nm).
        """
        grid = self.wavelengths
        qe = self.peak_qe * self.sensitivities / self.sensitivities.max()
        area = (self.pixel_pitch * 1e-6) ** 2
        irradiance = np.pi * self.transmittance / (4.0 * self.f_number**2)
        photons_per_joule = grid * 1e-9 / (PLANCK_H * SPEED_OF_LIGHT)
        w = quadrature_weights(grid, self.rule)
        return np.ascontiguousarray((qe * (irradiance * area * photons_per_joule * w)[:, None]).T)

    def capture(
        self, radiance: Any, *, exposure_time: float, seed: int = 0
    ) -> npt.NDArray[np.uint16]:
        """A raw frame of spectral radiance (H, W, L) float32, W m⁻² sr⁻¹ nm⁻¹.

        The (H, W, L) array is read once, in Rust; no float64 copy is made.

        Raises
        ------
        TypeError
            A dtype other than float32.
        ValueError
            A grid mismatch, a wrong shape, or negative / NaN radiance.
        """
        self._check_samples(radiance, "radiance")
        native = self.sensor.native(seed=seed, exposure_time=exposure_time)
        return native.capture_spectral(
            radiance, self.response(), as_pattern(self.pattern), self._falloff(radiance)
        )

    def _falloff(self, image: Any) -> tuple[float, float, float] | None:
        """The native kernels' cos⁴ falloff of an image: its centre (x, y)
        and the pixel pitch in focal lengths; ``None`` without a focal length
        (or for an array the kernel will refuse by its shape)."""
        shape = np.shape(image)
        if self.focal_length is None or len(shape) < 2:
            return None
        h, w = shape[:2]
        return ((w - 1) / 2, (h - 1) / 2, self.pixel_pitch * 1e-3 / self.focal_length)

    def _check_samples(self, spectra: Any, name: str) -> None:
        """The spectra's last axis matches this camera's grid (a mismatch is
        a different grid, not a wrong response)."""
        n = np.shape(spectra)[-1:]
        if n != (len(self.wavelengths),):
            raise ValueError(
                f"{name} must have one sample per wavelength of the camera's grid "
                f"({len(self.wavelengths)}, {self.wavelengths[0]:g}-{self.wavelengths[-1]:g} nm) "
                f"along its last axis, got shape {np.shape(spectra)}"
            )

    def camera_rates(self, radiance: Any) -> Float32Array:
        """Noise-free mean electron rates (e-/s) of every channel, shape (..., 3),
        of radiance (..., L): what the sensor's photodiodes average to."""
        arr = as_real(radiance, "radiance", np.float32)
        self._check_samples(arr, "radiance")
        lead = arr.shape[:-1]
        cube = arr.reshape((-1, 1, arr.shape[-1]) if arr.ndim < 3 else arr.shape)
        return _native.spectral_integrate(cube, self.response()).reshape(*lead, 3)

    def rgb_matrix(self, illuminant_radiance: Any) -> Float64Array:
        """Electrons per second per unit of linear sRGB, shape (3, 3).

        An RGB pixel upsampled with :func:`upsampling_basis` ``B`` and lit by
        ``E`` has the spectrum ``E(λ) B(λ) rgb``, linear in ``rgb``; so the
        camera's rates are ``response @ (E B) @ rgb``: this 3x3 matrix, computed
        once, replaces the per-pixel spectra.
        """
        spd = _spectra(illuminant_radiance, self.wavelengths, "illuminant_radiance")
        return self.response() @ (spd[:, None] * upsampling_basis(self.wavelengths, self.rule))

    def capture_rgb(
        self,
        rgb: Any,
        *,
        illuminant_radiance: Any,
        exposure_time: float,
        seed: int = 0,
    ) -> npt.NDArray[np.uint16]:
        """A raw frame of a linear sRGB image (H, W, 3) float32 taken as
        reflectances under ``illuminant_radiance`` (W m⁻² sr⁻¹ nm⁻¹ of the
        perfect white, shape (L,)).

        Upsampled on the fly: each pixel's spectrum is never built, because
        the camera response of the three-function basis is the 3x3
        :meth:`rgb_matrix` (so this costs one 3-term dot product per pixel
        whatever the number of wavelengths). Negative components (out of
        gamut) count as 0.
        """
        arr = np.asarray(rgb)
        if arr.dtype != np.float32:
            raise TypeError(f"rgb must be a float32 (H, W, 3) image, got dtype {arr.dtype}")
        native = self.sensor.native(seed=seed, exposure_time=exposure_time)
        matrix = np.ascontiguousarray(self.rgb_matrix(illuminant_radiance))
        return native.capture_rgb(arr, matrix, as_pattern(self.pattern), self._falloff(arr))


# --- RGB -> spectrum ----------------------------------------------------------------------

#: XYZ (D65) -> linear sRGB, IEC 61966-2-1 (the matrix colour-science uses).
XYZ_TO_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def xyz_weights(wl: Any, illuminant_spd: Any, rule: Rule = "trapezoid") -> Float64Array:
    """Per-sample weights (L, 3) that turn a reflectance under
    ``illuminant_spd`` into XYZ with the illuminant's Y = 1:
    ``XYZ = reflectance @ weights``, the weights ``x̄ȳz̄ S w / Σ ȳ S w``
    (``w`` the quadrature weights)."""
    grid = check_wavelengths(wl)
    spd = _spectra(illuminant_spd, grid, "illuminant_spd")
    cmfs = cie_cmfs(grid)
    w = quadrature_weights(grid, rule)
    luminance = np.sum(cmfs[:, 1] * spd * w)
    if not luminance > 0:
        raise ValueError(
            "illuminant_spd has no luminance (Y = 0): it is zero where the eye sees, so "
            "nothing normalises its Y to 1"
        )
    return cmfs * (spd * w)[:, None] / luminance


def upsampling_basis(wl: Any = None, rule: Rule = "trapezoid") -> Float64Array:
    """The three reflectance spectra (L, 3) that linear sRGB components scale.

    Mallett and Yuksel's 2019 basis (shipped in colour-science; non-negative,
    summing to 1, so ``rgb`` in [0, 1] gives a reflectance in [0, 1]), times
    the inverse of its own sRGB under D65 on this grid and rule (within 1 % of
    the identity): then ``spectrum -> sRGB`` gives ``rgb`` back exactly on this
    grid. The corrected functions stay >= 0; their sum departs from 1 by
    < 0.1 % at 10 nm (0.02 % at 5 nm), so sRGB white reflects at most 1.0009.

    Examples
    --------
    >>> B = upsampling_basis()
    >>> B.shape, bool(B.min() >= 0), bool(abs(B.sum(1) - 1).max() < 1e-3)
    ((41, 3), True, True)
    """
    grid = _grid_or_default(wl)
    from colour.recovery import MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019 as basis

    _colour()
    b = _resample(basis.wavelengths, basis.values, grid, "the Mallett-Yuksel basis")
    srgb_of_basis = XYZ_TO_SRGB @ (b.T @ xyz_weights(grid, illuminant("D65", grid), rule)).T
    # A grid too coarse or too narrow to see the three primaries apart makes
    # the correction singular or drives reflectances below 0.
    singular = np.linalg.cond(srgb_of_basis) > 1e3
    corrected = b if singular else b @ np.linalg.inv(srgb_of_basis)
    if singular or corrected.min() < 0:
        raise ValueError(
            f"a grid of {len(grid)} wavelengths from {grid[0]:g} to {grid[-1]:g} nm is too "
            "coarse or too narrow to carry sRGB as non-negative reflectances; use one "
            "covering 400-700 nm in steps of 20 nm or less"
        )
    return corrected


def rgb_to_reflectance(rgb: Any, wl: Any = None, rule: Rule = "trapezoid") -> Float64Array:
    """Reflectance spectra (..., L) of linear sRGB colours (..., 3).

    Negative components (colours outside sRGB) are clipped to 0: the basis
    has no negative reflectance to offer them. The spectra are materialised:
    for images, :meth:`SpectralCamera.capture_rgb` folds the basis into a 3x3
    matrix instead.

    Examples
    --------
    >>> R = rgb_to_reflectance([0.2, 0.5, 0.1])
    >>> R.shape, bool((R >= 0).all())
    ((41,), True)
    """
    arr = as_float_array(rgb, "rgb")
    if arr.shape[-1:] != (3,):
        raise ValueError(f"rgb must have shape (..., 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("rgb must be finite")
    return np.clip(arr, 0.0, None) @ upsampling_basis(wl, rule).T


def reflectance_to_rgb(reflectance: Any, wl: Any = None, rule: Rule = "trapezoid") -> Float64Array:
    """Linear sRGB (..., 3) of reflectances (..., L) under D65 (white Y = 1)."""
    grid = _grid_or_default(wl)
    refl = _spectra(reflectance, grid, "reflectance")
    return refl @ xyz_weights(grid, illuminant("D65", grid), rule) @ XYZ_TO_SRGB.T


def luminance_scale(spd: Any, wl: Any, luminance: float) -> Float64Array:
    """``spd`` scaled to a spectral radiance (W m⁻² sr⁻¹ nm⁻¹) of ``luminance``
    cd/m² (683 lm/W x ∫ L ȳ dλ, trapezoidal)."""
    grid = check_wavelengths(wl)
    spd = _spectra(spd, grid, "spd")
    if not (np.isfinite(luminance) and luminance >= 0):
        raise ValueError(f"luminance must be a finite number >= 0 (cd/m²), got {luminance!r}")
    lum = 683.0 * np.sum(spd * cie_cmfs(grid)[:, 1] * quadrature_weights(grid))
    if not lum > 0:
        raise ValueError("spd has no luminance: it is zero where the eye sees")
    return spd * (float(luminance) / lum)


# --- characterisation ---------------------------------------------------------------------


def _white(white_xyz: Any) -> Float64Array:
    """A reference white: three finite XYZ values > 0 (L*a*b* divides by
    each: a white with X or Z of 0 gave infinite b*)."""
    white = as_float_array(white_xyz, "white_xyz")
    if white.shape != (3,) or not np.isfinite(white).all():
        raise ValueError(
            f"white_xyz must be 3 finite values X, Y, Z > 0, got {np.asarray(white_xyz)!r}"
        )
    if not (white > 0).all():
        raise ValueError(
            f"white_xyz must have X, Y, Z > 0 (a white holds some of each, and a "
            f"luminance Y > 0), got {white.tolist()}"
        )
    return white


def _xyz_rows(xyz: Any, name: str) -> Float64Array:
    """Colours (..., 3), finite."""
    arr = as_float_array(xyz, name)
    if arr.shape[-1:] != (3,) or not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite XYZ values, shape (..., 3), got shape {arr.shape}")
    return arr


def xyz_to_lab(xyz: Any, white_xyz: Any) -> Float64Array:
    """CIE L*a*b* of XYZ relative to ``white_xyz`` (CIE 15; colour-science)."""
    colour = _colour()
    white = _white(white_xyz)
    return colour.XYZ_to_Lab(_xyz_rows(xyz, "xyz") / white[1], colour.XYZ_to_xy(white))


def delta_e2000(xyz: Any, xyz_ref: Any, white_xyz: Any) -> Float64Array:
    """CIEDE2000 colour differences between XYZ rows (white ``white_xyz``).

    Raises
    ------
    ValueError
        Rows of different shapes, non-finite values, or a white without
        luminance.

    Examples
    --------
    >>> white = [0.9505, 1.0, 1.089]
    >>> float(delta_e2000([0.2, 0.2, 0.2], [0.2, 0.2, 0.2], white))
    0.0
    """
    colour = _colour()
    a, b = _xyz_rows(xyz, "xyz"), _xyz_rows(xyz_ref, "xyz_ref")
    if a.shape != b.shape:
        raise ValueError(f"xyz and xyz_ref must have one shape, got {a.shape} and {b.shape}")
    lab, lab_ref = xyz_to_lab(a, white_xyz), xyz_to_lab(b, white_xyz)
    return np.asarray(colour.delta_E(lab, lab_ref, method="CIE 2000"))


class ColorFit(NamedTuple):
    """A fitted colour matrix and its errors on the training patches.

    Attributes
    ----------
    matrix : ndarray, float64, shape (3, 3)
        Camera RGB (not white-balanced) -> XYZ.
    delta_e : ndarray, float64, shape (N,)
        CIEDE2000 of each patch.
    """

    matrix: Float64Array
    delta_e: Float64Array

    @property
    def mean_delta_e(self) -> float:
        """Mean CIEDE2000 over the patches."""
        return float(self.delta_e.mean())

    @property
    def max_delta_e(self) -> float:
        """Largest CIEDE2000 of a patch."""
        return float(self.delta_e.max())


def fit_color_matrix(
    camera_rgb: Any,
    xyz: Any,
    white_xyz: Any,
    *,
    method: Literal["least_squares", "de2000"] = "least_squares",
    white_rgb: Any = None,
) -> ColorFit:
    """The 3x3 matrix ``M`` with ``xyz ≈ camera_rgb @ M.T``.

    ``"least_squares"`` minimises the squared XYZ error over the patches;
    ``"de2000"`` starts there and refines the entries by Levenberg-Marquardt
    on the patches' CIEDE2000 (scipy's ``least_squares``).

    Given the camera's response to the white, ``white_rgb``, the fit keeps
    ``M @ white_rgb = white_xyz`` exactly (white-point preserving least
    squares, Finlayson and Drew 1996): a neutral then stays neutral, where a
    free fit may leave it about 1 CIEDE2000 off, and ``dng_color_tags``'s
    neutral is the camera's own.

    Parameters
    ----------
    camera_rgb, xyz : array_like, shape (N, 3)
        Training patches (N >= 3), e.g. a simulated ColorChecker.
    white_xyz : array_like, shape (3,)
        The white the Lab differences refer to.
    white_rgb : array_like, shape (3,), optional
        The camera RGB of that white, each > 0.

    Raises
    ------
    ValueError
        Shapes other than (N, 3), non-finite values, a bad white, or camera
        RGB of rank < 3 (the matrix would be any of infinitely many).
    """
    rgb = as_float_array(camera_rgb, "camera_rgb")
    target = as_float_array(xyz, "xyz")
    if rgb.ndim != 2 or rgb.shape[1] != 3 or rgb.shape != target.shape or len(rgb) < 3:
        raise ValueError(
            "camera_rgb and xyz must both have shape (N, 3) with N >= 3, got "
            f"{rgb.shape} and {target.shape}"
        )
    if method not in ("least_squares", "de2000"):
        raise ValueError(f'method must be "least_squares" or "de2000", got {method!r}')
    if not (np.isfinite(rgb).all() and np.isfinite(target).all()):
        raise ValueError("camera_rgb and xyz must be finite (a NaN or inf patch has no colour)")
    white = _white(white_xyz)
    rank = int(np.linalg.matrix_rank(rgb))
    if rank < 3:
        raise ValueError(
            f"camera_rgb has rank {rank}: its patches span fewer than 3 independent "
            "colours, so they determine no 3x3 matrix (patches of one hue, or a channel "
            "that reads 0 or copies another)"
        )
    # Camera values in e-/s are ~1e10 times XYZ; fitting on values scaled to
    # order 1 keeps the optimiser's steps and tolerances meaningful.
    scale = float(np.abs(rgb).max())
    unit = rgb / scale
    matrix = np.linalg.lstsq(unit, target, rcond=None)[0].T
    # The matrix moves only along ``free`` (3 x k): every row's change is a
    # mix of its columns, which a preserved white's RGB is orthogonal to.
    free = np.eye(3)
    if white_rgb is not None:
        w = _white_rgb(white_rgb) / scale
        # The least-squares correction that takes w to the white exactly.
        gram_w = np.linalg.solve(unit.T @ unit, w)
        matrix += np.outer(white - matrix @ w, gram_w) / (w @ gram_w)
        free = np.linalg.svd(w[None])[2][1:].T
    if method == "de2000":
        from scipy.optimize import least_squares

        def moved(change: Float64Array) -> Float64Array:
            return matrix + change.reshape(3, -1) @ free.T

        def residuals(change: Float64Array) -> Float64Array:
            return delta_e2000(unit @ moved(change).T, target, white_xyz)

        start = np.zeros(3 * free.shape[1])
        matrix = moved(least_squares(residuals, start, method="lm").x)
    return ColorFit(matrix / scale, delta_e2000(unit @ matrix.T, target, white_xyz))


def _white_rgb(white_rgb: Any) -> Float64Array:
    """A camera white: three finite values > 0."""
    w = as_float_array(white_rgb, "white_rgb")
    if w.shape != (3,) or not (np.isfinite(w).all() and (w > 0).all()):
        raise ValueError(
            f"white_rgb must be the camera's 3 finite values > 0 for the white, got {white_rgb!r}"
        )
    return w


def characterise(
    camera: SpectralCamera,
    illuminant_name: str = "D65",
    *,
    method: Literal["least_squares", "de2000"] = "least_squares",
    preserve_white: bool = True,
) -> ColorFit:
    """Fit ``camera``'s colour matrix on a simulated, noise-free ColorChecker.

    The 24 patches lit by the CIE illuminant give the camera's mean rates
    (integrated in Rust) and their XYZ (white Y = 1), and
    :func:`fit_color_matrix` relates them, keeping the camera's response to
    the perfect white on the white when ``preserve_white``: the greys then
    stay neutral, and for the Nikon 5100 the patches' mean error drops too
    (the spectral guide gives the figures).

    Examples
    --------
    >>> fit = characterise(SpectralCamera())
    >>> fit.matrix.shape, bool(fit.mean_delta_e < 3)
    ((3, 3), True)
    """
    wl = camera.wavelengths
    spd = illuminant(illuminant_name, wl)
    _, refl = colorchecker(wl)
    weights = xyz_weights(wl, spd, camera.rule)
    xyz = refl @ weights
    white = weights.sum(axis=0)
    rgb = camera.camera_rates(refl * spd)
    white_rgb = None
    if flag(preserve_white, "preserve_white"):
        white_rgb = camera.camera_rates(spd[None])[0]
    return fit_color_matrix(rgb, xyz, white, method=method, white_rgb=white_rgb)


def idt_matrix(
    wl: Any, sensitivities: Any, illuminant_spd: Any
) -> tuple[Float64Array, Float64Array]:
    """An ACES input device transform fitted as *RAW to ACES* v1 does.

    The 190 training reflectances of *RAW to ACES* (colour-science's copy),
    lit by ``illuminant_spd``, give white-balanced camera RGB and XYZ adapted
    to the ACES white by CAT02; the 3x3 matrix ``M``,
    its rows summing to 1 so that the balanced white stays white, minimises
    the Euclidean norm of the CIE L*a*b* errors of ``ACES → XYZ (M rgb)``
    over the patches (BFGS from the identity). This is the procedure of
    colour-science's ``matrix_idt`` with its defaults, but for one choice.

    The fit is not scale-free (L*a*b* is not linear), so the light's scale
    matters: it is set so that the balanced perfect white reads 1, by the
    channel that responds most to the light. colour-science takes the
    channel whose sensitivity peaks highest instead, which for a camera whose
    tabulated peaks tie (the default Nikon 5100, each channel normalised to
    1) turns on the sampling (the spectral guide gives the figures). Where
    both rules pick the same channel, a test reproduces ``matrix_idt`` to
    1e-3.

    Parameters
    ----------
    wl : array_like, shape (L,)
        The grid, nm; the sums over it are trapezoidal, so an uneven grid
        gives what a uniform one does.
    sensitivities : array_like, shape (L, 3)
        The camera's R, G, B sensitivities, finite and >= 0, each channel
        with some response to the light.
    illuminant_spd : array_like, shape (L,)
        The scene illuminant.

    Returns
    -------
    matrix : ndarray, float64, shape (3, 3)
        White-balanced camera RGB -> ACES2065-1.
    white_balance : ndarray, float64, shape (3,)
        The multipliers applied to camera RGB first (smallest 1).
    """
    import os

    from scipy.optimize import minimize

    colour = _colour()
    grid = check_wavelengths(wl)
    sens = as_float_array(sensitivities, "sensitivities")
    if sens.shape != (len(grid), 3):
        raise ValueError(f"sensitivities must have shape ({len(grid)}, 3), got {sens.shape}")
    _spectra(sens.T, grid, "sensitivities")
    # Trapezoid weights fold into the light: every sum below is over it.
    spd = _spectra(illuminant_spd, grid, "illuminant_spd") * quadrature_weights(grid)
    responses = spd @ sens
    if not (responses > 0).all():
        raise ValueError(
            f"sensitivities times illuminant_spd must give each channel a response > 0, "
            f"got {responses.tolist()}"
        )
    aces = colour.RGB_COLOURSPACES["ACES2065-1"]
    path = os.path.join(colour.characterisation.aces_it.ROOT_RESOURCES_RAWTOACES, "190_Patches.csv")
    sds = colour.io.read_sds_from_csv_file(path).values()
    refl = np.stack([_resample(sd.wavelengths, sd.values, grid, "the training set") for sd in sds])
    # The balanced perfect white reads 1: the scale M's rows (summing to 1)
    # refer to.
    spd = spd / responses.max()
    white_balance = responses.max() / responses
    # Plain products, not the checked kernel: a few training samples are
    # slightly negative (measurement noise), and colour-science keeps them.
    rgb = (refl * spd) @ sens * white_balance
    cmfs = cie_cmfs(grid)
    white = spd @ cmfs
    xyz = (refl * spd) @ cmfs
    adapt = colour.adaptation.matrix_chromatic_adaptation_VonKries(
        white / white[1], colour.xy_to_XYZ(aces.whitepoint), "CAT02"
    )
    lab = colour.XYZ_to_Lab(xyz / white[1] @ adapt.T, aces.whitepoint)

    def matrix(params: Float64Array) -> Float64Array:
        m = np.zeros((3, 3))
        m[:, :2] = params.reshape(3, 2)
        m[:, 2] = 1.0 - m[:, :2].sum(axis=1)
        return m

    def cost(params: Float64Array) -> float:
        fitted = rgb @ (aces.matrix_RGB_to_XYZ @ matrix(params)).T
        return float(np.linalg.norm(colour.XYZ_to_Lab(fitted, aces.whitepoint) - lab))

    start = np.array([1.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    best = minimize(cost, start, method="BFGS", jac="2-point").x
    return matrix(best), white_balance


def _neutral(fit: ColorFit, white_xyz: Any) -> tuple[Float64Array, Float64Array]:
    """The checked white and its camera RGB through the inverse of
    ``fit.matrix``: > 0 in every channel, as a DNG neutral must be."""
    white = _white(white_xyz)
    neutral = np.linalg.inv(fit.matrix) @ white
    if not (neutral > 0).all():
        raise ValueError(
            f"the fitted matrix takes the white {white.tolist()} to camera RGB "
            f"{neutral.tolist()}, not > 0 in every channel: no DNG neutral"
        )
    return white, neutral


def dng_color_tags(fit: ColorFit, white_xyz: Any) -> tuple[Float64Array, Float64Array]:
    """DNG ``ColorMatrix1`` (XYZ -> camera RGB) and ``AsShotNeutral`` (the
    camera RGB of ``white_xyz``) of a fitted matrix.

    ``ColorMatrix1`` is scaled as the DNG specification asks: the white maps
    to camera RGB whose largest component is 1, which is ``AsShotNeutral``.

    Raises
    ------
    ValueError
        A white that is not 3 finite values >= 0 with Y > 0, a singular
        matrix, or one that takes the white to a camera RGB not > 0.
    """
    _, neutral = _neutral(fit, white_xyz)
    cam_from_xyz = np.linalg.inv(fit.matrix)
    # Division, not a multiplication by the reciprocal: x / x is exactly 1 in
    # IEEE arithmetic, x * (1 / x) is not always.
    largest = neutral.max()
    return cam_from_xyz / largest, neutral / largest


#: The DNG profile connection space's white, D50 (xy 0.3457, 0.3585) with Y = 1.
D50_XYZ = np.array([0.3457 / 0.3585, 1.0, (1.0 - 0.3457 - 0.3585) / 0.3585])


def dng_forward_matrix(fit: ColorFit, white_xyz: Any) -> Float64Array:
    """DNG ``ForwardMatrix1`` of a fitted matrix: white-balanced camera RGB
    to XYZ (D50).

    White balance divides camera RGB by the white's camera RGB, so
    ``fit.matrix @ diag(neutral)`` takes the balanced white (1, 1, 1) to
    ``white_xyz``; Bradford's chromatic adaptation (colour-science) then moves
    that white to D50, and the result is scaled to map (1, 1, 1) to exactly
    :data:`D50_XYZ`, as the DNG specification asks.

    Raises
    ------
    ValueError
        As :func:`dng_color_tags`.
    """
    colour = _colour()
    white, neutral = _neutral(fit, white_xyz)
    adapt = colour.adaptation.matrix_chromatic_adaptation_VonKries(
        white / white[1], D50_XYZ, transform="Bradford"
    )
    forward = adapt @ fit.matrix @ np.diag(neutral / white[1])
    return forward * (D50_XYZ / forward.sum(axis=1))[:, None]


def colorchecker_scene(
    wl: Any, illuminant_radiance: Any, *, patch: int = 32, gap: int = 8
) -> tuple[Float32Array, list[tuple[slice, slice]]]:
    """A ColorChecker as a spectral radiance image (H, W, L) float32.

    Six columns by four rows of ``patch``-pixel squares, ``gap`` pixels apart
    on a black surround (reflectance 0.03), lit by ``illuminant_radiance``
    (the radiance of a perfect white, shape (L,)).

    Returns
    -------
    radiance : ndarray, float32, shape (4 patch + 5 gap, 6 patch + 7 gap, L)
    boxes : list of (slice, slice)
        Each patch's rows and columns, in the chart's order.
    """
    grid = check_wavelengths(wl)
    spd = _spectra(illuminant_radiance, grid, "illuminant_radiance")
    _check_int(patch, "patch", 1)
    _check_int(gap, "gap", 0)
    _, refl = colorchecker(grid)
    h, w = 4 * patch + 5 * gap, 6 * patch + 7 * gap
    image = np.empty((h, w, len(grid)), np.float32)
    image[:] = (0.03 * spd).astype(np.float32)
    boxes = []
    for i, r in enumerate(refl):
        y, x = gap + (i // 6) * (patch + gap), gap + (i % 6) * (patch + gap)
        box = (slice(y, y + patch), slice(x, x + patch))
        image[box] = (r * spd).astype(np.float32)
        boxes.append(box)
    return image, boxes


def write_dng(
    path: Any,
    raw: Any,
    camera: SpectralCamera,
    fit: ColorFit,
    *,
    white_xyz: Any = None,
) -> None:
    """Write a raw frame of ``camera`` as a DNG that rawpy / LibRaw and
    :func:`imgform_rs.develop` develop with the right colours.

    ``ColorMatrix1`` and ``AsShotNeutral`` come from :func:`dng_color_tags`,
    ``ForwardMatrix1`` from :func:`dng_forward_matrix` (the scene white
    defaults to D65's XYZ, the calibration illuminant the writer declares);
    black and white levels and the CFA pattern from the camera.
    """
    from .dng import write_dng as _write

    if white_xyz is None:
        wl = camera.wavelengths
        white_xyz = xyz_weights(wl, illuminant("D65", wl), camera.rule).sum(axis=0)
    color_matrix, neutral = dng_color_tags(fit, white_xyz)
    _write(
        path,
        raw,
        camera.pattern,
        white_level=camera.sensor.white_level,
        black_level=camera.sensor.black_level,
        color_matrix=color_matrix,
        as_shot_neutral=neutral,
        forward_matrix=dng_forward_matrix(fit, white_xyz),
        model="imgform-rs spectral camera",
    )
