"""The demo's spectral figures (``imgform demo``; colour-science needed).

- the ColorChecker as a simulated camera records it (spectral radiance, lens,
  sensor with noise, DNG, :func:`imgform_rs.develop`) beside the chart's own
  colours, each patch's CIEDE2000 written on it;
- the lecture's Figure 4a, a thin lens's focal shift against wavelength for
  three glasses, drawn with Pillow (a runtime dependency, unlike matplotlib);
- the demo scene rendered spectrally through a dispersive singlet: crops
  without chromatic aberration, with the longitudinal one and with both.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from . import spectral as sp
from .develop import develop
from .dispersion import Glass, focal_shift, render_dispersion
from .optics import render_defocus

#: Catalogue (n_d, V_d) of three glasses from the crown to the dense flints (Schott).
GLASSES = {
    "N-BK7 (crown)": (1.5168, 64.17),
    "F2 (flint)": (1.62004, 36.37),
    "N-SF11 (dense flint)": (1.78472, 25.68),
}
# Plot colours of the three curves, in GLASSES' order.
CURVE_COLOURS = [(31, 119, 180), (214, 39, 40), (44, 160, 44)]
# The chart is lit by D65 at a white of 300 cd/m² and exposed so that the
# white patch's brightest channel reaches 60 % of saturation: the highlights
# keep a margin for PRNU and shot noise, as a photographer's would.
CHART_LUMINANCE, CHART_TARGET = 300.0, 0.6
# Patch means leave this many pixels of each patch's border out (demosaicing
# blurs the edges with the surround).
PATCH_MARGIN = 8


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear sRGB in [0, 1] (clipped) to 8-bit sRGB (IEC 61966-2-1's curve)."""
    v = np.clip(linear, 0.0, 1.0)
    v = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    return np.floor(v * 255 + 0.5).astype(np.uint8)


def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """8-bit sRGB to linear float32 in [0, 1]."""
    v = encoded.astype(np.float32) / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    return ImageFont.load_default(size=size)


def demo_camera() -> sp.SpectralCamera:
    """The Nikon 5100's measured sensitivities behind an f/4 lens, on the
    default 4 µm sensor with 0.5 % PRNU and 1 e- DSNU."""
    return sp.SpectralCamera(sensor=sp.Sensor(prnu=0.005, dsnu=1.0, pattern_seed=2))


def chart_errors(
    developed: np.ndarray, boxes: list[tuple[slice, slice]], wl: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Per-patch CIEDE2000 of a developed chart (linear sRGB) against the
    chart's own D65 colours (clipped to sRGB, as a developer's output is),
    with the exposure fixed on the white patch's green.

    Returns the errors, the reference colours (24, 3) and the exposure gain.
    """
    spd = sp.illuminant("D65", wl)
    weights = sp.xyz_weights(wl, spd)
    _, refl = sp.colorchecker(wl)
    want = np.clip(refl @ weights @ sp.XYZ_TO_SRGB.T, 0.0, 1.0)
    m = PATCH_MARGIN
    got = np.array([developed[ys, xs][m:-m, m:-m].reshape(-1, 3).mean(0) for ys, xs in boxes])
    gain = float(want[18, 1] / got[18, 1])
    to_xyz = np.linalg.inv(sp.XYZ_TO_SRGB)
    de = sp.delta_e2000(got * gain @ to_xyz.T, want @ to_xyz.T, weights.sum(axis=0))
    return de, want, gain


def colorchecker_figure(out: Path, log: Callable[[str], None]) -> tuple[np.ndarray, Path]:
    """Capture the ColorChecker, write it as ``colorchecker.dng``, develop it
    and draw it beside the reference chart with each patch's CIEDE2000.

    Returns the figure (8-bit sRGB) and the DNG's path.
    """
    cam = demo_camera()
    wl = cam.wavelengths
    light = sp.luminance_scale(sp.illuminant("D65", wl), wl, CHART_LUMINANCE)
    radiance, boxes = sp.colorchecker_scene(wl, light, patch=56, gap=10)
    fit = sp.characterise(cam)
    white_rates = cam.camera_rates(light)
    t = sp.auto_exposure(white_rates, cam.sensor, target=CHART_TARGET, percentile=100.0)
    raw = cam.capture(radiance, exposure_time=t, seed=3)
    dng = out / "colorchecker.dng"
    sp.write_dng(dng, raw, cam, fit)
    developed = develop(dng, tone="linear", bps="float")
    de, want, gain = chart_errors(developed, boxes, wl)
    log(
        f"ColorChecker (D65, {CHART_LUMINANCE:g} cd/m², {1e3 * t:.2f} ms at f/{cam.f_number:g}) "
        f"-> DNG -> develop: CIEDE2000 mean {de.mean():.2f}, max {de.max():.2f}; "
        f"the matrix fit alone {fit.mean_delta_e:.2f} / {fit.max_delta_e:.2f}"
    )
    reference = np.empty_like(developed)
    reference[:] = np.clip(0.03 * sp.reflectance_to_rgb(np.ones(len(wl)), wl), 0, 1)
    for (ys, xs), colour in zip(boxes, want, strict=True):
        reference[ys, xs] = colour
    panels = [srgb_encode(developed * gain), srgb_encode(reference)]
    return _chart_canvas(panels, boxes, want, de, fit), dng


def _chart_canvas(panels, boxes, want, de, fit) -> np.ndarray:
    """The two charts side by side, titled, the developed one annotated."""
    h, w = panels[0].shape[:2]
    pad, top, bottom = 12, 30, 30
    canvas = Image.new("RGB", (3 * pad + 2 * w, top + h + bottom), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    font, small = _font(15), _font(13)
    titles = ["simulated camera -> DNG -> develop", "the chart (colour-science, D65)"]
    for i, (panel, title) in enumerate(zip(panels, titles, strict=True)):
        x0 = pad + i * (w + pad)
        canvas.paste(Image.fromarray(panel), (x0, top))
        draw.text((x0, 8), title, fill=(0, 0, 0), font=font)
    for (ys, xs), colour, err in zip(boxes, want, de, strict=True):
        # Dark text on light patches, white on dark ones (relative luminance).
        ink = (0, 0, 0) if colour @ [0.2126, 0.7152, 0.0722] > 0.25 else (255, 255, 255)
        centre = (pad + (xs.start + xs.stop) / 2, top + (ys.start + ys.stop) / 2)
        draw.text(centre, f"{err:.2f}", fill=ink, font=small, anchor="mm")
    draw.text(
        (pad, top + h + 8),
        f"CIEDE2000 per patch: mean {de.mean():.2f}, max {de.max():.2f} "
        f"(the fitted 3x3 matrix alone: {fit.mean_delta_e:.2f} / {fit.max_delta_e:.2f})",
        fill=(0, 0, 0),
        font=small,
    )
    return np.asarray(canvas)


def focal_shift_plot(f_d: float = 50.0, size: tuple[int, int] = (560, 340)) -> np.ndarray:
    """Figure 4a: ``f(λ) - f_d`` (mm) of a thin lens of each of
    :data:`GLASSES`, 400-700 nm, as an RGB image."""
    wl = np.linspace(400.0, 700.0, 301)
    shifts = [focal_shift(Glass.from_abbe(*nv), wl, f_d) for nv in GLASSES.values()]
    lo = np.floor(min(s.min() for s in shifts) * 2) / 2
    hi = np.ceil(max(s.max() for s in shifts) * 2) / 2
    width, height = size
    left, right, top, bottom = 58, 16, 34, 46
    canvas = Image.new("RGB", size, (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    font = _font(13)

    def to_px(lam: np.ndarray, mm: np.ndarray) -> list[tuple[float, float]]:
        x = left + (lam - 400.0) / 300.0 * (width - left - right)
        y = top + (hi - mm) / (hi - lo) * (height - top - bottom)
        return list(zip(x.tolist(), y.tolist(), strict=True))

    box = (
        *to_px(np.array([400.0]), np.array([hi]))[0],
        *to_px(np.array([700.0]), np.array([lo]))[0],
    )
    draw.rectangle(box, outline=(0, 0, 0))
    for lam in range(400, 701, 50):
        x, y = to_px(np.array([float(lam)]), np.array([lo]))[0]
        draw.line([(x, y), (x, y + 4)], fill=(0, 0, 0))
        draw.text((x, y + 6), str(lam), fill=(0, 0, 0), font=font, anchor="mt")
    for mm in np.arange(lo, hi + 1e-9, 0.5):
        x, y = to_px(np.array([400.0]), np.array([mm]))[0]
        draw.line([(x - 4, y), (x, y)], fill=(0, 0, 0))
        if mm == 0:
            draw.line([(x, y), (box[2], y)], fill=(170, 170, 170))
        draw.text((x - 6, y), f"{mm:+.1f}", fill=(0, 0, 0), font=font, anchor="rm")
    for shift, colour in zip(shifts, CURVE_COLOURS, strict=True):
        draw.line(to_px(wl, shift), fill=colour, width=2)
    draw.text((width / 2, height - 6), "wavelength (nm)", fill=(0, 0, 0), font=font, anchor="mb")
    draw.text(
        (left, 8),
        f"Figure 4a: focal shift f - f_d (mm) of a {f_d:g} mm thin lens, f_d at 587.6 nm",
        fill=(0, 0, 0),
        font=font,
    )
    for i, ((name, (_, v_d)), colour) in enumerate(
        zip(GLASSES.items(), CURVE_COLOURS, strict=True)
    ):
        # Bottom right: the curves all pass above it (normal dispersion).
        y = height - bottom - 62 + 18 * i
        draw.line([(width - 250, y), (width - 228, y)], fill=colour, width=2)
        draw.text((width - 222, y), f"{name}, V_d {v_d:g}", fill=(0, 0, 0), font=font, anchor="lm")
    return np.asarray(canvas)


class Lens(NamedTuple):
    """A thin lens focused on a scene: focal length at the d line (mm),
    f-number, focus distance (mm) and the sensor's pixel pitch (mm)."""

    f_d: float
    N: float
    focus_distance: float
    pixel_pitch: float


#: The glass of the aberration crops: the crown. The flints' red focuses
#: behind the sensor of a 50 mm lens focused at the demo's 6.3 m (their
#: 700 nm focal length exceeds the sensor distance), so no object is sharp in red.
CA_GLASS = "N-BK7 (crown)"
# Pixels around the crop rendered with it: more than the widest blur disc's
# radius (400 nm, 1.3 mm short of focus: ~8 px across at f/2.8 and 56 µm).
CA_MARGIN = 16


def dispersion_crops(
    linear_rgb: np.ndarray,
    depth: np.ndarray,
    lens: Lens,
    crop: tuple[slice, slice],
    log: Callable[[str], None],
) -> np.ndarray:
    """The scene through a singlet of :data:`CA_GLASS`, rendered spectrally
    (400-700 nm every 20 nm: the image upsampled to reflectances, each
    wavelength defocused and magnified by its own focal length, then
    integrated back to sRGB under D65); ``crop`` of an achromatic lens of
    the same focal length, of the singlet's longitudinal aberration alone and
    with its lateral one, side by side and magnified 2x, 8-bit sRGB.

    Lateral aberration magnifies about the image centre, so that panel is
    rendered whole; the other two need only the crop and a margin wider than
    their largest blur (the borders are mirrored).
    """
    wl = sp.wavelengths(400, 700, 20)
    glass = Glass.from_abbe(*GLASSES[CA_GLASS])
    lens_args = dict(f_d=lens.f_d, N=lens.N, focus_distance=lens.focus_distance)
    to_rgb = sp.xyz_weights(wl, sp.illuminant("D65", wl)) @ sp.XYZ_TO_SRGB.T
    ys, xs = crop
    pad = CA_MARGIN
    window = (slice(ys.start - pad, ys.stop + pad), slice(xs.start - pad, xs.stop + pad))
    inner = (slice(pad, -pad), slice(pad, -pad))

    def spectral(region: tuple[slice, slice], lateral: bool) -> np.ndarray:
        cube = sp.rgb_to_reflectance(linear_rgb[region], wl).astype(np.float32)
        out = render_dispersion(
            cube,
            wl,
            glass,
            depth=depth[region],
            pixel_pitch=lens.pixel_pitch,
            lateral=lateral,
            **lens_args,
        )
        return out @ to_rgb

    start = time.perf_counter()
    whole = spectral((slice(None), slice(None)), lateral=True)
    ms = 1e3 * (time.perf_counter() - start)
    panels = [
        render_defocus(
            linear_rgb[window],
            depth[window],
            pixel_pitch=lens.pixel_pitch,
            f=lens.f_d,
            N=lens.N,
            focus_distance=lens.focus_distance,
        )[inner],
        spectral(window, lateral=False)[inner],
        whole[crop],
    ]
    log(
        f"render_dispersion {CA_GLASS}, {len(wl)} wavelengths, "
        f"{linear_rgb.shape[1]}x{linear_rgb.shape[0]}, f/{lens.N:g}: {ms:.0f} ms; focal shift "
        f"{focal_shift(glass, [400.0], lens.f_d)[0]:+.2f} mm at 400 nm, "
        f"{focal_shift(glass, [700.0], lens.f_d)[0]:+.2f} mm at 700 nm"
    )
    tiles = [srgb_encode(p).repeat(2, axis=0).repeat(2, axis=1) for p in panels]
    gap = np.full((tiles[0].shape[0], 6, 3), 255, np.uint8)
    return np.hstack([tiles[0], gap, tiles[1], gap, tiles[2]])
