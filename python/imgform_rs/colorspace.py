"""Output colour spaces of :func:`imgform_rs.develop`: primaries, white, encoding.

Each RGB space is defined by the CIE 1931 xy chromaticities of its three
primaries and of its white; the matrix from linear RGB to XYZ follows from
them (SMPTE RP 177: the primaries' XYZ scaled so that RGB (1, 1, 1) is the
white with Y = 1). A space whose white is not D65 (ProPhoto's D50) is reached
through the Bradford chromatic adaptation, as ICC profiles and LibRaw do
(ProPhoto to D50, ACES2065-1 to the ACES white near D60), so sRGB's white
stays neutral there. ``"xyz"`` is CIE XYZ relative to D65 white (Y = 1), not
adapted to D50, as LibRaw's XYZ output: a D65 white has Z = 1.089, which the
clip to [0, 1] of every output cuts to 1, in LibRaw too.

Each space names the transfer curve it is encoded with, which ``tone="auto"``
picks: the sRGB curve for sRGB and Display P3, Adobe RGB (1998)'s 563/256
power (``"gamma22"``), BT.709's curve for Rec. 2020 (BT.2020's constants for
10-bit systems are BT.709's), ROMM's for ProPhoto (``"romm"``), and linear
for XYZ and ACES2065-1, which are defined linear.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["COLOR_SPACES", "ColorSpace", "bradford", "rgb_to_xyz", "srgb_to"]

Float64Array = npt.NDArray[np.float64]

D65 = (0.3127, 0.3290)
D50 = (0.3457, 0.3585)
ACES_WHITE = (0.32168, 0.33767)

# Bradford's cone-response matrix (Lam 1985), as ICC.1 Annex E gives it.
_BRADFORD = np.array(
    [
        [0.8951, 0.2664, -0.1614],
        [-0.7502, 1.7135, 0.0367],
        [0.0389, -0.0685, 1.0296],
    ]
)


@dataclass(frozen=True)
class ColorSpace:
    """An output colour space.

    Attributes
    ----------
    name : str
        Its key in :data:`COLOR_SPACES`.
    title : str
        Its usual name, e.g. ``"Adobe RGB (1998)"``.
    primaries : tuple of three (x, y), or None
        The red, green and blue chromaticities; None for XYZ itself.
    white : (x, y)
        The white point's chromaticity.
    tone : str
        The transfer curve the space is encoded with (a :data:`~imgform_rs.TONES` name).
    adapt : bool
        Whether colours are chromatically adapted from D65 to ``white``.
    libraw : int
        LibRaw's ``output_color`` (rawpy's ``ColorSpace`` value) for it.
    """

    name: str
    title: str
    primaries: tuple[tuple[float, float], ...] | None
    white: tuple[float, float]
    tone: str
    adapt: bool
    libraw: int


_SPACES = (
    ColorSpace("srgb", "sRGB", ((0.64, 0.33), (0.30, 0.60), (0.15, 0.06)), D65, "srgb", True, 1),
    ColorSpace(
        "adobe_rgb",
        "Adobe RGB (1998)",
        ((0.64, 0.33), (0.21, 0.71), (0.15, 0.06)),
        D65,
        "gamma22",
        True,
        2,
    ),
    ColorSpace(
        "display_p3",
        "Display P3",
        ((0.680, 0.320), (0.265, 0.690), (0.150, 0.060)),
        D65,
        "srgb",
        True,
        7,
    ),
    ColorSpace(
        "rec2020",
        "Rec. 2020",
        ((0.708, 0.292), (0.170, 0.797), (0.131, 0.046)),
        D65,
        "bt709",
        True,
        8,
    ),
    ColorSpace(
        "prophoto",
        "ProPhoto RGB (ROMM)",
        ((0.7347, 0.2653), (0.1596, 0.8404), (0.0366, 0.0001)),
        D50,
        "romm",
        True,
        4,
    ),
    ColorSpace("xyz", "CIE XYZ (D65)", None, D65, "linear", False, 5),
    ColorSpace(
        "aces2065_1",
        "ACES2065-1 (AP0)",
        ((0.7347, 0.2653), (0.0, 1.0), (0.0001, -0.0770)),
        ACES_WHITE,
        "linear",
        True,
        6,
    ),
)

COLOR_SPACES: dict[str, ColorSpace] = {s.name: s for s in _SPACES}
"""Every output colour space :func:`imgform_rs.develop` offers besides ``"camera"``."""


def _xyz(xy: tuple[float, float]) -> Float64Array:
    """XYZ of a chromaticity at Y = 1."""
    x, y = xy
    return np.array([x / y, 1.0, (1.0 - x - y) / y])


def rgb_to_xyz(space: ColorSpace) -> Float64Array:
    """The matrix from linear RGB of ``space`` to XYZ (its own white, Y = 1).

    Examples
    --------
    >>> m = rgb_to_xyz(COLOR_SPACES["srgb"])
    >>> np.round(m[1], 4).tolist()  # luminance weights of R, G, B
    [0.2126, 0.7152, 0.0722]
    """
    if space.primaries is None:
        return np.eye(3)
    columns = np.stack([_xyz(p) for p in space.primaries], axis=1)
    return columns * np.linalg.solve(columns, _xyz(space.white))


def bradford(source: tuple[float, float], target: tuple[float, float]) -> Float64Array:
    """The Bradford adaptation from white ``source`` to ``target``, XYZ to XYZ."""
    src, dst = _BRADFORD @ _xyz(source), _BRADFORD @ _xyz(target)
    return np.linalg.solve(_BRADFORD, (dst / src)[:, None] * _BRADFORD)


def srgb_to(name: str) -> Float64Array:
    """The matrix from linear sRGB to linear RGB of the space ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`COLOR_SPACES`.

    Returns
    -------
    ndarray, float64, shape (3, 3)

    Raises
    ------
    ValueError
        For an unknown name.

    Examples
    --------
    >>> np.round(srgb_to("adobe_rgb") @ [1.0, 1.0, 1.0], 6).tolist()  # white stays white
    [1.0, 1.0, 1.0]
    """
    space = COLOR_SPACES.get(name) if isinstance(name, str) else None
    if space is None:
        raise ValueError(f"colour space must be one of {tuple(COLOR_SPACES)}, got {name!r}")
    to_xyz = rgb_to_xyz(COLOR_SPACES["srgb"])
    if space.adapt and space.white != D65:
        to_xyz = bradford(D65, space.white) @ to_xyz
    return np.linalg.solve(rgb_to_xyz(space), to_xyz)
