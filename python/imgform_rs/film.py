"""Colour film, spectrally: expose, develop, print and scan (lecture sections 4 and 5).

A stock has ``n`` emulsion layers (red, green, blue sensitive for colour film;
one for black-and-white), each with a spectral log-sensitivity ``log10 s_i(λ)``,
a characteristic curve ``D_i = f_i(log10 H_i)`` and a dye of spectral density
``e_i(λ)`` per unit of analytical density. The model, step by step:

1. **Exposure** (:func:`expose`): ``H_i = 2^EV ∫ L(λ) s_i(λ) dλ / ∫ W(λ) s_i(λ) dλ``,
   the layer's exposure relative to the stock's reference white ``W``: a
   black body at the stock's balance temperature with CIE 1931 tristimulus
   ``Y = ∫ W(λ) ȳ(λ) dλ = 1`` (λ in nm, trapezoidal on the stock's grid). A
   spectral image in W m⁻² sr⁻¹ nm⁻¹ has ``Y`` = luminance / 683 cd/m², so
   a white of 683 cd/m² exposes ``H ≈ 1``. An RGB image is taken as linear
   sRGB reflectances (Mallett and Yuksel 2019 basis) lit by ``W``: the basis
   folds into an ``n x 3`` matrix, so a neutral ``(g, g, g)`` gives
   ``H_i = g`` in every layer exactly.
2. **Development** (:func:`develop`): ``D_i = f_i(log10 H_i)``; DIR couplers
   lower a receiver's log exposure by ``Σ_j A_ij G_σ * (D_j - D_j,min)`` (donor
   densities blurred by the inhibitors' diffusion), with the curves
   pre-corrected so that a neutral wedge still develops the stated curves
   (Hunt, *The Reproduction of Colour*, 6th ed., 14.8; the Rust docs of
   ``film::develop`` give the equations). Halation (light scattered back
   from the base, red layer first, energy-conserving) acts on the exposure
   before; Poisson grain (RMS at density 1 a stock parameter) on the
   densities after.
3. **Dyes** (:func:`transmittance`): Beer-Lambert,
   ``D(λ) = b(λ) + Σ_i D_i e_i(λ) + Σ_i (D_i,max - D_i) m_i(λ)``, ``T = 10^-D(λ)``,
   with ``m_i`` a negative's coloured masking coupler, which is used up as
   dye ``i`` forms (Hunt 14.7): when ``m_i`` equals the dye's unwanted
   absorption, the unwanted absorption is the same at every density and the
   print filtration removes it.
4. **Printing** (:func:`print`): the paper's layer exposures are
   ``t ∫ P(λ) F(λ) T(λ) s_k(λ) dλ`` for an enlarger lamp ``P`` (a 3200 K
   black body) through dichroic filters ``F = 10^-(y Y(λ) + m M(λ) + c C(λ))``
   chosen by :func:`balance_print` so that a mid grey on the negative prints as
   a neutral of the paper's mid density; then the paper develops like a film.
5. **Viewing** (:func:`scan`): ``XYZ = ∫ V(λ) T(λ) x̄ȳz̄(λ) dλ / ∫ V ȳ dλ``
   through the CIE 1931 observer under a viewing light ``V`` (D65): a print's
   reflection density is used as its density, a slide is seen by
   transmission. :func:`to_srgb` encodes the result.

Per-pixel work (the exposure integral, curves and couplers, Beer-Lambert
integrals) runs in Rust, with no random numbers: every output is identical
for any thread count.

Stocks are data (:func:`load_stock`, :func:`save_stock`): a JSON format
documented in :data:`STOCK_FORMAT`, with provenance. The shipped stocks are
generic and parametric, written by :func:`parametric_stock` from the equations
in its docstring; they are not digitised datasheets of any product.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from . import _native
from . import spectral as sp
from ._arrays import Float64Array, as_seed, flag, real, require_finite

Float32Array = npt.NDArray[np.float32]
Kind = Literal["negative", "reversal", "paper"]

#: The ``format`` value of a stock file this version reads and writes.
STOCK_FORMAT = "imgform-film-stock/1"
#: Log-exposure step (log10 units) of the curves handed to the kernels.
CURVE_STEP = 0.005
#: Enlarger lamp colour temperature, K (a tungsten-halogen lamp).
ENLARGER_KELVIN = 3200.0
#: The analytical density each paper layer reaches for a mid grey: a
#: reflection density near that of an 18 % grey card.
PRINT_GREY_DENSITY = 0.7
#: The reflectance taken as mid grey when balancing a print.
MID_GREY = 0.18
#: Width of the frame an image is taken to fill, mm (135 film), which sets
#: the pixel size for the couplers' diffusion length.
FRAME_WIDTH_MM = 36.0
#: The largest exposure change accepted, in stops either way: 2^100 (1e30)
#: carries any scene past both ends of every curve (a stock spans some 20
#: stops) and keeps float32 exposures finite for scene values up to 1e8.
MAX_EV = 100.0

_KINDS = ("negative", "reversal", "paper")
_STOCKS_DIR = "film_stocks"


@dataclass(frozen=True)
class Layer:
    """One emulsion layer: its sensitivity, curve and dye.

    Attributes
    ----------
    name : str
        "red", "green", "blue" or "pan" by convention.
    log_sensitivity : ndarray (L,)
        ``log10`` of the spectral sensitivity (any scale: exposures are
        normalised to the stock's reference white).
    log_exposure, density : ndarray (K,)
        The characteristic curve: ``log_exposure`` strictly increasing,
        ``density`` >= 0 and strictly monotone (rising for a negative or
        paper, falling for a reversal film).
    dye_density : ndarray (L,)
        The dye's spectral density per unit of analytical density, >= 0.
    mask_density : ndarray (L,)
        The masking coupler's spectral density per unit of unformed coupler
        (zeros for no mask), >= 0.
    """

    name: str
    log_sensitivity: Float64Array
    log_exposure: Float64Array
    density: Float64Array
    dye_density: Float64Array
    mask_density: Float64Array

    def curve(self, log_exposure: Any) -> Float64Array:
        """The stated curve at ``log_exposure``, held flat beyond its ends."""
        return np.interp(log_exposure, self.log_exposure, self.density)


@dataclass(frozen=True)
class Stock:
    """A film or paper stock; see :data:`STOCK_FORMAT` for the file format.

    Attributes
    ----------
    name, kind, description : str
        ``kind`` is "negative", "reversal" or "paper".
    wavelengths : ndarray (L,)
        The grid (nm) of every spectral quantity.
    layers : tuple of Layer
    base_density : ndarray (L,)
        Support plus fog, >= 0.
    balance_kelvin : float
        Colour temperature of the white the stock is balanced for.
    coupler_matrix : ndarray (n, n)
        DIR couplers, receiver row ``i``, donor column ``j``, >= 0.
    coupler_diffusion_um : float
        The inhibitors' diffusion length (Gaussian sigma), micrometres.
    halation : ndarray (n,)
        Fraction of each layer's exposure scattered back from the base, in
        [0, 1] (largest for the red layer, nearest the base).
    halation_um : float
        The spread (Gaussian sigma) of that light, micrometres.
    rms_granularity : ndarray (n,)
        Each layer's RMS granularity at density 1 through a 48 µm aperture
        (Kodak's "diffuse RMS granularity" / 1000), >= 0.
    provenance : dict
        Where the data come from, under which licence, how derived.
    """

    name: str
    kind: Kind
    description: str
    wavelengths: Float64Array
    layers: tuple[Layer, ...]
    base_density: Float64Array
    balance_kelvin: float
    coupler_matrix: Float64Array
    coupler_diffusion_um: float
    halation: Float64Array
    halation_um: float
    rms_granularity: Float64Array
    provenance: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _validate(self)

    @property
    def dye_max(self) -> Float64Array:
        """Each layer's largest density: its dye at full strength."""
        return np.array([layer.density.max() for layer in self.layers])

    def without_couplers(self) -> Stock:
        """The same stock with its DIR couplers removed."""
        return replace(self, coupler_matrix=np.zeros_like(self.coupler_matrix))


# --- validation ----------------------------------------------------------------------------


def _fail(stock: str, what: str) -> None:
    raise ValueError(f"stock {stock!r}: {what}")


def _check_spectrum(stock: str, name: str, values: Float64Array, n: int, nonneg: bool) -> None:
    if values.shape != (n,):
        _fail(stock, f"{name} must have {n} samples, one per wavelength, got shape {values.shape}")
    if not np.isfinite(values).all():
        _fail(stock, f"{name} must be finite, sample {int(np.argmin(np.isfinite(values)))} is not")
    if nonneg and (values < 0).any():
        i = int(np.argmax(values < 0))
        _fail(stock, f"{name} must be >= 0, sample {i} ({values[i]:g} at index {i}) is negative")


def _check_curve(stock: Stock, layer: Layer) -> None:
    where = f"layer {layer.name!r}"
    x, d = layer.log_exposure, layer.density
    if x.ndim != 1 or x.shape != d.shape or len(x) < 2:
        _fail(
            stock.name,
            f"{where}: log_exposure and density must be two 1-D lists of one "
            f"length >= 2, got shapes {x.shape} and {d.shape}",
        )
    if not (np.isfinite(x).all() and np.isfinite(d).all()):
        _fail(stock.name, f"{where}: the curve must be finite")
    if (np.diff(x) <= 0).any():
        i = int(np.argmax(np.diff(x) <= 0))
        _fail(
            stock.name,
            f"{where}: log_exposure must increase strictly, sample {i + 1} "
            f"({x[i + 1]:g}) follows {x[i]:g}",
        )
    if (d < 0).any():
        i = int(np.argmax(d < 0))
        _fail(stock.name, f"{where}: densities must be >= 0, sample {i} is {d[i]:g}")
    sign = -1.0 if stock.kind == "reversal" else 1.0
    step = sign * np.diff(d)
    if (step <= 0).any():
        i = int(np.argmax(step <= 0))
        trend = "fall" if sign < 0 else "rise"
        _fail(
            stock.name,
            f"{where}: a {stock.kind} curve must {trend} strictly with log "
            f"exposure; density goes from {d[i]:g} to {d[i + 1]:g} between samples {i} "
            f"and {i + 1}",
        )


def _validate(stock: Stock) -> None:
    name = stock.name
    if stock.kind not in _KINDS:
        _fail(name, f"kind must be one of {_KINDS}, got {stock.kind!r}")
    try:
        sp.check_wavelengths(stock.wavelengths)
    except ValueError as exc:
        _fail(name, f"wavelengths: {exc}")
    n_wl, n = len(stock.wavelengths), len(stock.layers)
    if n == 0:
        _fail(name, "a stock needs at least one layer")
    _check_spectrum(name, "base_density", stock.base_density, n_wl, nonneg=True)
    for layer in stock.layers:
        for attr, nonneg in (
            ("log_sensitivity", False),
            ("dye_density", True),
            ("mask_density", True),
        ):
            _check_spectrum(
                name, f"layer {layer.name!r} {attr}", getattr(layer, attr), n_wl, nonneg
            )
        _check_curve(stock, layer)
    if stock.coupler_matrix.shape != (n, n):
        _fail(name, f"coupler_matrix must be {n} x {n}, got shape {stock.coupler_matrix.shape}")
    if not (np.isfinite(stock.coupler_matrix).all() and (stock.coupler_matrix >= 0).all()):
        _fail(name, "coupler_matrix entries must be finite and >= 0")
    if not (np.isfinite(stock.coupler_diffusion_um) and stock.coupler_diffusion_um >= 0):
        _fail(name, f"coupler_diffusion_um must be >= 0, got {stock.coupler_diffusion_um}")
    for attr, low, high in (("halation", 0.0, 1.0), ("rms_granularity", 0.0, np.inf)):
        v = getattr(stock, attr)
        if v.shape != (n,) or not ((v >= low) & (v <= high)).all():
            _fail(
                name,
                f"{attr} must hold {n} values in [{low:g}, {high:g}], one per layer, "
                f"got {v.tolist()}",
            )
    if not (np.isfinite(stock.halation_um) and stock.halation_um > 0):
        _fail(name, f"halation_um must be > 0, got {stock.halation_um}")
    if not (np.isfinite(stock.balance_kelvin) and stock.balance_kelvin > 0):
        _fail(name, f"balance_kelvin must be > 0, got {stock.balance_kelvin}")


# --- files ---------------------------------------------------------------------------------


def _array(obj: dict[str, Any], key: str, stock: str) -> Float64Array:
    if key not in obj:
        _fail(stock, f"missing field {key!r}")
    try:
        return np.asarray(obj[key], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"stock {stock!r}: {key} must be a list of numbers ({exc})") from None


def _section(obj: dict[str, Any], key: str, stock: str) -> dict[str, Any]:
    """The JSON object under ``key`` (empty when absent)."""
    value = obj.get(key, {})
    if not isinstance(value, dict):
        _fail(stock, f"{key} must be a JSON object {{...}}, got a {type(value).__name__}")
    return value


def _number(obj: dict[str, Any], key: str, default: float, stock: str) -> float:
    """The number under ``key`` (``default`` when absent)."""
    value = obj.get(key, default)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"stock {stock!r}: {key} must be a number, got {value!r}") from None


def stock_from_dict(data: dict[str, Any]) -> Stock:
    """A :class:`Stock` from the parsed JSON of a stock file, validated.

    Raises
    ------
    ValueError
        A wrong format tag, a missing field, a field of the wrong JSON type
        (``couplers``, ``halation``, ``grain``, ``provenance`` and a layer's
        ``curve`` are objects; ``balance_kelvin``, ``diffusion_um`` and
        ``spread_um`` numbers), wrong grids, non-monotone curves, negative
        densities: the message names the stock, key, layer and sample.
    """
    if not isinstance(data, dict):
        raise ValueError(f"a stock is a JSON object {{...}}, got a {type(data).__name__}")
    name = str(data.get("name", "<unnamed>"))
    if data.get("format") != STOCK_FORMAT:
        _fail(name, f"format must be {STOCK_FORMAT!r}, got {data.get('format')!r}")
    if not isinstance(data.get("layers"), list) or not all(
        isinstance(layer, dict) for layer in data["layers"]
    ):
        _fail(name, "layers must be a list of layer objects")
    couplers = _section(data, "couplers", name)
    halation = _section(data, "halation", name)
    grain = _section(data, "grain", name)
    layers = tuple(
        Layer(
            name=str(layer.get("name", f"layer {i}")),
            log_sensitivity=_array(layer, "log_sensitivity", name),
            log_exposure=_array(_section(layer, "curve", name), "log_exposure", name),
            density=_array(_section(layer, "curve", name), "density", name),
            dye_density=_array(layer, "dye_density", name),
            mask_density=np.asarray(
                layer.get("mask_density", [0.0] * len(data.get("wavelengths", []))), np.float64
            ),
        )
        for i, layer in enumerate(data["layers"])
    )
    n = len(layers)
    return Stock(
        name=name,
        kind=data.get("kind", ""),
        description=str(data.get("description", "")),
        wavelengths=_array(data, "wavelengths", name),
        layers=layers,
        base_density=_array(data, "base_density", name),
        balance_kelvin=_number(data, "balance_kelvin", 5500.0, name),
        coupler_matrix=np.asarray(couplers.get("matrix", np.zeros((n, n))), np.float64),
        coupler_diffusion_um=_number(couplers, "diffusion_um", 0.0, name),
        halation=np.asarray(halation.get("strength", np.zeros(n)), np.float64),
        halation_um=_number(halation, "spread_um", 50.0, name),
        rms_granularity=np.asarray(grain.get("rms_granularity", np.zeros(n)), np.float64),
        provenance={str(k): str(v) for k, v in _section(data, "provenance", name).items()},
    )


def stock_to_dict(stock: Stock) -> dict[str, Any]:
    """The JSON-ready dictionary of a stock (the inverse of :func:`stock_from_dict`)."""

    def floats(a: Float64Array) -> list[float]:
        return [round(float(v), 6) for v in np.ravel(a)]

    return {
        "format": STOCK_FORMAT,
        "name": stock.name,
        "kind": stock.kind,
        "description": stock.description,
        "provenance": stock.provenance,
        "balance_kelvin": stock.balance_kelvin,
        "wavelengths": floats(stock.wavelengths),
        "base_density": floats(stock.base_density),
        "couplers": {
            "matrix": [floats(row) for row in stock.coupler_matrix],
            "diffusion_um": stock.coupler_diffusion_um,
        },
        "halation": {"strength": floats(stock.halation), "spread_um": stock.halation_um},
        "grain": {"rms_granularity": floats(stock.rms_granularity), "aperture_um": 48.0},
        "layers": [
            {
                "name": layer.name,
                "log_sensitivity": floats(layer.log_sensitivity),
                "curve": {
                    "log_exposure": floats(layer.log_exposure),
                    "density": floats(layer.density),
                },
                "dye_density": floats(layer.dye_density),
                "mask_density": floats(layer.mask_density),
            }
            for layer in stock.layers
        ],
    }


def shipped_stocks() -> tuple[str, ...]:
    """Names of the stocks shipped with the package (all generic, parametric)."""
    folder = resources.files(__package__).joinpath(_STOCKS_DIR)
    return tuple(sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".json")))


def load_stock(stock: str | Path | Stock) -> Stock:
    """A stock by shipped name (see :func:`shipped_stocks`) or from a JSON file.

    A :class:`Stock` is returned as it is.

    Raises
    ------
    ValueError
        An unknown name, unparsable JSON or an invalid stock (see
        :func:`stock_from_dict`).

    Examples
    --------
    >>> neg = load_stock("generic-negative")
    >>> neg.kind, [layer.name for layer in neg.layers]
    ('negative', ['red', 'green', 'blue'])
    """
    if isinstance(stock, Stock):
        return stock
    path = Path(stock)
    if path.suffix != ".json":
        if str(stock) not in shipped_stocks():
            raise ValueError(
                f"unknown stock {stock!r}: pass a .json file or one of {shipped_stocks()}"
            )
        text = resources.files(__package__).joinpath(_STOCKS_DIR, f"{stock}.json").read_text()
        origin = f"shipped stock {stock}"
    else:
        text, origin = path.read_text(), str(path)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{origin} is not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{origin} must hold a JSON object, got {type(data).__name__}")
    return stock_from_dict(data)


def save_stock(stock: Stock, path: str | Path) -> None:
    """Writes ``stock`` as a JSON stock file that :func:`load_stock` reads back."""
    Path(path).write_text(json.dumps(stock_to_dict(stock), indent=1) + "\n")


# --- parametric stocks ---------------------------------------------------------------------


def gaussian(wl: Any, peak: float, width: float) -> Float64Array:
    """``exp(-(λ - peak)² / (2 width²))``: the band shape of the generic stocks."""
    peak, width = real(peak, "peak"), real(width, "width")
    return np.exp(-0.5 * ((np.asarray(wl, np.float64) - peak) / width) ** 2)


def logistic_curve(
    log_exposure: Any, d_min: float, d_max: float, gamma: float, x0: float
) -> Float64Array:
    """``D = D_min + (D_max - D_min) / (1 + exp(-4 γ (x - x0) / (D_max - D_min)))``.

    A sigmoid from fog ``D_min`` to ``D_max`` whose slope at its midpoint
    ``x0`` is ``γ`` (the straight-line gamma of a datasheet; negative for a
    reversal film, whose curve falls). Derived here: ``dD/dx`` at ``x0`` is
    ``(D_max - D_min) · 4γ / (D_max - D_min) / 4 = γ``.
    """
    x = np.asarray(log_exposure, np.float64)
    d_min, d_max = real(d_min, "d_min"), real(d_max, "d_max")
    gamma, x0 = real(gamma, "gamma"), real(x0, "x0")
    span = d_max - d_min
    return d_min + span / (1.0 + np.exp(-4.0 * gamma * (x - x0) / span))


#: Parameters of the generic stocks (see :func:`parametric_stock`): per layer
#: (name, sensitivity peak and width nm, dye peak and width nm, the dye's
#: unwanted secondary absorption (peak nm, width nm, strength), fog, D_max,
#: gamma, curve midpoint). Band positions are typical of colour materials
#: (Hunt, *The Reproduction of Colour*, 6th ed., figs. 14.4 and 15.2); the
#: numbers are ours, not any product's.
_GENERIC: dict[str, dict[str, Any]] = {
    "generic-negative": {
        "kind": "negative",
        "description": "A generic daylight colour negative film (ISO 100 class): gamma 0.6, "
        "coloured masking couplers, DIR couplers.",
        "balance_kelvin": 5500.0,
        "log_exposure": (-4.0, 2.0),
        "base": 0.08,
        "layers": [
            ("red", 645, 22, 665, 45, (540, 45, 0.12), 0.18, 2.58, 0.62, -0.7),
            ("green", 548, 24, 548, 32, (440, 30, 0.16), 0.22, 2.62, 0.62, -0.7),
            ("blue", 450, 22, 445, 38, None, 0.26, 2.66, 0.62, -0.7),
        ],
        "mask": True,
        "couplers": ([[0.06, 0.08, 0.04], [0.08, 0.06, 0.06], [0.03, 0.08, 0.06]], 12.0),
        "halation": ([0.03, 0.008, 0.002], 60.0),
        "grain": [0.005, 0.004, 0.006],
    },
    "generic-paper": {
        "kind": "paper",
        "description": "A generic colour negative printing paper: gamma 2.2, red sensitivity "
        "far in the red where a negative's cyan dye absorbs most.",
        "balance_kelvin": ENLARGER_KELVIN,
        "log_exposure": (-3.0, 1.0),
        "base": 0.03,
        "layers": [
            ("red", 665, 14, 655, 42, (545, 45, 0.08), 0.04, 2.3, 2.2, -1.0),
            ("green", 545, 14, 540, 30, (440, 30, 0.10), 0.04, 2.3, 2.2, -1.0),
            ("blue", 445, 14, 445, 28, None, 0.04, 2.3, 2.2, -1.0),
        ],
        "mask": False,
        "couplers": (np.zeros((3, 3)).tolist(), 0.0),
        "halation": ([0.0, 0.0, 0.0], 50.0),
        "grain": [0.0, 0.0, 0.0],
    },
    "generic-reversal": {
        "kind": "reversal",
        "description": "A generic daylight colour reversal (slide) film: the curve falls with "
        "gamma -1.7 from D_max 3.3; DIR couplers for colour saturation.",
        "balance_kelvin": 5500.0,
        "log_exposure": (-3.5, 1.5),
        "base": 0.05,
        "layers": [
            ("red", 640, 22, 660, 42, (545, 45, 0.10), 0.12, 3.2, -1.7, -0.9),
            ("green", 548, 24, 545, 30, (440, 30, 0.12), 0.12, 3.3, -1.7, -0.9),
            ("blue", 450, 22, 445, 28, None, 0.12, 3.4, -1.7, -0.9),
        ],
        "mask": False,
        "couplers": ([[0.0, 0.05, 0.03], [0.05, 0.0, 0.05], [0.02, 0.05, 0.0]], 10.0),
        "halation": ([0.02, 0.005, 0.001], 60.0),
        "grain": [0.009, 0.008, 0.01],
    },
    "generic-bw-pan": {
        "kind": "negative",
        "description": "A generic panchromatic black-and-white negative film: one silver layer "
        "sensitive 400-660 nm, gamma 0.65.",
        "balance_kelvin": 5500.0,
        "log_exposure": (-4.0, 2.0),
        "base": 0.1,
        "layers": [("pan", None, None, None, None, None, 0.2, 2.6, 0.65, -0.7)],
        "mask": False,
        "couplers": ([[0.0]], 0.0),
        "halation": ([0.01], 60.0),
        "grain": [0.01],
    },
    "generic-bw-paper": {
        "kind": "paper",
        "description": "A generic graded black-and-white printing paper (about grade 2): one "
        "blue-sensitive silver layer, gamma 2.0.",
        "balance_kelvin": ENLARGER_KELVIN,
        "log_exposure": (-3.0, 1.0),
        "base": 0.03,
        "layers": [("blue", 430, 35, None, None, None, 0.04, 2.1, 2.0, -1.0)],
        "mask": False,
        "couplers": ([[0.0]], 0.0),
        "halation": ([0.0], 50.0),
        "grain": [0.0],
    },
}

#: The provenance every generic stock carries.
_GENERIC_PROVENANCE = {
    "source": "imgform-rs, film.parametric_stock",
    "license": "MIT (the project's licence); generated, no measured data",
    "derivation": "Gaussian sensitivities and dyes, logistic characteristic curves "
    "(film.logistic_curve), masks equal to the dyes' secondary absorptions; band "
    "positions typical of colour materials after Hunt, The Reproduction of Colour, 6th ed., "
    "ch. 14-15",
    "datasheets": "none used: no third-party digitised curves are shipped",
}


def _pan_sensitivity(wl: Float64Array) -> Float64Array:
    """A flat band 400-660 nm with logistic edges 12 nm wide."""
    return 1.0 / ((1.0 + np.exp((400.0 - wl) / 12.0)) * (1.0 + np.exp((wl - 660.0) / 12.0)))


def _neutral_dyes(wl: Float64Array, layers: list[Layer]) -> list[Layer]:
    """The layers with the red and blue dyes scaled so that equal analytical
    densities of 1 look neutral under D65 (a* = b* = 0): the equivalent
    neutral density calibration of a viewed material's dyes (Hunt 14.9).
    Newton's method on (a*, b*) with a finite-difference Jacobian."""
    light = sp.illuminant("D65", wl) * sp.quadrature_weights(wl)
    cmfs = sp.cie_cmfs(wl)
    white = light @ cmfs

    def ab(k: Float64Array) -> Float64Array:
        dye = k[0] * layers[0].dye_density + layers[1].dye_density + k[1] * layers[2].dye_density
        lab = sp.xyz_to_lab((10.0**-dye * light) @ cmfs, white / white[1])
        return np.asarray(lab)[1:]

    k = np.ones(2)
    for _ in range(20):
        r = ab(k)
        if np.abs(r).max() < 1e-6:
            break
        jac = np.stack([(ab(k + 1e-6 * e) - r) / 1e-6 for e in np.eye(2)], axis=1)
        k = k - np.linalg.solve(jac, r)
    scale = (k[0], 1.0, k[1])
    return [
        replace(lay, dye_density=f * lay.dye_density) for lay, f in zip(layers, scale, strict=True)
    ]


def parametric_stock(name: str, wl: Any = None) -> Stock:
    """A generic stock derived from equations: "generic-negative", "generic-paper",
    "generic-reversal", "generic-bw-pan" or "generic-bw-paper".

    Every layer ``i`` has:

    - sensitivity ``s_i = exp(-(λ - μ_i)² / 2σ_i²)`` (stored as ``log10``,
      floored at -6), or for a panchromatic layer a 400-660 nm band with
      logistic edges;
    - a dye ``e_i = g(λ; peak_i, width_i) + a_i g(λ; λ'_i, w'_i)``: a main
      Gaussian band of peak density 1 plus the unwanted secondary
      absorption real cyan and magenta dyes have (their blue and green
      absorption); silver is spectrally flat, ``e = 1``;
    - for the negative, a masking coupler ``m_i = a_i g(λ; λ'_i, w'_i)``,
      exactly the dye's secondary absorption (Hunt 14.7), so the unwanted
      absorption is the same at every exposure;
    - the curve :func:`logistic_curve` sampled every 0.01 log10 units;
    - for a paper or reversal film, which are looked at, the red and blue
      dyes scaled so that equal densities of 1 are neutral under D65
      (equivalent neutral density, Hunt 14.9).

    Raises
    ------
    ValueError
        An unknown name.
    """
    if name not in _GENERIC:
        raise ValueError(f"unknown generic stock {name!r}; accepted: {tuple(_GENERIC)}")
    p = _GENERIC[name]
    grid = sp.wavelengths(380.0, 780.0, 10.0) if wl is None else sp.check_wavelengths(wl)
    lo, hi = p["log_exposure"]
    x = np.round(np.arange(lo, hi + 1e-9, 0.01), 6)
    layers = []
    for lname, s_pk, s_w, d_pk, d_w, second, fog, dmax, gamma, x0 in p["layers"]:
        sens = _pan_sensitivity(grid) if s_pk is None else gaussian(grid, s_pk, s_w)
        main = np.ones_like(grid) if d_pk is None else gaussian(grid, d_pk, d_w)
        extra = np.zeros_like(grid) if second is None else second[2] * gaussian(grid, *second[:2])
        layers.append(
            Layer(
                name=lname,
                log_sensitivity=np.maximum(np.log10(np.maximum(sens, 1e-300)), -6.0),
                log_exposure=x,
                density=logistic_curve(x, fog, dmax, gamma, x0),
                dye_density=main + extra,
                mask_density=extra if p["mask"] else np.zeros_like(grid),
            )
        )
    if p["kind"] != "negative" and len(layers) == 3:
        layers = _neutral_dyes(grid, layers)
    matrix, diffusion = p["couplers"]
    strength, spread = p["halation"]
    return Stock(
        name=name,
        kind=p["kind"],
        description=p["description"],
        wavelengths=grid,
        layers=tuple(layers),
        base_density=np.full_like(grid, p["base"]),
        balance_kelvin=p["balance_kelvin"],
        coupler_matrix=np.asarray(matrix, np.float64),
        coupler_diffusion_um=diffusion,
        halation=np.asarray(strength, np.float64),
        halation_um=spread,
        rms_granularity=np.asarray(p["grain"], np.float64),
        provenance=dict(_GENERIC_PROVENANCE),
    )


# --- the kernels' arguments ----------------------------------------------------------------


def _kernel_curves(stock: Stock) -> list[tuple[float, float, list[float]]]:
    """Each layer's curve resampled every :data:`CURVE_STEP` from its first
    stated sample (so stated samples on that grid are kept exactly)."""
    out = []
    for layer in stock.layers:
        x0, x1 = float(layer.log_exposure[0]), float(layer.log_exposure[-1])
        x = x0 + CURVE_STEP * np.arange(round((x1 - x0) / CURVE_STEP) + 1)
        out.append((x0, CURVE_STEP, layer.curve(np.minimum(x, x1)).tolist()))
    return out


def _white(stock: Stock) -> Float64Array:
    """The reference white: a black body at the stock's balance temperature,
    scaled to CIE Y = ∫ W ȳ dλ = 1 (trapezoidal quadrature, λ in nm): in
    W m⁻² sr⁻¹ nm⁻¹, a luminance of 683 cd/m²."""
    wl = stock.wavelengths
    return sp.luminance_scale(sp.blackbody(wl, stock.balance_kelvin), wl, 683.0)


def _sensitivity(stock: Stock) -> Float64Array:
    """Layer sensitivities times quadrature weights, (n, L)."""
    s = 10.0 ** np.array([layer.log_sensitivity for layer in stock.layers])
    return s * sp.quadrature_weights(stock.wavelengths)


def _gain(exposure_ev: float) -> float:
    """``2^EV`` of an exposure change of at most ``MAX_EV`` stops either way."""
    ev = real(exposure_ev, "exposure_ev")
    if not (np.isfinite(ev) and abs(ev) <= MAX_EV):
        raise ValueError(
            f"exposure_ev must be a finite number of stops in [-{MAX_EV:g}, {MAX_EV:g}], "
            f"got {exposure_ev!r}"
        )
    return 2.0**ev


def spectral_response(stock: Stock, exposure_ev: float = 0.0) -> Float64Array:
    """``(n, L)`` weights turning a spectral radiance on the stock's grid into
    layer exposures: ``2^EV s_i(λ) w(λ) / Σ W s_i w`` (``W`` the reference
    white, ``w`` the quadrature weights)."""
    sens = _sensitivity(stock)
    return _gain(exposure_ev) * sens / (sens @ _white(stock))[:, None]


def exposure_matrix(stock: Stock, exposure_ev: float = 0.0) -> Float64Array:
    """``(n, 3)``: linear sRGB reflectances to layer exposures under the
    reference white, through the Mallett-Yuksel basis ``B``:
    ``M = 2^EV (s w W) B / (s w W) B 1``, so that ``(1, 1, 1)`` exposes
    every layer to exactly ``2^EV``."""
    basis = sp.upsampling_basis(stock.wavelengths)
    m = (_sensitivity(stock) * _white(stock)) @ basis
    return _gain(exposure_ev) * m / m.sum(axis=1, keepdims=True)


def _dyes(stock: Stock) -> tuple[Float64Array, Float64Array]:
    """Beer-Lambert in the kernel's form: the base with every masking coupler
    unformed, and each dye less the mask it replaces (Hunt 14.7)."""
    masks = np.array([layer.mask_density for layer in stock.layers])
    dyes = np.array([layer.dye_density for layer in stock.layers])
    return stock.base_density + stock.dye_max @ masks, dyes - masks


def _pixel_um(frame_width_mm: Any, shape: tuple[int, ...], *spreads_um: float) -> float:
    """The pixel pitch in µm of an image ``shape`` spanning ``frame_width_mm``.

    A frame so small that a stock's spread (halation, coupler diffusion) blurs
    over more pixels than the image has sides, or than the kernels' widest
    blur (``FILM_MAX_BLUR``, 1000 px), is refused: such a blur would only
    make every pixel the frame's mean, and its taps (three widths each side)
    would not fit in memory for the tiniest frames.
    """
    width_mm = real(frame_width_mm, "frame_width_mm")
    if not (np.isfinite(width_mm) and width_mm > 0):
        raise ValueError(f"frame_width_mm must be a finite number > 0, got {frame_width_mm!r}")
    pixel_um = width_mm * 1000.0 / shape[1]
    widest_px = min(max(shape[0], shape[1]), _native.FILM_MAX_BLUR)
    widest = max(spreads_um, default=0.0)
    if widest / pixel_um > widest_px:
        least = widest * shape[1] / widest_px / 1000.0
        raise ValueError(
            f"frame_width_mm={width_mm:g} makes a {shape[1]} px wide image's pixels "
            f"{pixel_um:.3g} µm, and the stock's {widest:g} µm spread wider than "
            f"{widest_px:g} px (the image's side, or the widest blur); frame_width_mm must "
            f"be at least {least:.3g} for this image"
        )
    return pixel_um


def _image(image: Any, name: str, channels: int | None = None) -> Float32Array:
    """A float32 (H, W, C) array, contiguous."""
    arr = np.asarray(image)
    if arr.dtype.kind not in "fiu":
        raise TypeError(f"{name} must be a real-valued array, got dtype {arr.dtype}")
    if arr.ndim != 3 or (channels is not None and arr.shape[2] != channels):
        want = f"(H, W, {channels})" if channels else "(H, W, C)"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float32)


def _transmit(density: Any, stock: Stock, response: Float64Array) -> Float32Array:
    base, dyes = _dyes(stock)
    arr = _image(density, "density", len(stock.layers))
    return _native.film_transmit(
        arr, base.tolist(), dyes.ravel().tolist(), response.ravel().tolist()
    )


# --- the process ---------------------------------------------------------------------------


def expose(image: Any, stock: str | Path | Stock, *, exposure_ev: float = 0.0) -> Float32Array:
    """Layer exposures ``H_i`` (H, W, n) of an RGB or spectral image.

    Parameters
    ----------
    image : ndarray, float, (H, W, 3) or (H, W, L)
        Linear sRGB reflectances (negative components, outside sRGB, are
        clipped to 0), or spectral radiance on the stock's wavelength grid
        relative to the reference white: a black body at the stock's
        balance temperature with CIE Y = ∫ W ȳ dλ = 1 (λ in nm). In
        W m⁻² sr⁻¹ nm⁻¹ (:func:`imgform_rs.spectral.luminance_scale`) that
        white has a luminance of 683 cd/m²: a white of ``L`` cd/m² exposes
        about ``L / 683``, and ``exposure_ev = log2(683 / L)`` brings it to 1.
        Integer images are refused: an 8- or 16-bit picture is usually
        sRGB-encoded, and a linear one may fill any part of its range (12
        bits in uint16), so no one scale makes reflectances of them.
    stock : str, Path or Stock
        A shipped name, a JSON file or a :class:`Stock`.
    exposure_ev : float
        Exposure change in stops, within ±100: ``H`` scales by ``2^EV``.

    Returns
    -------
    ndarray, float32, (H, W, n)
        1.0 is the exposure of a perfect white at EV 0.

    Raises
    ------
    TypeError
        An image that is not of floats, an ``exposure_ev`` that is not a
        real number.
    ValueError
        A shape other than (H, W, 3) or (H, W, L), or an ``exposure_ev``
        outside ±100 or not finite.

    Examples
    --------
    >>> H = expose(np.full((1, 1, 3), 0.18, np.float32), "generic-negative")
    >>> np.round(H.astype(float), 4).tolist()
    [[[0.18, 0.18, 0.18]]]
    """
    st = load_stock(stock)
    dtype = np.asarray(image).dtype
    if dtype.kind in "iu":
        raise TypeError(
            f"image must be float (linear sRGB reflectances or spectral radiance), got dtype "
            f"{dtype}: divide an 8-bit picture by 255 (16-bit: 65535) and undo the sRGB "
            "transfer curve first, as `imgform film` does"
        )
    arr = _image(image, "image")
    n_wl = len(st.wavelengths)
    if arr.shape[2] == n_wl:
        response = spectral_response(st, exposure_ev)
    elif arr.shape[2] == 3:
        response = exposure_matrix(st, exposure_ev)
        arr = np.maximum(arr, 0.0) if (arr < 0).any() else arr
    else:
        raise ValueError(
            f"image must have 3 channels (linear sRGB) or {n_wl}, one per wavelength of the "
            f"stock {st.name!r}, got shape {arr.shape}"
        )
    exposure = _native.spectral_integrate(arr, np.ascontiguousarray(response))
    sp._require_in_float32(exposure)
    return exposure


def pixel_granularity(stock: str | Path | Stock, pixel_um: float) -> Float64Array:
    """Each layer's RMS granularity at density 1 in one square pixel of side
    ``pixel_um``: Selwyn's law (``σ² A`` is constant) from the stock's 48 µm
    circular aperture, ``σ_pixel = σ_48 sqrt(π 24²) / pixel_um``."""
    st = load_stock(stock)
    pitch = real(pixel_um, "pixel_um")
    if not (np.isfinite(pitch) and pitch > 0):
        raise ValueError(f"pixel_um must be a finite number > 0, got {pixel_um!r}")
    return st.rms_granularity * np.sqrt(np.pi * 24.0**2) / pitch


def develop(
    exposure: Any,
    stock: str | Path | Stock,
    *,
    couplers: bool = True,
    halation: bool = True,
    grain: bool = False,
    seed: int = 0,
    frame_width_mm: float = FRAME_WIDTH_MM,
) -> Float32Array:
    """Analytical dye densities (H, W, n) of developed layers.

    Parameters
    ----------
    exposure : ndarray, (H, W, n)
        Layer exposures from :func:`expose` (finite, >= 0).
    stock : str, Path or Stock
    couplers : bool
        Apply the stock's DIR couplers (with curves pre-corrected so that a
        neutral wedge still follows the stated curves); ``False`` gives the
        curves exactly.
    halation : bool
        Spread the stock's halation fraction of each layer's exposure by its
        halation spread, before development (energy-conserving).
    grain : bool
        Replace each density by a Poisson count of grains whose RMS at
        density 1 is :func:`pixel_granularity`; seeded by ``seed`` and the
        pixel, so identical for any thread count.
    seed : int
        The grain's seed, an int in [0, 2**64).
    frame_width_mm : float
        The width of film the image spans, which turns the stock's lengths
        (µm) into pixels.

    Examples
    --------
    >>> D = develop(np.full((1, 1, 3), 0.18, np.float32), "generic-negative")
    >>> np.round(D.astype(float), 2).tolist()
    [[[1.35, 1.39, 1.43]]]
    """
    st = load_stock(stock)
    arr = _image(exposure, "exposure", len(st.layers))
    couplers, halation = flag(couplers, "couplers"), flag(halation, "halation")
    grain = flag(grain, "grain")
    halo_um = st.halation_um if halation and st.halation.any() else 0.0
    pixel_um = _pixel_um(frame_width_mm, arr.shape, halo_um, st.coupler_diffusion_um)
    grain_seed = as_seed(seed, "seed")
    matrix = st.coupler_matrix if couplers else np.zeros_like(st.coupler_matrix)
    spread = (st.halation.tolist(), st.halation_um / pixel_um)
    dens = _native.film_develop(
        arr,
        1.0,
        _kernel_curves(st),
        matrix.ravel().tolist(),
        st.coupler_diffusion_um / pixel_um,
        spread if halation and st.halation.any() else None,
    )
    if grain and st.rms_granularity.any():
        per_grain = pixel_granularity(st, pixel_um) ** 2
        dens = _native.film_grain(dens, per_grain.tolist(), grain_seed)
    return dens


def transmittance(density: Any, stock: str | Path | Stock) -> Float32Array:
    """Spectral transmittance (H, W, L) ``10^-D(λ)`` of developed densities
    (Beer-Lambert with base, dyes and masking couplers)."""
    st = load_stock(stock)
    return _transmit(density, st, np.eye(len(st.wavelengths)))


@dataclass(frozen=True)
class Filtration:
    """An enlarger's dichroic filtration and exposure.

    Attributes
    ----------
    yellow, magenta, cyan : float
        Filter densities (the smallest is 0: a neutral part is exposure).
    exposure : float
        Relative exposure (lamp intensity x time) of the print.
    """

    yellow: float
    magenta: float
    cyan: float
    exposure: float


def dichroic_filters(wl: Any) -> Float64Array:
    """Spectral densities (3, L) of unit yellow, magenta and cyan filters.

    Yellow ``Y = 1 / (1 + exp((λ - 505) / 8))`` blocks blue, cyan
    ``C = 1 / (1 + exp((595 - λ) / 8))`` blocks red, magenta ``M = 1 - Y - C``
    the green between: ``Y + M + C = 1`` at every wavelength, so equal
    densities of all three are a neutral density (an exposure change).
    """
    grid = np.asarray(wl, np.float64)
    y = 1.0 / (1.0 + np.exp((grid - 505.0) / 8.0))
    c = 1.0 / (1.0 + np.exp((595.0 - grid) / 8.0))
    return np.stack([y, 1.0 - y - c, c])


def _print_pair(
    negative: str | Path | Stock, paper: str | Path | Stock, what: str
) -> tuple[Stock, Stock]:
    """The stocks of a print: a negative and a paper, in that order."""
    neg, pap = load_stock(negative), load_stock(paper)
    if neg.kind != "negative" or pap.kind != "paper":
        raise ValueError(
            f"{what} needs a negative and a paper, got a {neg.kind} ({neg.name!r}) and a "
            f"{pap.kind} ({pap.name!r})"
        )
    return neg, pap


def _print_light(negative: Stock, paper: Stock) -> Float64Array:
    """The paper's layer sensitivities times the enlarger lamp on the
    negative's grid, (m, L), for unit exposure and no filtration."""
    if not np.array_equal(negative.wavelengths, paper.wavelengths):
        raise ValueError(
            f"the negative {negative.name!r} and the paper {paper.name!r} must share one "
            "wavelength grid"
        )
    lamp = sp.blackbody(negative.wavelengths, ENLARGER_KELVIN)
    return _sensitivity(paper) * (lamp / lamp.max())


def _grey_transmittance(negative: Stock, grey: float) -> Float64Array:
    """The negative's transmittance where it saw a uniform neutral ``grey``:
    the stated curves, which the couplers' pre-correction keeps."""
    d = np.array([layer.curve(np.log10(grey)) for layer in negative.layers])
    base, dyes = _dyes(negative)
    return 10.0 ** -(base + d @ dyes)


def balance_print(
    negative: str | Path | Stock, paper: str | Path | Stock, *, grey: float = MID_GREY
) -> Filtration:
    """The filtration and exposure that print ``grey`` as a neutral.

    Newton's method on ``log10 E_k(f) = x_k`` for the filter densities ``f``
    (yellow, magenta, cyan), ``E_k`` the paper layer ``k``'s exposure through
    the negative where it saw the neutral ``grey`` (at EV 0), ``x_k`` the log
    exposure at which the paper's curve reaches :data:`PRINT_GREY_DENSITY`.
    The Jacobian is exact: ``∂ log10 E_k / ∂ f_j = -Σ F_j c_k / Σ c_k`` with
    ``c_k`` the integrand. The neutral part (the smallest density) becomes
    exposure, as a printer would set it.

    Raises
    ------
    ValueError
        Stocks other than a negative and a paper (as :func:`print`), or an
        iteration that does not converge. A paper of other than 3 layers
        (black and white) gets exposure only, no filtration.
    """
    neg, pap = _print_pair(negative, paper, "balance_print")
    filters = dichroic_filters(neg.wavelengths)
    light = _print_light(neg, pap) * _grey_transmittance(neg, real(grey, "grey"))
    target = np.array(
        [np.interp(PRINT_GREY_DENSITY, layer.density, layer.log_exposure) for layer in pap.layers]
    )
    m = len(pap.layers)
    f = np.zeros(3)
    for _ in range(50):
        c = light * 10.0 ** -(f @ filters)
        e = c.sum(axis=1)
        residual = np.log10(e) - target
        if np.abs(residual).max() < 1e-10:
            break
        if m == 3:
            f = f - np.linalg.solve(-(c @ filters.T) / e[:, None], residual)
        else:  # no colour to balance: only the neutral part, whose derivative is -1
            f = f + residual.mean()
    else:
        raise ValueError(f"the print balance of {neg.name!r} on {pap.name!r} did not converge")
    neutral = f.min()
    return Filtration(*(f - neutral).tolist(), exposure=float(10.0**-neutral))


def print(
    density: Any,
    negative: str | Path | Stock,
    paper: str | Path | Stock,
    *,
    filtration: Filtration | None = None,
    exposure_ev: float = 0.0,
    couplers: bool = True,
    frame_width_mm: float = FRAME_WIDTH_MM,
) -> Float32Array:
    """Prints a developed negative onto paper: the paper's densities (H, W, m).

    Parameters
    ----------
    density : ndarray, (H, W, n)
        The negative's densities from :func:`develop`.
    negative, paper : str, Path or Stock
    filtration : Filtration, optional
        Defaults to :func:`balance_print` for the mid grey.
    exposure_ev : float
        Print exposure change in stops, within ±100 (darker print for > 0).
    couplers, frame_width_mm
        As for :func:`develop`, applied to the paper.
    """
    neg, pap = _print_pair(negative, paper, "print")
    couplers = flag(couplers, "couplers")
    fil = balance_print(neg, pap) if filtration is None else filtration
    f = np.array([fil.yellow, fil.magenta, fil.cyan])
    light = _print_light(neg, pap) * 10.0 ** -(f @ dichroic_filters(neg.wavelengths))
    light = fil.exposure * _gain(exposure_ev) * light
    if pap.halation.any():
        exposure = _transmit(density, neg, light)
        return develop(exposure, pap, couplers=couplers, frame_width_mm=frame_width_mm)
    # One pass per row: the paper's exposures are developed as they are made.
    arr = _image(density, "density", len(neg.layers))
    pixel_um = _pixel_um(frame_width_mm, arr.shape, pap.coupler_diffusion_um)
    base, dyes = _dyes(neg)
    matrix = pap.coupler_matrix if couplers else np.zeros_like(pap.coupler_matrix)
    return _native.film_print(
        arr,
        base.tolist(),
        dyes.ravel().tolist(),
        light.ravel().tolist(),
        _kernel_curves(pap),
        matrix.ravel().tolist(),
        pap.coupler_diffusion_um / pixel_um,
        1.0,
    )


def scan(density: Any, stock: str | Path | Stock, *, illuminant: str = "D65") -> Float32Array:
    """CIE XYZ (H, W, 3) of a developed film or print seen under ``illuminant``.

    ``XYZ = Σ V T x̄ȳz̄ w / Σ V ȳ w``: Y = 1 for a perfect white (transmittance
    or reflectance 1). A print's reflection density is taken as its density.
    """
    st = load_stock(stock)
    wl = st.wavelengths
    light = sp.illuminant(illuminant, wl) * sp.quadrature_weights(wl)
    cmfs = sp.cie_cmfs(wl)
    response = (cmfs * light[:, None]).T / (cmfs[:, 1] @ light)
    return _transmit(density, st, response)


def to_srgb(xyz: Any, *, encode: bool = True) -> Float32Array:
    """sRGB (H, W, 3) in [0, 1] of D65-relative XYZ: the IEC 61966-2-1 matrix,
    clipped, and its transfer curve when ``encode``."""
    arr = _image(xyz, "xyz", 3)
    # The one film function whose input meets no checking kernel: NaN came out.
    require_finite(arr, "xyz")
    rgb = np.clip(arr @ sp.XYZ_TO_SRGB.T.astype(np.float32), 0.0, 1.0)
    if flag(encode, "encode"):
        rgb = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * rgb ** (1 / 2.4) - 0.055)
    return rgb.astype(np.float32)


def _simulation_stocks(
    stock: str | Path | Stock, paper: str | Path | Stock | None
) -> tuple[Stock, Stock | None]:
    """:func:`simulate`'s film and the paper it is printed on (None for a
    reversal film, viewed directly), checked before any work: a paper given
    for a reversal film was ignored, and a film given as paper was found
    only after the film's whole development."""
    st = load_stock(stock)
    if st.kind == "paper":
        raise ValueError(f"{st.name!r} is a paper: simulate takes a negative or reversal film")
    if st.kind != "negative":
        if paper is not None:
            raise ValueError(
                f"{st.name!r} is a {st.kind} film, viewed directly: only a negative is "
                f"printed on paper, got paper={paper!r}"
            )
        return st, None
    default = "generic-paper" if len(st.layers) == 3 else "generic-bw-paper"
    return _print_pair(st, default if paper is None else paper, "simulate")


def simulate(
    image: Any,
    stock: str | Path | Stock = "generic-negative",
    *,
    paper: str | Path | Stock | None = None,
    exposure_ev: float = 0.0,
    couplers: bool = True,
    halation: bool = True,
    grain: bool = True,
    seed: int = 0,
    frame_width_mm: float = FRAME_WIDTH_MM,
    encode: bool = True,
) -> Float32Array:
    """Photographs ``image`` on film and returns what one sees, as sRGB.

    A negative is printed on ``paper`` (the generic colour or black-and-white
    paper by default), balanced for the mid grey of this exposure as a lab
    would; a reversal film is viewed directly. Both under D65.

    Parameters
    ----------
    image : ndarray, (H, W, 3) or (H, W, L)
        As for :func:`expose`.
    couplers, halation, grain, seed, frame_width_mm
        As for :func:`develop` (the film's; the paper has neither halation
        nor grain of its own).

    Returns
    -------
    ndarray, float32, (H, W, 3)
        sRGB, encoded unless ``encode=False``.

    Raises
    ------
    ValueError
        A paper as ``stock``; a ``paper`` for a reversal film, or one that is
        not a paper (before any work); and what :func:`expose` refuses.
    """
    st, pap = _simulation_stocks(stock, paper)
    flag(encode, "encode")  # before the whole simulation, not after it
    dens = develop(
        expose(image, st, exposure_ev=exposure_ev),
        st,
        couplers=couplers,
        halation=halation,
        grain=grain,
        seed=seed,
        frame_width_mm=frame_width_mm,
    )
    if pap is not None:
        fil = balance_print(st, pap, grey=MID_GREY * 2.0**exposure_ev)
        dens = print(
            dens, st, pap, filtration=fil, couplers=couplers, frame_width_mm=frame_width_mm
        )
        st = pap
    return to_srgb(scan(dens, st), encode=encode)
