"""Lens corrections from the lensfun database: distortion, lateral chromatic
aberration (TCA) and vignetting.

The database and the interpolation of its coefficients between calibrated
focal lengths, apertures and distances are lensfun's, through lensfunpy (the
``lens`` extra: ``pip install imgform-rs[lens]``; its wheel bundles liblensfun
0.3.4 and the database). The corrections themselves run in Rust with
lensfun's models and coordinate conventions: positions agree with lensfunpy's
``apply_subpixel_geometry_distortion`` and vignetting gains with its
``apply_color_modification`` (tested over a sample of real database entries).

What lensfun corrects and how:

- distortion (``poly3``, ``poly5``, ``ptlens``) and TCA (``linear``,
  ``poly3``) together, each output channel read once from the source at its
  own distorted and magnified position (no double resampling);
- vignetting (``pa``) as a gain on *linear* values (:func:`develop` applies it
  to the raw photosites, above black, before anything else);
- the image is mapped onto the calibration sensor through the diagonal (the
  crop factors), the sensor's aspect ratio and the profile's centre offset;
  the image keeps its size (no automatic zoom: lensfun's ``scale=1``), so
  corrected pincushion distortion leaves a border of ``fill`` at the edges,
  and corrected barrel distortion, which reads inwards, pushes the
  capture's outermost pixels out of the frame.

Geometry conversions (fisheye to rectilinear) are not done: a fisheye
profile's distortion is corrected within the fisheye projection, as lensfun
does without ``LF_MODIFY_GEOMETRY``.

Matching (:func:`match_lens`) follows lensfun's rules: a camera's maker and
model and a lens name are searched strictly (every word of the name must be
in the entry), then loosely; lensfun drops lenses calibrated on a sensor
smaller than the camera's (crop factor more than 4 % larger) because the
image would reach beyond the calibrated circle. Several candidates: the one
lensfun scores highest, ties broken by name; a loose search is only accepted
with a unique best score. Everything is reported in :class:`LensMatch`;
nothing found is not an error.
"""

from __future__ import annotations

import functools
import glob
import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _native, _samples
from ._arrays import is_int, real
from .remap import ImageT, Interpolation

__all__ = ["LensMatch", "LensProfile", "find_profile", "lens_database", "match_lens"]

# lensfun's defaults: a lens without <aspect-ratio> was calibrated on a 3:2
# sensor; an unknown focus distance is "far" (lensfunpy's default 1000 m).
_DEFAULT_ASPECT = 1.5
_FAR = 1000.0
# lensfun's crop-factor rule (lens.cpp, _lf_lens_compare_score): a lens
# calibrated on a sensor whose crop factor exceeds the camera's by more than
# 1 / 0.96 does not cover the camera's frame.
_CROP_TOLERANCE = 0.96
# A focal length this far outside a lens's range is a wrong match or wrong
# metadata, not an extrapolation worth applying.
_FOCAL_TOLERANCE = 0.02


def _lensfunpy() -> Any:
    try:
        import lensfunpy
    except ImportError as e:
        raise ImportError("lens corrections need lensfunpy: pip install imgform-rs[lens]") from e
    return lensfunpy


@functools.lru_cache(maxsize=1)
def lens_database() -> Any:
    """lensfunpy's bundled database (``lensfunpy.Database``), loaded once.

    Only the database in lensfunpy's wheel is read, not a system copy, so
    that the profile fields lensfunpy does not expose (the calibration
    sensor's aspect ratio) are read from the same files.
    """
    return _lensfunpy().Database(load_common=False, load_bundled=True)


@functools.lru_cache(maxsize=1)
def _aspect_ratios() -> dict[tuple[str, str, float], float]:
    """``<aspect-ratio>`` of every lens in the bundled database, keyed by
    maker, model and crop factor: lensfunpy does not expose it, and it
    scales every coordinate of a lens calibrated on a 4:3 or 16:9 sensor."""
    root = os.path.join(os.path.dirname(_lensfunpy().__file__), "db_files")
    ratios = {}
    for path in sorted(glob.glob(os.path.join(root, "*.xml"))):
        for lens in ET.parse(path).getroot().iter("lens"):
            key = (
                _plain(lens, "maker"),
                _plain(lens, "model"),
                _crop_key(lens.findtext("cropfactor")),
            )
            ratios[key] = _ratio(lens.findtext("aspect-ratio"))
    return ratios


def _plain(element: ET.Element, tag: str) -> str:
    """The text of the first ``tag`` child without a ``lang`` attribute
    (the name lensfun and lensfunpy report)."""
    for child in element.findall(tag):
        if "lang" not in child.attrib:
            return child.text or ""
    return ""


def _crop_key(value: Any) -> float:
    return round(float(value or 0.0), 3)


def _ratio(text: str | None) -> float:
    """lensfun's parsing: ``"4:3"`` or a plain number."""
    if not text:
        return _DEFAULT_ASPECT
    num, _, den = text.partition(":")
    return float(num) / float(den) if den else float(num)


def _model(calib: Any) -> tuple[str, tuple[float, ...]] | None:
    """An interpolated lensfunpy calibration as (model name, terms)."""
    if calib is None:
        return None
    name = calib.model.name.lower()
    if name == "none":
        return None
    return name, tuple(float(t) for t in calib.terms)


@dataclass(frozen=True)
class LensProfile:
    """The corrections of one lens on one camera at one setting.

    Attributes
    ----------
    lens, camera : str
        The database entries, ``"maker / model"``.
    crop_factor : float
        The camera's crop factor.
    calibration_crop : float
        The crop factor of the sensor the lens was calibrated on.
    aspect_ratio : float
        Long over short side of that sensor.
    center : (float, float)
        The profile's optical-centre offset (lensfun's normalised units).
    focal_length, aperture, distance : float
        The setting the coefficients were interpolated for (mm, f-number,
        metres; aperture 0 when unknown).
    distortion, tca : (str, tuple of float) or None
        Model name and terms in lensfun's order.
    vignetting : (float, float, float) or None
        ``k1, k2, k3`` of the ``pa`` model.
    """

    lens: str
    camera: str
    crop_factor: float
    calibration_crop: float
    aspect_ratio: float
    center: tuple[float, float]
    focal_length: float
    aperture: float
    distance: float
    distortion: tuple[str, tuple[float, ...]] | None
    tca: tuple[str, tuple[float, ...]] | None
    vignetting: tuple[float, float, float] | None

    @property
    def corrects_geometry(self) -> bool:
        return self.distortion is not None or self.tca is not None

    def native(self, width: int, height: int) -> Any:
        """The Rust correction for images of ``width x height`` pixels: the
        same object for equal profiles and sizes, among the last few asked
        for, so that the grid of source positions it builds on first use
        (~4 ms and ~7 MB at 24 MP) serves every later image of a batch or
        sequence from that lens at that setting (a profile built with
        unhashable terms, lists, gets a new one each time)."""
        if not (is_int(width) and is_int(height) and min(width, height) >= 1):
            # int(3.7) would quietly size the grid for another image.
            raise ValueError(f"width and height must be ints >= 1, got {width!r} x {height!r}")
        width, height = int(width), int(height)
        try:
            hash(self)
        except TypeError:
            return _native_correction(self, width, height)
        return _kept_correction(self, width, height)

    def positions(self, width: int, height: int) -> npt.NDArray[np.float64]:
        """Where each corrected pixel is read from in the uncorrected image.

        Returns
        -------
        ndarray, float64, shape (height, width, 3, 2)
            ``(x, y)`` in pixels per channel R, G, B: the layout of
            lensfunpy's ``apply_subpixel_geometry_distortion``. These are
            the positions :meth:`correct` samples at: exact on a grid of at
            most 16 px, bilinearly interpolated in between to within
            0.002 px of the exact ones.
        """
        return self.native(width, height).positions()

    def correct(
        self,
        image: ImageT,
        *,
        vignetting: bool = True,
        geometry: bool = True,
        interpolation: Interpolation = "bilinear",
        fill: float = 0,
        out: ImageT | None = None,
    ) -> ImageT:
        """Correct an RGB image taken with this lens at this setting.

        Parameters
        ----------
        image : ndarray (H, W, 3), uint8, uint16 or float32
            *Linear* values when ``vignetting`` is on (the gain describes
            light, not encoded values).
        vignetting, geometry : bool
            Which corrections to apply (those the profile has).
        interpolation : {"bilinear", "bicubic"}
        fill : float
            Value read outside the source (the border pincushion correction
            leaves); finite, held exactly by the dtype, as in
            :func:`imgform_rs.remap`.
        out : ndarray, optional
            Where to write the result, returned instead of a new array: the
            image's shape and dtype, C-contiguous, writeable, sharing no
            memory with ``image``. Reusing one buffer over many images of one
            size saves the page faults and the OS's zeroing of a fresh output.

        Returns
        -------
        ndarray
            Same shape and dtype (``out`` if given); integer values clamp to
            the type's range.

        Examples
        --------
        >>> p = LensProfile("test", "test", 1.5, 1.5, 1.5, (0.0, 0.0), 20.0, 4.0, 1000.0,
        ...                 ("poly3", (-0.05,)), None, (-0.3, 0.0, 0.0))
        >>> img = np.ones((40, 60, 3), np.float32)
        >>> out = p.correct(img, geometry=False)
        >>> bool(out[0, 0, 0] > 1.0), round(float(out[20, 30, 0]), 3)  # corner, near centre
        (True, 1.0)
        """
        h, w = np.shape(image)[:2]
        devignette = vignetting and self.vignetting is not None
        fill_value = real(fill, "fill")
        if geometry and self.corrects_geometry:
            # One pass: each sample is read at its position and multiplied
            # by the vignetting gain there.
            native = self.native(w, h)
            return native.correct_geometry(image, interpolation, fill_value, devignette, out=out)
        # Vignetting alone, or nothing to do: the devignetting pass, with a
        # gain of 1 for nothing, so the result is a new array (or ``out``)
        # of an image checked as every other path checks it.
        plain = self if devignette else replace(self, vignetting=None)
        result = plain.native(w, h).devignette(image, np.zeros((1, 1)))
        return result if out is None else _samples.fill_out(out, result, np.asarray(image))

    def describe(self) -> str:
        """One line: the entries, the setting and the models applied."""
        models = [
            f"distortion {self.distortion[0]}" if self.distortion else "",
            f"TCA {self.tca[0]}" if self.tca else "",
            "vignetting pa" if self.vignetting else "",
        ]
        applied = ", ".join(m for m in models if m) or "nothing (no calibration at this setting)"
        setting = f"{self.focal_length:g} mm"
        if self.aperture:
            setting += f" f/{self.aperture:g}"
        return f"{self.lens} on {self.camera} at {setting}: {applied}"


def _native_correction(profile: LensProfile, width: int, height: int) -> Any:
    """The Rust correction of ``profile`` for images of ``width x height``."""
    dist = profile.distortion or ("none", ())
    tca = profile.tca or ("none", ())
    return _native.NativeLensCorrection(
        width,
        height,
        profile.crop_factor,
        profile.calibration_crop,
        profile.aspect_ratio,
        profile.center,
        dist[0],
        list(dist[1]),
        tca[0],
        list(tca[1]),
        profile.vignetting,
    )


# The four profiles and sizes asked for last: a profile is a frozen
# dataclass, so equal ones hash alike.
_kept_correction = functools.lru_cache(maxsize=4)(_native_correction)


@dataclass(frozen=True)
class LensMatch:
    """What :func:`match_lens` looked for, found and chose.

    Attributes
    ----------
    profile : LensProfile or None
        ``None`` when nothing is applied; ``reason`` says why.
    camera, lens : str
        The names searched for (from the file or the overrides).
    candidates : tuple of str
        Lens entries lensfun returned, best first (the first is the chosen one).
    reason : str
        Why there is no profile, or notes on the one chosen ("loose match",
        "vignetting skipped: aperture unknown").
    """

    profile: LensProfile | None
    camera: str = ""
    lens: str = ""
    candidates: tuple[str, ...] = field(default_factory=tuple)
    reason: str = ""

    def report(self) -> str:
        """One line for a per-file report."""
        if self.profile is None:
            return f"lens correction: none ({self.reason})"
        extra = f" [{self.reason}]" if self.reason else ""
        more = len(self.candidates) - 1
        alts = f"; {more} other candidate(s): {', '.join(self.candidates[1:4])}" if more > 0 else ""
        return f"lens correction: {self.profile.describe()}{extra}{alts}"


def _name(entry: Any) -> str:
    return f"{entry.maker} / {entry.model}"


def _best(entries: list[Any]) -> list[Any]:
    """lensfun's scores, best first; ties by name so the choice never
    depends on the database's order."""
    return sorted(entries, key=lambda e: (-e.score, e.maker, e.model))


def _maker_model(camera: Any) -> tuple[str, str]:
    """``camera`` as (maker, model): a pair of names, or a model's name."""
    if isinstance(camera, str):
        return "", camera
    if isinstance(camera, (tuple, list)) and len(camera) == 2:
        if all(isinstance(name, str) for name in camera):
            return camera[0], camera[1]
    raise TypeError(f"camera must be a model's name or a (maker, model) pair, got {camera!r}")


def _find_camera(db: Any, maker: str, model: str) -> tuple[Any | None, str]:
    if not (maker or model):
        return None, "the file names no camera"
    name = (maker + " " + model).strip()
    for loose in (False, True):
        found = _best(db.find_cameras(maker or None, model or None, loose_search=loose))
        if not found:
            continue
        if loose and len(found) > 1 and found[0].score == found[1].score:
            return None, _unmatched("camera", name, found)
        return found[0], "loose camera match" if loose else ""
    return None, f"camera {name!r} is not in the lensfun database"


def _unmatched(kind: str, name: str, found: list[Any]) -> str:
    """Why a name that only a loose search found, and more than once, is not
    taken: an unknown model's name reads as several."""
    alike = ", ".join(_name(f) for f in found[:3])
    return f"{kind} {name!r} is not in lensfun; a loose search finds several alike: {alike}"


def _find_lenses(db: Any, camera: Any, lens: str) -> tuple[list[Any], str]:
    for loose in (False, True):
        found = _best(db.find_lenses(camera, None, lens, loose_search=loose))
        found = [f for f in found if camera.crop_factor >= f.crop_factor * _CROP_TOLERANCE]
        if not found:
            continue
        if loose and len(found) > 1 and found[0].score == found[1].score:
            return [], _unmatched("lens", lens, found)
        return found, "loose lens match" if loose else ""
    return [], f"lens {lens!r} is not in the lensfun database for {_name(camera)}"


def _fixed_lens(db: Any, camera: Any) -> tuple[list[Any], str]:
    """A compact camera's own lens: files of fixed-lens cameras rarely name
    it, and lensfun lists it under the camera's private mount. Accepted only
    when that mount holds exactly one lens."""
    found = [f for f in db.find_lenses(camera) if camera.mount in f.mounts]
    if len(found) == 1:
        return found, "the camera's fixed lens"
    return [], "the file names no lens"


def _positive(value: Any, name: str) -> float:
    """A setting given to :func:`find_profile`, or 0 when unknown: None, or
    a number that is not finite and > 0 (a file's 0 for what it did not
    record). A str or another non-number is a TypeError naming it."""
    if value is None:
        return 0.0
    v = real(value, name)
    return v if math.isfinite(v) and v > 0 else 0.0


def find_profile(
    lens: str,
    camera: str | tuple[str, str],
    *,
    focal_length: float,
    aperture: float | None = None,
    distance: float | None = None,
) -> LensMatch:
    """Look a lens up by name for a camera and interpolate its corrections.

    Parameters
    ----------
    lens : str
        Lens name as cameras write it (e.g. ``"EF-S 18-55mm f/3.5-5.6 IS"``).
    camera : str or (maker, model)
        ``"Canon EOS 550D"`` or ``("Canon", "Canon EOS 550D")``.
    focal_length : float
        Millimetres; must lie within the lens's range.
    aperture : float, optional
        f-number; without it vignetting is not corrected.
    distance : float, optional
        Focus distance in metres (default far).

    Returns
    -------
    LensMatch
        With ``profile=None`` and the reason when nothing applies.

    Raises
    ------
    ImportError
        lensfunpy is not installed.
    TypeError
        A setting that is not a real number (or None for the optional ones),
        or a camera that is neither a name nor a (maker, model) pair.
    """
    focal = _positive(focal_length, "focal_length")
    ap = _positive(aperture, "aperture")
    dist = _positive(distance, "distance") or _FAR
    maker, model = _maker_model(camera)
    db = lens_database()
    cam, note = _find_camera(db, maker, model)
    searched = (maker + " " + model).strip()
    if cam is None:
        return LensMatch(None, searched, lens, (), note)
    found, lens_note = _find_lenses(db, cam, lens) if lens else _fixed_lens(db, cam)
    names = tuple(_name(f) for f in found)
    if not found:
        return LensMatch(None, searched, lens, names, lens_note)
    chosen = found[0]
    lo, hi = chosen.min_focal or 0.0, chosen.max_focal or 0.0
    if not focal:
        return LensMatch(None, searched, lens, names, "focal length unknown")
    if lo and hi and not (lo * (1 - _FOCAL_TOLERANCE) <= focal <= hi * (1 + _FOCAL_TOLERANCE)):
        return LensMatch(
            None,
            searched,
            lens,
            names,
            f"focal length {focal:g} mm is outside {_name(chosen)}'s {lo:g}-{hi:g} mm",
        )
    vig = chosen.interpolate_vignetting(focal, ap, dist) if ap else None
    notes = [n for n in (note, lens_note) if n]
    if not ap and chosen.calib_vignetting:
        notes.append("vignetting skipped: aperture unknown")
    elif vig is None and chosen.calib_vignetting:
        at = f" focused at {dist:g} m" if distance else ""
        notes.append(f"vignetting skipped: its calibration does not reach f/{ap:g}{at}")
    key = (chosen.maker, chosen.model, _crop_key(chosen.crop_factor))
    profile = LensProfile(
        lens=_name(chosen),
        camera=_name(cam),
        crop_factor=float(cam.crop_factor),
        calibration_crop=float(chosen.crop_factor),
        aspect_ratio=_aspect_ratios().get(key, _DEFAULT_ASPECT),
        center=(float(chosen.center_x), float(chosen.center_y)),
        focal_length=focal,
        aperture=ap,
        distance=dist,
        distortion=_model(chosen.interpolate_distortion(focal)),
        tca=_model(chosen.interpolate_tca(focal)),
        vignetting=tuple(float(k) for k in vig.terms[:3]) if vig is not None else None,  # type: ignore[arg-type]
    )
    return LensMatch(profile, searched, lens, names, "; ".join(notes))


def match_lens(
    raw: Any,
    *,
    lens: str | None = None,
    camera: str | None = None,
    focal_length: float | None = None,
    aperture: float | None = None,
    distance: float | None = None,
) -> LensMatch:
    """Find the lensfun profile for a raw from its metadata.

    The camera's maker and model come from the file's TIFF tags
    (:attr:`RawImage.make` / ``model``, else LibRaw's), the lens, focal
    length and aperture from LibRaw (:attr:`RawImage.shot`). Each can be
    overridden.

    Parameters
    ----------
    raw : RawImage
    lens, camera : str, optional
        Names to search instead of the file's.
    focal_length, aperture, distance : float, optional
        Setting instead of the file's (distance: metres, default far).

    Returns
    -------
    LensMatch
        ``profile=None`` with the reason when nothing matches (not an error).
    """
    shot = raw.shot
    if camera is not None:
        cam: str | tuple[str, str] = camera
    else:
        cam = (raw.make or shot.make, raw.model or shot.model)
    return find_profile(
        shot.lens if lens is None else lens,
        cam,
        focal_length=shot.focal_length if focal_length is None else focal_length,
        aperture=shot.f_number if aperture is None else aperture,
        distance=distance,
    )
