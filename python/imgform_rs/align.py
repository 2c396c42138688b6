"""Three-colour alignment (lecture section 4): similarity metrics, shift search
and the colourisation of Prokudin-Gorskii glass-plate scans.

Shifts follow the conventions (``docs/conventions.rst``): ``(dy, dx)`` is what
``np.roll(moving, (dy, dx), axis=(0, 1))`` needs to land ``moving`` on
``reference``, the convention of scikit-image's ``phase_cross_correlation``.
The published shifts of the cathedral plate, G (5, 2) and R (12, 3) relative
to blue, are (row, column) displacements that move G and R onto B, i.e. this
convention: ``colorize_plate(scan, reference="b")`` returns exactly them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from . import _native
from ._arrays import as_real, flag, integer, native, real
from ._balance import auto_balance
from ._frame import FRAME_SEARCH as FRAME_SEARCH
from ._frame import channels_frame_box
from ._frame import frame_box as frame_box

Metric = Literal["ssd", "cosine", "ncc"]
Motion = Literal["translation", "euclidean", "similarity", "affine"]
MOTIONS = ("translation", "euclidean", "similarity", "affine")
Features = Literal["auto", "intensity", "gradient"]
FEATURES = ("auto", "intensity", "gradient")
Channel = Literal["r", "g", "b"]

_DTYPES = (np.uint8, np.uint16, np.float32)

#: Correlation (NCC, cosine or ECC) below which :attr:`Alignment.low_confidence`
#: is set: aligned channels of a plate correlate at 0.6-0.99, unrelated
#: images near 0.
LOW_CORRELATION = 0.3

#: :func:`colorize_plate`'s default search range, as a fraction of a
#: channel's shorter side: the exposures of a real plate are rarely more
#: than ~6 % apart, and 20 % leaves room for any scan's cropping.
DEFAULT_RANGE = 0.2
#: Rows and columns the smallest overlap of a search keeps (the core's).
MIN_OVERLAP = 2


#: :func:`align`'s default most Gauss-Newton steps per ECC pyramid level.
ECC_MAX_ITERATIONS = 50

#: :func:`align`'s default ECC tolerance: a level stops once a step moves no
#: window corner by more than this many full-resolution pixels. Steps
#: shrink several-fold each, so the warp is then within ~0.02 px of where
#: more steps would take it (on the benchmark's rotated plate 0.05 instead
#: of 0.01 moves no corner by more than 0.02 px and saves one or two
#: full-resolution steps), while channels whose content differs, as a
#: plate's do, limit the accuracy to tenths of a pixel. OpenCV's
#: ``findTransformECC`` stops on a change of the correlation below 1e-3.
ECC_TOLERANCE = 0.05


@dataclass(frozen=True)
class Level:
    """What one pyramid level searched: ``scale`` (1 = full resolution),
    ``candidates`` scored, the best ``shift`` in pixels of that level and its
    ``score``."""

    scale: int
    candidates: int
    shift: tuple[int, int]
    score: float


@dataclass(frozen=True)
class Alignment:
    """Result of :func:`align`.

    Attributes
    ----------
    shift : tuple of int, or of float with ``subpixel=True``
        ``(dy, dx)`` to roll ``moving`` by to land it on ``reference``.
    score : float
        The metric at the best integer shift (full resolution).
    surface : ndarray, float64, shape (S, S)
        Scores of the finest level: entry ``[i, j]`` is the shift
        ``surface_origin + (i, j)``; NaN where no candidate was scored (beyond
        ``max_shift``). A single-scale search gives all of ``[-k, k]^2``.
    surface_origin : tuple of int
        The shift of ``surface[0, 0]``.
    levels : tuple of Level
        The pyramid levels of the shift search, coarsest first.
    metric : str
    motion : str
        The motion model estimated.
    matrix : ndarray, float64, shape (2, 3)
        Maps a reference pixel ``(x, y, 1)`` (column, row) to the position of
        ``moving`` that lands there: :func:`apply_warp` (or
        ``cv2.warpAffine(moving, matrix, (W, H), flags=cv2.INTER_LINEAR |
        cv2.WARP_INVERSE_MAP)``) registers ``moving`` on ``reference``, the
        convention of OpenCV's ``findTransformECC`` with the reference as
        template. For a translation ``[[1, 0, -dx], [0, 1, -dy]]``.
    rotation : float
        Radians by which ``moving`` turns to land on ``reference``
        (positive from +x towards +y, i.e. clockwise on screen); 0 for a
        translation. For an affine motion, that of its closest similarity.
    scale : float
        The factor ``moving`` is magnified by to land on ``reference``.
    ecc : float
        The ECC refinement's correlation (the NCC of ``reference`` and the
        registered ``moving`` over the cropped window, of their gradient
        magnitudes with ``features="gradient"``) at the final warp; NaN for
        ``motion="translation"`` (see ``score``).
    iterations : tuple of int
        Gauss-Newton steps per ECC pyramid level, coarsest first.
    converged : bool
        Whether the finest ECC level met its tolerance (always True for a
        translation).
    at_limit : bool
        Whether the best shift lies on the edge of the search range: the
        true shift may be beyond it.

    For motions other than a translation, ``shift`` is the float ``(dy,
    dx)`` that lands the moving image's point on the reference's centre,
    ``surface``, ``score`` and ``levels`` those of the translation search
    that started the refinement.
    """

    shift: tuple[float, float] | tuple[int, int]
    score: float
    surface: npt.NDArray[np.float64] = field(repr=False)
    surface_origin: tuple[int, int]
    levels: tuple[Level, ...]
    metric: str
    motion: str = "translation"
    matrix: npt.NDArray[np.float64] = field(default_factory=lambda: _translation(0, 0))
    rotation: float = 0.0
    scale: float = 1.0
    ecc: float = math.nan
    iterations: tuple[int, ...] = ()
    converged: bool = True
    at_limit: bool = False

    @property
    def low_confidence(self) -> bool:
        """Whether the result should not be trusted: the shift is on the
        edge of the search range, the ECC refinement did not converge, or
        the correlation (``ecc`` for refined motions, ``score`` for NCC and
        cosine searches) is below ``LOW_CORRELATION``. Unrelated or
        near-constant channels and motions beyond the range land here."""
        if self.at_limit or not self.converged:
            return True
        if self.motion != "translation":
            return not self.ecc >= LOW_CORRELATION
        return self.metric != "ssd" and not self.score >= LOW_CORRELATION


def _translation(dy: float, dx: float) -> np.ndarray:
    """The matrix of the shift ``(dy, dx)``: it reads pixel ``(x - dx, y - dy)``."""
    return np.array([[1.0, 0.0, -dx], [0.0, 1.0, -dy]])


def _image(value: Any, name: str) -> np.ndarray:
    """An (H, W) uint8/uint16/float32 array; float64 is narrowed to float32."""
    arr = native(value)
    if arr.dtype == np.float64:
        big = np.isfinite(arr) & (np.abs(arr) > np.finfo(np.float32).max)
        if big.any():  # narrowed, it would be reported as holding inf
            at = tuple(int(i) for i in np.argwhere(big)[0])
            raise ValueError(
                f"{name} holds {arr[at]:g} at {at}, beyond float32's range "
                "(float64 images are narrowed to float32)"
            )
        arr = arr.astype(np.float32)
    if arr.dtype not in _DTYPES:
        raise TypeError(f"{name} must be a uint8, uint16 or float32 array, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a single-channel (H, W) image, got shape {arr.shape}")
    return arr


def similarity(a: Any, b: Any, metric: Metric = "ncc") -> float:
    """Compare two single-channel images of the same shape, pixel by pixel.

    Parameters
    ----------
    a, b : array_like, shape (H, W), uint8, uint16 or float32 (float64 is
        converted to float32); both of one dtype.
    metric : {"ssd", "cosine", "ncc"}
        ``"ssd"``: ``sqrt(sum (a - b)^2)`` (lecture eq. 5), lower is better.
        ``"cosine"``: ``<a, b> / (|a| |b|)`` (eq. 6); ``"ncc"``: the cosine of
        the mean-free images (eq. 7), invariant to ``s * I + t`` with
        ``s > 0``; both higher is better, in [-1, 1]. A constant image (no
        variance for NCC, all zeros for cosine) scores 0.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Different shapes, NaN or infinite samples or samples beyond ±2^50
        (the search sums their products in float32), an unknown metric.
    TypeError
        An unsupported dtype, or two different dtypes.

    Examples
    --------
    >>> a = np.array([[1, 2], [3, 4]], np.float32)
    >>> round(similarity(a, 2 * a + 1, "ncc"), 6)
    1.0
    >>> similarity(a, a, "ssd")
    0.0
    """
    return float(_native.similarity(_image(a, "a"), _image(b, "b"), str(metric)))


def _levels(pyramid: int | str) -> int | None:
    if isinstance(pyramid, str):
        if pyramid != "auto":
            raise ValueError(f'pyramid must be "auto" or a number of levels >= 0, got {pyramid!r}')
        return None
    levels = integer(pyramid, "pyramid")
    if not 0 <= levels < 2**64:  # the native usize
        raise ValueError(f'pyramid must be "auto" or a number of levels >= 0, got {levels}')
    return levels


def _resolve_features(features: str, motion: str) -> str:
    """What ``features="auto"`` compares for ``motion``: gradient magnitudes
    when the motion is refined by ECC, whose intensity optimum the different
    content of a plate's channels pulls off the true warp (0.77 px against
    0.27 px at the benchmark plate's corners under a similarity), and
    intensities for a translation, where both find the exact integer shift
    and intensities skip the Sobel pass. Other values are returned as given.

    Raises ``ValueError`` for an unknown ``features`` or ``motion``."""
    if motion not in MOTIONS:
        raise ValueError(f"motion must be one of {', '.join(MOTIONS)}, got {motion!r}")
    if features not in FEATURES:
        raise ValueError(f"features must be one of {', '.join(FEATURES)}, got {features!r}")
    if features != "auto":
        return features
    return "intensity" if motion == "translation" else "gradient"


def align(
    reference: Any,
    moving: Any,
    *,
    max_shift: int = 15,
    metric: Metric = "ncc",
    crop: float = 0.1,
    pyramid: int | str = "auto",
    features: Features = "auto",
    subpixel: bool = False,
    motion: Motion = "translation",
    max_iterations: int = ECC_MAX_ITERATIONS,
    tolerance: float = ECC_TOLERANCE,
) -> Alignment:
    """Find the shift (or warp) that lands ``moving`` on ``reference``.

    Every candidate ``(dy, dx)`` in ``[-max_shift, max_shift]^2`` is scored
    (rayon-parallel; the result is identical for any thread count): the
    reference pixels inside the window left after cutting ``crop`` of each
    border are compared with the moving pixels ``np.roll`` would bring there,
    using only moving pixels that exist (no wrap-around). While the shift is
    within the crop margin every candidate is compared over the same window.
    A wide search is scored for NCC and cosine through one FFT correlation of
    the two images, in float64, where that is the faster (from ~200
    candidates on a 1024 x 1024 image, ~500 on larger ones: ``pyramid=0``
    with ``max_shift >= 7`` or ``>= 11``); it gives the same sums as scoring
    each candidate, in a fraction of the time. SSD is always summed per
    candidate, so that an exact match scores exactly 0.

    Ties (e.g. a constant image, where every candidate scores 0) go to the
    smallest ``dy^2 + dx^2``, then the lexicographically smallest ``(dy, dx)``.

    Parameters
    ----------
    reference, moving : array_like, shape (H, W), uint8, uint16 or float32
        Of one shape and dtype (float64 is converted to float32).
    max_shift : int
        Largest ``|dy|`` and ``|dx|``, in pixels, ``0 <= max_shift < min(H, W)``.
    metric : {"ncc", "ssd", "cosine"}
        See :func:`similarity`.
    crop : float in [0, 0.5)
        Fraction of each border left out of the comparison.
    pyramid : "auto" or int
        Number of 2x box-filter halvings before a coarse-to-fine search; 0 is
        a single-scale exhaustive search. ``"auto"`` halves while the search
        radius exceeds 8 pixels and a level keeps >= 64 pixels per side: the
        coarsest level scores at most 17 x 17 candidates, every finer one 5 x 5
        around twice the coarser shift.
    features : {"auto", "intensity", "gradient"}
        ``"gradient"`` compares Sobel gradient magnitudes, for channels whose
        brightness differs (the "Emir" plate), in the shift search and in the
        ECC refinement. Edges sit at the same place in every channel whatever
        their brightness, so for motions other than a translation it is also
        the more accurate choice when the channels record different content,
        as a plate's do (see the three-colour guide), and the one that
        follows anti-correlated channels. ``"auto"`` (the default) is
        ``"gradient"`` for those motions and ``"intensity"`` for a
        translation, whose integer shift both find exactly on the benchmark
        plates, intensities without the Sobel pass.
    subpixel : bool
        Refine the peak with a parabola through its neighbours on each axis
        (float shift, at most 0.5 px from the integer one).
    motion : {"translation", "euclidean", "similarity", "affine"}
        ``"translation"`` is the exhaustive shift search above. The others
        start from its shift and refine a rotation (``"euclidean"``), a
        rotation and isotropic scale (``"similarity"``) or a general linear
        map (``"affine"``) with the translation by maximising the ECC
        (Evangelidis & Psarakis 2008, as OpenCV's ``findTransformECC``),
        Gauss-Newton steps coarse to fine through a pyramid whose coarsest
        level keeps >= 160 pixels per side; the per-pixel sums run in Rust
        over row bands and do not depend on the thread count. ECC ignores
        gain and offset between the channels, whatever ``metric`` the shift
        search used, and correlates the ``features`` the search compared.
    max_iterations : int
        Most Gauss-Newton steps per pyramid level.
    tolerance : float
        A level stops once a step moves no corner of the window by more
        than this many full-resolution pixels.

    Returns
    -------
    Alignment

    Raises
    ------
    ValueError
        Different shapes; ``max_shift`` negative or not smaller than the
        image; images too small for the search (an overlap of fewer than 2
        pixels per axis at some level) or for the motion (fewer than 64
        window pixels per parameter); ``crop`` outside [0, 0.5); NaN or
        infinite samples, or samples beyond ±2^50; an unknown metric,
        features, pyramid or motion;
        a channel ECC cannot follow (constant, or without texture along
        some parameter) or a warp that leaves the moving image.
    TypeError
        Unsupported or different dtypes; a ``max_shift``, ``pyramid`` or
        ``max_iterations`` that is not an integer, a ``crop`` or
        ``tolerance`` that is not a real number.

    Examples
    --------
    >>> y, x = np.mgrid[:64, :64]
    >>> ref = (np.sin(x / 5.0) + np.cos(y / 7.0 + x / 11.0)).astype(np.float32)
    >>> moving = np.roll(ref, (-3, 2), axis=(0, 1))
    >>> align(ref, moving, max_shift=5).shift
    (3, -2)
    """
    features = _resolve_features(features, motion)
    ref = _image(reference, "reference")
    k = integer(max_shift, "max_shift")
    # Checked here too: a k beyond the native i64 is an OverflowError there.
    if not 0 <= k < min(ref.shape):
        h, w = ref.shape
        raise ValueError(f"max_shift must be >= 0 and smaller than the image ({h}x{w}), got {k}")
    shift, score, surface, origin, levels = _native.align_images(
        ref,
        _image(moving, "moving"),
        k,
        str(metric),
        real(crop, "crop"),
        _levels(pyramid),
        str(features),
        flag(subpixel, "subpixel"),
    )
    if not subpixel:
        shift = (int(shift[0]), int(shift[1]))
    found = Alignment(
        shift=shift,
        score=score,
        surface=surface,
        surface_origin=origin,
        levels=tuple(Level(*lv) for lv in levels),
        metric=str(metric),
        matrix=_translation(*shift),
        at_limit=k > 0 and max(abs(round(shift[0])), abs(round(shift[1]))) >= k,
    )
    if motion == "translation":
        return found
    return _refined(
        reference, [moving], [found], str(motion), crop, max_iterations, tolerance, features
    )[0]


def _refined(reference, movings, founds, motion, crop, max_iterations, tolerance, features):
    """Each of ``founds`` (translations of ``movings`` onto ``reference``)
    refined under ``motion`` by ECC on ``features``, in one native call that
    builds the reference's pyramid and sums once for all of them."""
    steps = integer(max_iterations, "max_iterations")
    # The native usize would make a negative or huge count an OverflowError.
    if not 1 <= steps < 2**64:
        raise ValueError(f"max_iterations must be an int in [1, 2**64), got {steps}")
    results = _native.refine_warp(
        _image(reference, "reference"),
        [_image(m, "moving") for m in movings],
        motion,
        [f.matrix.tolist() for f in founds],
        real(crop, "crop"),
        None,
        steps,
        real(tolerance, "tolerance"),
        str(features),
    )
    h, w = np.shape(reference)
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    out = []
    for found, (matrix, ecc, iterations, converged) in zip(founds, results, strict=True):
        m = np.array(matrix)
        # The moving point read at the reference's centre lands there.
        dx, dy = centre - (m[:, :2] @ centre + m[:, 2])
        # The similarity closest to the linear part (exact for the others):
        # moving is rotated and scaled by the inverse of it.
        a = 0.5 * (m[0, 0] + m[1, 1])
        b = 0.5 * (m[1, 0] - m[0, 1])
        out.append(
            replace(
                found,
                shift=(float(dy), float(dx)),
                motion=motion,
                matrix=m,
                rotation=-math.atan2(b, a),
                scale=1.0 / math.hypot(a, b),
                ecc=float(ecc),
                iterations=tuple(iterations),
                converged=bool(converged),
            )
        )
    return out


def _roll_fill(image: np.ndarray, dy: int, dx: int, fill: Any) -> np.ndarray:
    """``np.roll`` without wrap-around: vacated pixels get ``fill``."""
    h, w = image.shape[:2]
    out = np.full_like(image, fill)
    if abs(dy) < h and abs(dx) < w:
        out[max(dy, 0) : h + min(dy, 0), max(dx, 0) : w + min(dx, 0)] = image[
            max(-dy, 0) : h + min(-dy, 0), max(-dx, 0) : w + min(-dx, 0)
        ]
    return out


def _check_fill(fill: Any, dtype: np.dtype) -> None:
    """TypeError unless ``fill`` is a real number, ValueError unless
    ``dtype`` holds it: an integer within its range for integer images
    (NumPy would wrap or truncate it, or raise OverflowError, and the
    interpolation would clip it), a number within its range, NaN or an
    infinity for float ones."""
    value = real(fill, "fill")
    if dtype.kind in "biu":
        lo, hi = (0, 1) if dtype.kind == "b" else (np.iinfo(dtype).min, np.iinfo(dtype).max)
        if not (value.is_integer() and lo <= fill <= hi):
            raise ValueError(f"fill must be an integer from {lo} to {hi} for {dtype}, got {fill!r}")
    elif math.isfinite(value) and abs(value) > float(np.finfo(dtype).max):
        raise ValueError(f"fill must be within {dtype}'s range, NaN or infinite, got {fill!r}")


def apply_shift(image: Any, shift: Any, *, fill: float = 0) -> np.ndarray:
    """Move an image by ``shift = (dy, dx)`` the way ``np.roll`` would, but
    without wrap-around: pixels that come from outside get ``fill``.

    Integer shifts copy pixels exactly. Fractional shifts interpolate
    bilinearly (``out[y, x] = image(y - dy, x - dx)``); a pixel whose
    interpolation needs a sample from outside the image gets ``fill``.
    Integer images are rounded half up and clipped to their range.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, C), any real dtype
    shift : pair of numbers ``(dy, dx)``
    fill : number

    Returns
    -------
    ndarray, same shape and dtype as ``image``

    Raises
    ------
    ValueError
        A shift that is not two finite numbers, an image that is not 2-D/3-D,
        or a ``fill`` its dtype cannot hold (-1 or 0.5 for uint8).
    TypeError
        A ``fill`` that is not a real number.

    Examples
    --------
    >>> apply_shift(np.arange(4).reshape(2, 2), (0, 1))
    array([[0, 0],
           [0, 2]])
    >>> apply_shift(np.array([[0.0, 2.0]]), (0, 0.5), fill=-1)
    array([[-1.,  1.]])
    """
    img = np.asarray(image)
    if img.ndim not in (2, 3) or img.dtype.kind not in "biuf":
        raise ValueError(
            f"image must be a real (H, W) or (H, W, C) array, got {img.dtype} {img.shape}"
        )
    s = np.asarray(shift, dtype=np.float64)
    if s.shape != (2,) or not np.all(np.isfinite(s)):
        raise ValueError(f"shift must be two finite numbers (dy, dx), got {shift!r}")
    _check_fill(fill, img.dtype)
    dy, dx = float(s[0]), float(s[1])
    if dy.is_integer() and dx.is_integer():
        return _roll_fill(img, int(dy), int(dx), fill)
    fy, fx = int(np.floor(dy)), int(np.floor(dx))
    ty, tx = dy - fy, dx - fx
    src = img.astype(_interpolation_type(img.dtype))
    acc = np.zeros_like(src)
    # out(y) = (1 - ty) img(y - fy) + ty img(y - fy - 1), and likewise in x.
    # A mask of the image marks the taps from outside (a NaN of the image's
    # own stays NaN where it is read).
    inside = np.ones(img.shape, bool)
    outside = np.zeros(img.shape, bool)
    for oy, wy in ((fy, 1.0 - ty), (fy + 1, ty)):
        for ox, wx in ((fx, 1.0 - tx), (fx + 1, tx)):
            if wy * wx > 0.0:
                acc += wy * wx * _roll_fill(src, oy, ox, 0.0)
                outside |= ~_roll_fill(inside, oy, ox, False)
    if img.dtype.kind in "iu":
        info = np.iinfo(img.dtype)
        bounds = [_held(bound, acc.dtype) for bound in (info.min, info.max)]
        acc = np.clip(np.floor(acc + 0.5), *bounds)
    out = acc.astype(img.dtype)
    # After the cast: an integer fill beyond 2^53 would round in float64.
    out[outside] = fill
    return out


def _interpolation_type(dtype: np.dtype) -> type:
    """float64, or for 64-bit integers the platform's long double: x86's
    64-bit significand holds every int64 and uint64 value, where float64 would
    round those beyond 2^53 (on platforms whose long double is float64 they
    round as before)."""
    return np.longdouble if dtype.kind in "iu" and dtype.itemsize == 8 else np.float64


def _held(bound: int, ftype: np.dtype) -> np.floating:
    """``bound`` (an integer type's limit) in ``ftype``, moved towards 0 when
    it rounds beyond it: float64's 2^63 for int64's 2^63 - 1 would wrap round
    to the most negative value in the cast back."""
    value = ftype.type(bound)
    return np.nextafter(value, ftype.type(0)) if abs(int(value)) > abs(bound) else value


def apply_warp(
    image: Any, matrix: Any, *, fill: float = 0, interpolation: str = "bilinear"
) -> np.ndarray:
    """Resample ``image`` through a 2x3 ``matrix`` (an :attr:`Alignment.matrix`):
    ``out[y, x] = image at matrix @ (x, y, 1)``, with the remap kernel of
    :func:`imgform_rs.remap` (taps outside the image read ``fill``).

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C), uint8, uint16 or float32
    matrix : array_like, shape (2, 3)
    fill : number
        As in :func:`imgform_rs.remap`: finite, held exactly by the dtype.
    interpolation : {"bilinear", "bicubic"}

    Returns
    -------
    ndarray, same shape and dtype as ``image``

    Raises
    ------
    ValueError
        A matrix that is not 2x3 and finite; everything :func:`remap` refuses.
    TypeError
        A matrix that is not of real numbers (strings are not parsed), a
        ``fill`` that is not a real number.

    Examples
    --------
    >>> img = np.arange(12, dtype=np.float32).reshape(3, 4)
    >>> apply_warp(img, [[1, 0, 1], [0, 1, 0]], fill=-1)[0]
    array([ 1.,  2.,  3., -1.], dtype=float32)
    """
    from .remap import remap

    # as_real: a float64 cast would parse a matrix of strings.
    m = as_real(matrix, "matrix", np.float64)
    if m.shape != (2, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"matrix must be a finite 2x3 array, got {matrix!r}")
    img = np.asarray(image)
    if img.ndim not in (2, 3):
        raise ValueError(f"image must be (H, W) or (H, W, C), got shape {img.shape}")
    h, w = img.shape[:2]
    # One row and one column term in float64, their sum in float32: exact to
    # ~1e-4 px below 4000 px, well inside the remap's 1/256 px positions.
    x = np.arange(w, dtype=np.float64)[None, :]
    y = np.arange(h, dtype=np.float64)[:, None]
    map_x = (m[0, 0] * x).astype(np.float32) + (m[0, 1] * y + m[0, 2]).astype(np.float32)
    map_y = (m[1, 0] * x).astype(np.float32) + (m[1, 1] * y + m[1, 2]).astype(np.float32)
    return remap(img, (map_x, map_y), interpolation=interpolation, fill=fill)


def stack_channels(r: Any, g: Any, b: Any) -> np.ndarray:
    """Stack three (H, W) channels of one shape and dtype into an (H, W, 3) RGB
    image (channel order R, G, B as everywhere in imgform-rs).

    Raises
    ------
    ValueError
        Channels that are not 2-D or differ in shape or dtype.

    Examples
    --------
    >>> stack_channels(np.zeros((2, 3)), np.ones((2, 3)), np.zeros((2, 3))).shape
    (2, 3, 3)
    """
    chans = [np.asarray(c) for c in (r, g, b)]
    if any(c.ndim != 2 for c in chans) or len({(c.shape, c.dtype) for c in chans}) != 1:
        got = ", ".join(f"{c.dtype} {c.shape}" for c in chans)
        raise ValueError(f"r, g, b must be (H, W) arrays of one shape and dtype, got {got}")
    return np.stack(chans, axis=-1)


def colorize_plate(
    plate: Any,
    *,
    reference: Channel = "g",
    metric: Metric = "ncc",
    max_shift: int | None = None,
    crop: float = 0.1,
    pyramid: int | str = "auto",
    features: Features = "auto",
    subpixel: bool = False,
    frame: bool = True,
    motion: Motion = "translation",
    white_balance: bool = False,
    auto_contrast: bool = False,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Colourise a Prokudin-Gorskii glass-plate scan.

    The scan holds three exposures stacked top to bottom through blue, green
    and red filters. It is cut into thirds (a remainder of one or two rows at
    the bottom is dropped), the two other channels are aligned onto
    ``reference`` with :func:`align` and shifted (:func:`apply_shift`), and the
    result is cropped twice: to the area all three channels cover (the
    borders the shifts leave empty are cut), then (with ``frame=True``) by
    the scanning frame as :func:`frame_box` finds it. Frame detection reads
    only the outer bands of the plate, a small part of the alignment's cost.

    Parameters
    ----------
    plate : array_like, shape (3 H, W), uint8, uint16 or float32
        Or a path to an 8-bit JPG / 16-bit TIFF scan (read by :func:`read_plate`).
    reference : {"g", "r", "b"}
        The channel the others are aligned onto (the lecture uses red).
    max_shift : int, optional
        Default :func:`default_max_shift`: 20 % of the channel's shorter
        side (at least 15, or what a small plate's crop leaves), ~70 for
        the small published JPGs and ~650 for a full-resolution scan; the
        coarse-to-fine search keeps it cheap and
        exact at full resolution.
    metric, crop, pyramid, subpixel
        As in :func:`align`.
    features : {"auto", "intensity", "gradient"}
        As in :func:`align`: ``"auto"`` correlates gradient magnitudes for
        every motion but a translation, intensities for a translation.
    frame : bool
        Crop the scanning frame.
    motion : {"translation", "euclidean", "similarity", "affine"}
        As in :func:`align`; other motions than a translation resample the
        channels through their matrices (:func:`apply_warp`, bilinear) and
        crop to the rectangle inside all three warped channels.
    white_balance, auto_contrast : bool
        Finish the cropped result with :func:`auto_balance` (grey-world
        gains; a stretch of the 0.5 %..99.5 % quantiles to the full range).

    Returns
    -------
    rgb : ndarray, shape (h, w, 3), the plate's dtype
    found : dict
        For a translation ``{"r": (dy, dx), "g": ..., "b": ...}``, each
        relative to ``reference`` (which gets ``(0, 0)``) in the ``np.roll``
        convention. For other motions the :class:`Alignment` of each channel
        (``.matrix``, ``.rotation``, ``.scale``, ``.shift``, ``.ecc``); the
        reference's is the identity.

    Raises
    ------
    ValueError
        A plate that is not 2-D or has fewer than 3 rows, an unknown
        reference channel, and everything :func:`align` refuses.
    TypeError
        An unsupported dtype.

    Examples
    --------
    >>> y, x = np.mgrid[:80, :90]
    >>> scene = (100 + 60 * np.sin(x / 6.0) * np.cos(y / 9.0)).astype(np.uint8)
    >>> plate = np.vstack([np.roll(scene, (2, -1), (0, 1)), scene, np.roll(scene, (-3, 2), (0, 1))])
    >>> rgb, shifts = colorize_plate(plate, frame=False)
    >>> shifts
    {'r': (3, -2), 'g': (0, 0), 'b': (-2, 1)}
    >>> rgb.shape
    (75, 87, 3)
    """
    rgb, found = _colorize(
        plate,
        reference=reference,
        metric=metric,
        max_shift=max_shift,
        crop=crop,
        pyramid=pyramid,
        features=features,
        subpixel=subpixel,
        frame=frame,
        motion=motion,
        white_balance=white_balance,
        auto_contrast=auto_contrast,
    )
    if motion == "translation":
        return rgb, {c: a.shift for c, a in found.items()}
    return rgb, found


def _colorize(
    plate: Any,
    *,
    reference: Channel = "g",
    metric: Metric = "ncc",
    max_shift: int | None = None,
    crop: float = 0.1,
    pyramid: int | str = "auto",
    features: Features = "auto",
    subpixel: bool = False,
    frame: bool = True,
    motion: Motion = "translation",
    white_balance: bool = False,
    auto_contrast: bool = False,
) -> tuple[np.ndarray, dict[str, Alignment]]:
    """:func:`colorize_plate` with every channel's :class:`Alignment` (for a
    translation too: ``imgform align`` reports its score and confidence)."""
    if isinstance(plate, (str, Path)):
        plate = read_plate(plate)
    arr = np.asarray(plate)
    if arr.ndim != 2 or arr.shape[0] < 3:
        raise ValueError(f"plate must be a (3 H, W) single-channel scan, got shape {arr.shape}")
    if reference not in ("r", "g", "b"):
        raise ValueError(f'reference must be "r", "g" or "b", got {reference!r}')
    features = _resolve_features(features, motion)
    h = arr.shape[0] // 3
    chans = {"b": arr[:h], "g": arr[h : 2 * h], "r": arr[2 * h : 3 * h]}
    k = default_max_shift(h, arr.shape[1], crop) if max_shift is None else max_shift
    ref = chans[reference]
    others = [c for c in "rgb" if c != reference]
    search = {"max_shift": k, "metric": metric, "crop": crop, "pyramid": pyramid}
    found = {
        c: align(ref, chans[c], **search, features=features, subpixel=subpixel) for c in others
    }
    if motion != "translation":
        # One refinement for both channels: the reference's pyramid is shared.
        refined = _refined(
            ref,
            [chans[c] for c in others],
            [found[c] for c in others],
            motion,
            crop,
            ECC_MAX_ITERATIONS,
            ECC_TOLERANCE,
            features,
        )
        found = dict(zip(others, refined, strict=True))
    found[reference] = _identity(metric, motion, subpixel)
    found = {c: found[c] for c in "rgb"}
    if motion == "translation":
        common = _common_area(h, arr.shape[1], [a.shift for a in found.values()])
        aligned = [_shifted_crop(chans[c], found[c].shift, common) for c in "rgb"]
    else:
        rows, cols = _warped_area(h, arr.shape[1], [a.matrix for a in found.values()])
        aligned = [
            chans[c][rows, cols]
            if c == reference
            else apply_warp(chans[c], found[c].matrix)[rows, cols]
            for c in "rgb"
        ]
    if frame:
        t, b, lft, rgt = channels_frame_box(aligned)
        aligned = [c[t:b, lft:rgt] for c in aligned]
    rgb = np.stack(aligned, axis=-1)
    if white_balance or auto_contrast:
        rgb = auto_balance(rgb, contrast=auto_contrast, white_balance=white_balance)
    return rgb, found


def describe_estimate(found: tuple | Alignment) -> str:
    """One channel's estimate in words, what ``imgform align`` reports per
    plate: for a translation its shift and the search's score, for other
    motions the rotation, scale, centre shift and ECC; then "LOW
    CONFIDENCE" and why when :attr:`Alignment.low_confidence` is set. A
    plain shift (an entry of :func:`colorize_plate`'s result for a
    translation) is printed as it is.

    Examples
    --------
    >>> y, x = np.mgrid[:64, :64]
    >>> ref = (np.sin(x / 5.0) + np.cos(y / 7.0 + x / 11.0)).astype(np.float32)
    >>> describe_estimate(align(ref, np.roll(ref, (-3, 2), axis=(0, 1)), max_shift=5))
    'shift (3, -2), NCC 1.000'
    >>> describe_estimate(align(ref, np.roll(ref, (-3, 2), axis=(0, 1)), max_shift=3))
    'shift (3, -2), NCC 1.000 (LOW CONFIDENCE: on the edge of the search range)'
    """
    if not isinstance(found, Alignment):
        return str(found)
    dy, dx = found.shift
    if found.motion == "translation":
        shift = f"({dy:.2f}, {dx:.2f})" if isinstance(dy, float) else f"({dy}, {dx})"
        text = f"shift {shift}, {found.metric.upper()} {found.score:.3f}"
    else:
        text = (
            f"rotation {math.degrees(found.rotation):.3f} deg, scale {found.scale:.5f}, "
            f"shift ({dy:.2f}, {dx:.2f}), ECC {found.ecc:.3f}"
        )
    if not found.low_confidence:
        return text
    if found.at_limit:
        why = "on the edge of the search range"
    elif not found.converged:
        why = "ECC did not converge"
    else:
        why = f"correlation below {LOW_CORRELATION}"
    return f"{text} (LOW CONFIDENCE: {why})"


def default_max_shift(height: int, width: int, crop: float = 0.1) -> int:
    """:func:`colorize_plate`'s search range for channels of ``height x
    width``: ``DEFAULT_RANGE`` of the shorter side (at least 15), so any shift
    a real plate has is inside it; the pyramid keeps the wide range cheap.

    Never more than :func:`align` takes with ``crop``: the overlap of its
    largest shift with the cropped window must keep :data:`MIN_OVERLAP`
    rows and columns, which the floor of 15 broke on channels of fewer than
    ~20 rows (align then refused a ``max_shift`` the caller never gave)."""
    crop = real(crop, "crop")
    wanted = max(15, round(DEFAULT_RANGE * min(height, width)))
    fits = min(n - math.floor(crop * n) - MIN_OVERLAP for n in (height, width))
    return max(0, min(wanted, min(height, width) - 1, fits))


def _common_area(h: int, w: int, shifts) -> tuple[slice, slice]:
    """The rows and columns every shifted channel covers: the borders the
    shifts empty, up to the largest shift on each side, are left out."""
    dys = [s[0] for s in shifts]
    dxs = [s[1] for s in shifts]
    top, left = math.ceil(max(dys)), math.ceil(max(dxs))
    bottom, right = math.ceil(max(-d for d in dys)), math.ceil(max(-d for d in dxs))
    return slice(top, max(top, h - bottom)), slice(left, max(left, w - right))


def _identity(metric: str, motion: str, subpixel: bool) -> Alignment:
    """The reference channel's alignment onto itself (an integer shift for a
    translation without ``subpixel``, like the others'), with the score of
    identical images."""
    integer = motion == "translation" and not subpixel
    return Alignment(
        shift=(0, 0) if integer else (0.0, 0.0),
        score=0.0 if metric == "ssd" else 1.0,
        surface=np.empty((0, 0)),
        surface_origin=(0, 0),
        levels=(),
        metric=metric,
        motion=motion,
        matrix=_translation(0, 0),
        ecc=1.0,
    )


def _warped_area(h: int, w: int, matrices) -> tuple[slice, slice]:
    """The rows and columns inside every warped channel: for each matrix
    (reference pixel to channel position) the moving image's edges are
    mapped back into the reference and the box inside them kept, one pixel
    in so that no bilinear tap reads outside."""
    top, bottom, left, right = 0.0, h - 1.0, 0.0, w - 1.0
    for m in matrices:
        inv = np.linalg.inv(np.vstack([m, [0.0, 0.0, 1.0]]))[:2]
        corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float)
        (x00, y00), (x10, y10), (x01, y01), (x11, y11) = corners @ inv.T
        top, bottom = max(top, y00, y10), min(bottom, y01, y11)
        left, right = max(left, x00, x01), min(right, x10, x11)
    t, lft = math.ceil(top) + 1, math.ceil(left) + 1
    b, rgt = math.floor(bottom), math.floor(right)
    return slice(t, max(t, b)), slice(lft, max(lft, rgt))


def _shifted_crop(channel: np.ndarray, shift, area: tuple[slice, slice]) -> np.ndarray:
    """``apply_shift(channel, shift)[area]``; for an integer shift a view of
    ``channel`` (no copy of the whole plate before the crop)."""
    dy, dx = shift
    rows, cols = area
    if float(dy).is_integer() and float(dx).is_integer():
        dy, dx = int(dy), int(dx)
        return channel[rows.start - dy : rows.stop - dy, cols.start - dx : cols.stop - dx]
    return apply_shift(channel, shift)[rows, cols]


def read_plate(path: str | Path) -> np.ndarray:
    """Read a plate scan (8-bit JPG, 16-bit TIFF, PNG...) as a 2-D array with
    imageio; an RGB file of a grey scan is averaged to one channel. 16-bit
    scans stay uint16, 16-bit RGB PNGs too, which imageio would read as
    8-bit (see :mod:`imgform_rs._png`).

    Raises
    ------
    ValueError
        A file that cannot be read or decoded, or is not a 2-D / RGB image
        of uint8, uint16 or float32 samples (floats from 0 to 1, NaN
        refused); the message names the file.
    """
    from ._png import read_image

    path = Path(path)
    try:
        img = read_image(path)
    except Exception as exc:  # imageio raises many types for bad files
        reason = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise ValueError(f"cannot read plate {str(path)!r}: {reason}") from exc
    if img.ndim == 3 and img.shape[2] in (3, 4):
        grey = img[..., :3].mean(axis=-1, dtype=np.float64)
        # Integers round to the nearest level; floats keep their fraction
        # (rounded too, a float scan on 0..1 became black and white).
        img = (grey if img.dtype.kind == "f" else np.floor(grey + 0.5)).astype(img.dtype)
    if img.ndim != 2 or img.dtype not in _DTYPES:
        raise ValueError(
            f"plate {str(path)!r} must be a grey or RGB image of uint8, uint16 or float32, "
            f"got {img.dtype} {img.shape}"
        )
    if img.dtype.kind == "f" and img.size and not (img.min() >= 0 and img.max() <= 1):
        # Its colour image is written on 0..1: a scan on 0..255 came out white.
        raise ValueError(
            f"a float plate holds values from 0 to 1, {str(path)!r} holds "
            f"{img.min():g} to {img.max():g}"
        )
    return img
