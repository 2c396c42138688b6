"""The main job of ``make demo``: the sample scene through every camera model.

Renders :mod:`imgform_rs.scene` through

1. a pinhole camera, with the vanishing points of the scene's two horizontal
   edge directions and the horizon marked on a wider canvas;
2. a thin-lens camera focused on the middle box (depth of field);
3. a barrel-distorting lens (ray-traced through the lens model), and that
   picture undistorted again;
4. a lens with lateral chromatic aberration, and its correction; and the
   through-focus PSFs of a lens with and without spherical aberration;
5. a Bayer sensor: the pinhole picture mosaiced and demosaiced by every
   method, with each method's CPSNR;
6. the scene rendered spectrally (upsampled to reflectances under D65, an
   (H, W, L) radiance) and recorded by a :class:`~imgform_rs.spectral.SpectralCamera`,
   written as a DNG with its fitted colour matrix and developed back through
   LibRaw's decoder and our pipeline by every demosaicer; the ColorChecker
   through the same camera beside the chart, each patch's CIEDE2000 written
   on it (``colorchecker.png``); the lecture's Figure 4a for three glasses
   (``focal_shift.png``) and the scene through a dispersive singlet
   (``dispersion_ca.png``: achromatic, longitudinal, longitudinal + lateral);
   these need colour-science (``imgform-rs[spectral]``) and are skipped,
   saying so, without it;
7. when the shared sample data sit beside the checkout, the Prokudin-Gorskii
   plate aligned and one real camera raw developed;
8. a plenoptic camera's light field (a grid of sub-aperture views),
   refocused after capture on the near, middle and far box (a focal stack
   as PNGs and an animated GIF), and with a smaller synthetic aperture;
9. colour film (:mod:`imgform_rs.film`): the pinhole picture printed from
   the generic negative at -2, 0 and +2 EV, as a slide and as a
   black-and-white print (``film.png``);
10. Prokudin-Gorskii's camera (:mod:`imgform_rs.three_colour`): the pinhole
    picture photographed through three filters onto one plate, aligned and
    colourised, beside the scene (``three_colour.png``);

and writes PNGs under the output folder.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from . import scene
from . import spectral as sp
from ._png import write_png
from ._spectral_figures import (
    Lens,
    colorchecker_figure,
    demo_camera,
    dispersion_crops,
    focal_shift_plot,
    srgb_decode,
)
from .aberration import pupil_psf
from .align import colorize_plate
from .camera import Camera, vanishing_line, vanishing_point
from .cfa import mosaic
from .chromatic import add_lateral_ca, correct_lateral_ca
from .demosaic import BAYER_DEMOSAIC_METHODS, demosaic
from .develop import develop
from .lightfield import focal_stack, refocus, render_light_field, view_disparity
from .optics import circle_of_confusion, field_of_view, hyperfocal_distance, render_defocus
from .remap import undistort_image

WIDTH, HEIGHT = 640, 480
# A full-frame camera (36 mm wide sensor) with a fast 50 mm lens focused on
# the near (red) box, so the middle and far boxes blur more and more.
FOCAL_MM, F_NUMBER, SENSOR_MM = 50.0, 1.2, 36.0
PIXEL_PITCH_MM = SENSOR_MM / WIDTH
FOCUS_MM = 6300.0
BARREL = (-0.7, 0.25, 0.0, 0.0, 0.0)
EYE, TARGET = (4.5, 1.6, -3.0), (-0.5, 0.9, 9.0)
# Sky has no depth; put it far enough to be "at infinity" for the lens.
SKY_DEPTH_MM = 1e7
# 2 x 2 rays per pixel smooth the boxes' and the horizon's edges; the ground's
# texture needs no more, since each ray averages it over its own footprint.
SUPERSAMPLE = 2


def _camera(scale: int = 1, dist=None) -> Camera:
    fov = float(field_of_view(FOCAL_MM, SENSOR_MM))
    cam = Camera.from_fov(fov, (HEIGHT * scale, WIDTH * scale), dist=dist)
    return cam.look_at(EYE, TARGET)


def _render(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Supersampled colour (uint8) and z-depth in mm (float32) of the scene."""
    h, w = camera.image_size
    v, u = np.mgrid[0:h, 0:w]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)
    colour, z = scene.render(camera, pixels)
    depth = np.where(np.isfinite(z), z * 1000.0, SKY_DEPTH_MM)
    s = SUPERSAMPLE
    colour = colour.reshape(h // s, s, w // s, s, 3).mean(axis=(1, 3))
    depth = depth.reshape(h // s, s, w // s, s).min(axis=(1, 3))
    return (np.clip(colour, 0, 1) * 255 + 0.5).astype(np.uint8), depth.astype(np.float32)


def _draw_line(canvas: np.ndarray, p0, p1, colour, width: int = 1) -> None:
    """Draw a segment by dense sampling, clipped to the canvas."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    n = int(np.hypot(*(p1 - p0)) * 2) + 2
    pts = p0 + np.linspace(0, 1, n)[:, None] * (p1 - p0)
    for dy in range(-(width // 2), width - width // 2):
        for dx in range(-(width // 2), width - width // 2):
            uv = np.round(pts + [dx, dy]).astype(int)
            ok = (uv[:, 0] >= 0) & (uv[:, 0] < canvas.shape[1])
            ok &= (uv[:, 1] >= 0) & (uv[:, 1] < canvas.shape[0])
            canvas[uv[ok, 1], uv[ok, 0]] = colour


def _draw_disc(canvas: np.ndarray, centre, radius: float, colour) -> None:
    v, u = np.ogrid[: canvas.shape[0], : canvas.shape[1]]
    canvas[(u - centre[0]) ** 2 + (v - centre[1]) ** 2 <= radius**2] = colour


def _vanishing_canvas(camera: Camera, image: np.ndarray) -> np.ndarray:
    """The picture on a wider canvas with box edges extended to their
    vanishing points and the horizon drawn across."""
    vps = [vanishing_point(camera, d) for d in ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))]
    finite = [vp.point for vp in vps if not vp.at_infinity]
    lo = np.minimum(np.min(finite, axis=0), 0) - 40
    hi = np.maximum(np.max(finite, axis=0), [WIDTH, HEIGHT]) + 40
    scale = min(1.0, 1600 / (hi[0] - lo[0]))
    size = np.ceil((hi - lo) * scale).astype(int)
    canvas = np.full((size[1], size[0], 3), 245, np.uint8)
    small = image[:: max(1, round(1 / scale)), :: max(1, round(1 / scale))]
    off = np.round(-lo * scale).astype(int)
    canvas[off[1] : off[1] + small.shape[0], off[0] : off[0] + small.shape[1]] = small

    def to_canvas(p):
        return (np.asarray(p) - lo) * scale

    colours = [(200, 30, 30), (30, 90, 200)]
    for vp, colour in zip(vps, colours, strict=True):
        for box in scene.BOXES:
            for corner in _box_corners(box):
                start = camera.project(corner)
                if np.isfinite(start).all():
                    _draw_line(canvas, to_canvas(start), to_canvas(vp.point), colour)
        _draw_disc(canvas, to_canvas(vp.point), 6, colour)
    a, b, c = vanishing_line(camera, (0.0, 1.0, 0.0))
    us = np.array([lo[0], hi[0]])
    vs = -(a * us + c) / b
    _draw_line(canvas, to_canvas([us[0], vs[0]]), to_canvas([us[1], vs[1]]), (20, 140, 40), 2)
    return canvas


def _box_corners(box: scene.Box) -> list[tuple[float, float, float]]:
    (x0, y0, z0), (x1, y1, z1) = box.lo, box.hi
    return [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]


def _timed(label: str, log: list[str], fn: Callable[[], np.ndarray]) -> np.ndarray:
    start = time.perf_counter()
    result = fn()
    log.append(f"{label:<34s} {1e3 * (time.perf_counter() - start):8.1f} ms")
    return result


def cpsnr(reference: np.ndarray, estimate: np.ndarray, border: int = 10) -> float:
    """Colour PSNR in dB of 8-bit images over all three channels, ``border``
    pixels cropped (the demosaicing literature's protocol)."""
    crop = (slice(border, -border), slice(border, -border))
    err = reference[crop].astype(np.float64) - estimate[crop]
    return float(10 * np.log10(255.0**2 / max(np.mean(err**2), 1e-12)))


def _demosaic_strip(image: np.ndarray, log: Callable[[str], None]) -> np.ndarray:
    """Each method's reconstruction of a detailed crop, magnified, side by side."""
    raw = mosaic(image, "RGGB")
    # The far checkerboard near the horizon: fine detail where methods differ most.
    y, x, h, w = 200, 440, 90, 120
    tiles = []
    for method in BAYER_DEMOSAIC_METHODS:
        start = time.perf_counter()
        rgb = demosaic(raw, "RGGB", method)
        ms = 1e3 * (time.perf_counter() - start)
        log(f"demosaic {method:<20s} {ms:8.1f} ms   CPSNR {cpsnr(image, rgb):6.2f} dB")
        tiles.append(rgb[y : y + h, x : x + w].repeat(2, axis=0).repeat(2, axis=1))
        tiles.append(np.full((2 * h, 4, 3), 255, np.uint8))
    return np.hstack(tiles[:-1])


def _aberration_strip() -> np.ndarray:
    """Through-focus PSFs, defocus W020 from -2 to 2 waves left to right: the
    top row without aberration (mirror-symmetric about the middle, paraxial
    focus), the bottom row with one wave of spherical aberration (sharpest at
    W020 = -1, blurred differently on either side). One intensity scale for
    all, square-rooted so the rings show."""
    optics = {"n_pixels": 41, "pixel_pitch": 0.55e-3, "f_number": 2.0, "wavelength": 0.55e-3}
    rows = [
        [pupil_psf(defocus=d, spherical=w040, **optics) for d in np.linspace(-2.0, 2.0, 9)]
        for w040 in (0.0, 1.0)
    ]
    peak = max(float(p.max()) for row in rows for p in row)
    gap = np.full((82, 4), 255, np.uint8)
    strips = []
    for row in rows:
        tiles = [np.sqrt(p / peak) * 255 for p in row]
        tiles = [t.astype(np.uint8).repeat(2, axis=0).repeat(2, axis=1) for t in tiles]
        strips.append(np.hstack([x for t in tiles for x in (t, gap)][:-1]))
        strips.append(np.full((4, strips[-1].shape[1]), 255, np.uint8))
    return np.vstack(strips[:-1])


# The scene's light: D65 with a white of 300 cd/m², a bright overcast day.
SCENE_LUMINANCE = 300.0
# The raw round trip's exposure puts a white reflector's brightest channel at
# 80 % of saturation (margin for noise); develop lifts it back by log2(1/0.8).
RAW_TARGET = 0.8


def _raw_round_trip(out: Path, image: np.ndarray, log: Callable[[str], None]) -> list[Path]:
    """The scene rendered spectrally and recorded by the demo's spectral
    camera, written as a DNG with its fitted colour matrix, then decoded by
    LibRaw and developed by us with each demosaicer."""
    cam = demo_camera()
    wl = cam.wavelengths
    light = sp.luminance_scale(sp.illuminant("D65", wl), wl, SCENE_LUMINANCE)
    start = time.perf_counter()
    radiance = (sp.rgb_to_reflectance(srgb_decode(image), wl) * light).astype(np.float32)
    t = sp.auto_exposure(cam.camera_rates(light), cam.sensor, target=RAW_TARGET, percentile=100)
    raw = cam.capture(radiance, exposure_time=t, seed=1)
    ms = 1e3 * (time.perf_counter() - start)
    log(
        f"spectral scene {radiance.shape[1]}x{radiance.shape[0]}x{radiance.shape[2]} "
        f"(380-780 nm) -> 14-bit raw ({1e3 * t:.2f} ms at f/{cam.f_number:g}) in {ms:.0f} ms"
    )
    dng = out / "scene.dng"
    sp.write_dng(dng, raw, cam, sp.characterise(cam))
    written = [dng]
    for method in BAYER_DEMOSAIC_METHODS:
        start = time.perf_counter()
        rgb = develop(dng, demosaic=method, exposure=float(np.log2(1 / RAW_TARGET)))
        ms = 1e3 * (time.perf_counter() - start)
        log(f"develop scene.dng, {method:<20s} {ms:8.1f} ms   CPSNR {cpsnr(image, rgb):6.2f} dB")
    written.append(write_png(out / "scene_developed.png", rgb))
    return written


# The aberration crops' lens: the demo's 50 mm focused on the near box, at
# f/2.8 so that the chromatic blur shows beside the depth blur (400 nm focuses
# 1.33 mm short: a 0.47 mm disc, ~8 px); the crop is the near box's edge off
# the axis, where lateral colour splits edges too.
CA_F_NUMBER = 2.8
CA_CROP = (slice(240, 360), slice(464, 624))


def _needs_colour_science(what: str, log: Callable[[str], None]) -> bool:
    """Whether colour-science (the spectral data sets) is installed; the demo
    skips the figures that need it, saying so, rather than fail without it."""
    import importlib.util

    if importlib.util.find_spec("colour") is None:
        log(f"{what} skipped: they need colour-science (pip install imgform-rs[spectral])")
        return False
    return True


def _spectral(
    out: Path, image: np.ndarray, depth: np.ndarray, log: Callable[[str], None]
) -> list[Path]:
    """The spectral camera's raw round trip of the scene, the ColorChecker,
    Figure 4a and the dispersion crops; nothing without colour-science."""
    if not _needs_colour_science("spectral figures", log):
        return []
    written = _raw_round_trip(out, image, log)
    chart, dng = colorchecker_figure(out, log)
    written += [dng, write_png(out / "colorchecker.png", chart)]
    written.append(write_png(out / "focal_shift.png", focal_shift_plot()))
    lens = Lens(FOCAL_MM, CA_F_NUMBER, FOCUS_MM, PIXEL_PITCH_MM)
    crops = dispersion_crops(srgb_decode(image), depth, lens, CA_CROP, log)
    written.append(write_png(out / "dispersion_ca.png", crops))
    return written


# The light field: a 7x7 grid of views 6 cm apart, each 256x192 pixels (a
# plenoptic camera trades resolution for views), so its 49 views cost about
# twice the rays of the 2x supersampled pinhole picture. Disparities are
# then ~3.2, 2.0 and 1.1 px per view for the near, middle and far box.
LF_GRID, LF_BASELINE, LF_SIZE = (7, 7), 0.06, (192, 256)


def _light_field(out: Path, log: Callable[[str], None]) -> list[Path]:
    """Render the light field, refocus it on each box, write the focal
    stack (PNGs and a GIF sweeping the focus) and a small-aperture frame."""
    import imageio.v3 as iio

    fov = float(field_of_view(FOCAL_MM, SENSOR_MM))
    camera = Camera.from_fov(fov, LF_SIZE).look_at(EYE, TARGET)
    start = time.perf_counter()
    lf = render_light_field(scene, camera=camera, baseline=LF_BASELINE, grid=LF_GRID)
    render_ms = 1e3 * (time.perf_counter() - start)
    centres = [(np.array(b.lo) + np.array(b.hi)) / 2 for b in scene.BOXES]
    depths = [float((camera.R @ c + camera.t)[2]) for c in centres]
    alphas = [float(view_disparity(camera, LF_BASELINE, z)) for z in depths]
    start = time.perf_counter()
    stack = focal_stack(lf, alphas)
    refocus_ms = 1e3 * (time.perf_counter() - start) / len(alphas)
    log(
        f"light field {LF_GRID[0]}x{LF_GRID[1]} x {LF_SIZE[1]}x{LF_SIZE[0]} rendered in "
        f"{render_ms:.0f} ms; refocus {refocus_ms:.1f} ms per frame at alpha "
        + ", ".join(f"{a:.2f}" for a in alphas)
        + " px/view (near, middle, far box)"
    )
    written = [
        write_png(out / f"lightfield_focus_{name}.png", frame)
        for name, frame in zip(("near", "middle", "far"), stack, strict=True)
    ]
    written.append(
        write_png(out / "lightfield_near_small_aperture.png", refocus(lf, alphas[0], aperture=1))
    )
    # A focus sweep from the far box to the near one and back, for the GIF.
    sweep = np.linspace(alphas[2], alphas[0], 10)
    frames = focal_stack(lf, np.concatenate([sweep, sweep[-2:0:-1]]))
    gif = out / "lightfield_focal_stack.gif"
    iio.imwrite(gif, frames, duration=120, loop=0)
    written.append(gif)
    return written


def _film_strip(image: np.ndarray, log: Callable[[str], None]) -> np.ndarray:
    """The scene, then as printed from the generic colour negative at -2, 0
    and +2 EV (a lab balancing each print), a slide and a black-and-white
    print, side by side; 16-bit sRGB."""
    from . import film

    linear = srgb_decode(image)
    panels = [image.astype(np.float32) / 255.0]
    runs = [
        ("generic-negative", -2.0),
        ("generic-negative", 0.0),
        ("generic-negative", 2.0),
        ("generic-reversal", 0.0),
        ("generic-bw-pan", 0.0),
    ]
    for stock, ev in runs:
        start = time.perf_counter()
        panels.append(film.simulate(linear, stock, exposure_ev=ev))
        ms = 1e3 * (time.perf_counter() - start)
        log(f"film.simulate {stock} {ev:+g} EV: {image.shape[1]}x{image.shape[0]} in {ms:.0f} ms")
    gap = np.ones((image.shape[0], 4, 3), np.float32)
    strip = np.concatenate([p for panel in panels for p in (panel, gap)][:-1], axis=1)
    return np.floor(np.clip(strip, 0, 1) * 65535 + 0.5).astype(np.uint16)


def _three_colour_figure(image: np.ndarray, log: Callable[[str], None]) -> np.ndarray:
    """The simulated plate (B, G, R from the top), its colourised result and
    the scene's own rendering of that area, side by side; 8-bit sRGB."""
    from . import three_colour

    v = image[::2, ::2].astype(np.float32) / 255.0
    linear = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    start = time.perf_counter()
    run = three_colour.experiment(linear, seed=1)
    ms = 1e3 * (time.perf_counter() - start)
    for line in [f"three-colour experiment in {ms:.0f} ms", *run.comparison.report().splitlines()]:
        log(line)

    def encode(rgb: np.ndarray) -> np.ndarray:
        c = np.clip(rgb, 0.0, 1.0)
        c = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
        return np.floor(c * 255 + 0.5).astype(np.uint8)

    # The scan's 0-4 density range, levelled to the plate's own as a scanner would.
    lo, hi = np.percentile(run.plate.image, (0.1, 99.9))
    grey = np.clip((run.plate.image - lo) / (hi - lo), 0.0, 1.0)
    plate = np.floor(grey * 255 + 0.5).astype(np.uint8)[..., None].repeat(3, axis=-1)
    right = [encode(run.comparison.rgb), encode(run.comparison.scene)]
    width = max(p.shape[1] for p in right)
    column = np.full((plate.shape[0], width, 3), 255, np.uint8)
    column[: right[0].shape[0], : right[0].shape[1]] = right[0]
    top = right[0].shape[0] + 8
    column[top : top + right[1].shape[0], : right[1].shape[1]] = right[1]
    return np.hstack([plate, np.full((plate.shape[0], 8, 3), 255, np.uint8), column])


def run(
    out: Path,
    log: Callable[[str], None] = print,
    plate: Path | None = None,
    camera_raw: Path | None = None,
    *,
    overwrite: bool = False,
) -> list[Path]:
    """Render every picture of the demo into ``out`` and return their paths;
    colourise ``plate`` (a Prokudin-Gorskii scan) and develop ``camera_raw``
    too when given.

    The pictures are made in a hidden folder inside ``out`` and moved into
    ``out`` at the end, all or none: a FileExistsError names the files that
    are there already, unless ``overwrite``."""
    if not overwrite and (out / "pinhole.png").exists():  # a demo ran here before
        raise FileExistsError(f"{out / 'pinhole.png'} exists (use --overwrite to replace it)")
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix=".demo-", dir=out))
    try:
        made = _render_all(work, log, plate, camera_raw)
        files = sorted(work.iterdir())
        there = [str(out / f.name) for f in files if (out / f.name).exists()]
        if there and not overwrite:
            raise FileExistsError(
                f"{', '.join(there)} exist (use --overwrite to replace them); nothing was written"
            )
        for path in files:
            os.replace(path, out / path.name)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return [out / path.name for path in made]


def _render_all(
    out: Path, log: Callable[[str], None], plate: Path | None, camera_raw: Path | None
) -> list[Path]:
    """The pictures of :func:`run`, written into ``out``."""
    lines: list[str] = []
    s = SUPERSAMPLE
    hi_res = _camera(s)
    camera = _camera()
    pinhole, depth = _timed("ray-cast pinhole scene", lines, lambda: _render(hi_res))
    written = [write_png(out / "pinhole.png", pinhole)]
    written.append(write_png(out / "vanishing_points.png", _vanishing_canvas(camera, pinhole)))

    dof = _timed(
        "render_defocus (thin lens)",
        lines,
        lambda: render_defocus(
            pinhole,
            depth,
            f=FOCAL_MM,
            N=F_NUMBER,
            focus_distance=FOCUS_MM,
            pixel_pitch=PIXEL_PITCH_MM,
        ),
    )
    written.append(write_png(out / "thin_lens_dof.png", dof))
    coc_px = circle_of_confusion(FOCAL_MM, F_NUMBER, FOCUS_MM, depth) / PIXEL_PITCH_MM
    depth_vis = np.clip(coc_px / max(float(coc_px.max()), 1e-9) * 255, 0, 255)
    written.append(write_png(out / "circle_of_confusion.png", depth_vis.astype(np.uint8)))

    barrel_cam = _camera(s, dist=BARREL)
    barrel, _ = _timed("ray-cast through barrel lens", lines, lambda: _render(barrel_cam))
    written.append(write_png(out / "barrel_lens.png", barrel))
    lens = _camera(dist=BARREL)
    fixed = _timed("undistort_image (bilinear)", lines, lambda: undistort_image(barrel, lens))
    written.append(write_png(out / "barrel_undistorted.png", fixed))

    ca = _timed("add_lateral_ca", lines, lambda: add_lateral_ca(pinhole, 1.008, 0.992))
    written.append(write_png(out / "lateral_ca.png", ca))
    written.append(
        write_png(out / "lateral_ca_corrected.png", correct_lateral_ca(ca, 1.008, 0.992))
    )
    written.append(write_png(out / "spherical_aberration.png", _aberration_strip()))
    hyper = float(hyperfocal_distance(FOCAL_MM, F_NUMBER, 0.03))
    log(
        f"scene {WIDTH}x{HEIGHT}, f = {FOCAL_MM:g} mm, N = {F_NUMBER:g}, "
        f"focus {FOCUS_MM / 1000:g} m, hyperfocal {hyper / 1000:.1f} m (c = 0.03 mm), "
        f"largest blur {float(coc_px.max()):.1f} px, horizontal fov "
        f"{math.degrees(float(field_of_view(FOCAL_MM, SENSOR_MM))):.1f} deg"
    )
    for line in lines:
        log(line)
    strip = _demosaic_strip(pinhole, log)
    written.append(write_png(out / "demosaic_methods.png", strip))
    written += _spectral(out, pinhole, depth, log)
    written += _light_field(out, log)
    if _needs_colour_science("film and three-colour figures", log):
        written.append(write_png(out / "film.png", _film_strip(pinhole, log)))
        written.append(write_png(out / "three_colour.png", _three_colour_figure(pinhole, log)))
    if camera_raw is not None:
        start = time.perf_counter()
        rgb = develop(camera_raw)
        ms = 1e3 * (time.perf_counter() - start)
        log(f"develop {camera_raw.name}: {rgb.shape[1]}x{rgb.shape[0]} in {ms:.0f} ms")
        written.append(write_png(out / f"{camera_raw.stem}.png", rgb))
    if plate is not None:
        start = time.perf_counter()
        # Onto blue, the frame in which the plates' shifts are usually published.
        rgb, shifts = colorize_plate(plate, reference="b")
        ms = 1e3 * (time.perf_counter() - start)
        moves = ", ".join(f"{c.upper()} {tuple(v)}" for c, v in shifts.items())
        log(f"colorize_plate {plate.name}: {moves} in {ms:.0f} ms")
        written.append(write_png(out / f"{plate.stem}_colour.png", rgb))
    return written
