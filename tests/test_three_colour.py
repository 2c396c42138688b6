"""Prokudin-Gorskii's camera simulated: a ground truth for colorize_plate."""

from __future__ import annotations

import functools
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import output_with_threads
from imgform_rs import colorize_plate, film
from imgform_rs import spectral as sp
from imgform_rs import three_colour as tc

pytest.importorskip("colour")

CAMERA = tc.Camera()


def textured_scene(seed: int = 0, shape: tuple[int, int] = (96, 112)) -> np.ndarray:
    """Linear sRGB in [0.02, 0.9] as photographs are: a shared texture (noise
    blurred by a box of 5 px twice, detail at every scale the alignment's
    pyramid looks at) times smoother colours, so the channels correlate."""
    rng = np.random.default_rng(seed)

    def blurred(channels: int, width: int) -> np.ndarray:
        img = rng.uniform(0.0, 1.0, (shape[0] + 2 * width, shape[1] + 2 * width, channels))
        for axis in (0, 1, 0, 1):
            img = sum(np.roll(img, k, axis=axis) for k in range(-width, width + 1))
        img = img[width:-width, width:-width]
        lo, hi = img.min(axis=(0, 1)), img.max(axis=(0, 1))
        return (img - lo) / (hi - lo)

    rgb = blurred(1, 2) * (0.3 + 0.7 * blurred(3, 8))
    return (0.02 + 0.88 * rgb).astype(np.float32)


def chart_scene(patch: int = 14, gap: int = 6) -> tuple[np.ndarray, list]:
    """The ColorChecker as reflectances (H, W, L) on a 0.03 surround."""
    wl = CAMERA.wavelengths
    refl, boxes = sp.colorchecker_scene(wl, np.ones_like(wl), patch=patch, gap=gap)
    return refl, boxes


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("reference", ["b", "g", "r"])
def test_colorize_plate_recovers_the_simulated_shifts_exactly(seed, reference):
    """Integer camera motion up to 2 % of the scene each way, exposures off
    by up to 0.3 EV, grain on: every shift found is the true one, on a
    spectral Mondrian and on an sRGB photograph-like texture."""
    for scene in (tc.mondrian(seed=seed), textured_scene(seed)):
        run = tc.experiment(scene, reference=reference, seed=seed, ev_spread=0.3)
        truth = run.plate.true_shifts(reference)
        assert run.result.shifts == truth
        assert truth[reference] == (0, 0)
        assert any(s != (0, 0) for s in truth.values())  # the test moved something


@settings(max_examples=10)
@given(
    shifts=st.lists(st.tuples(st.integers(-3, 3), st.integers(-3, 3)), min_size=3, max_size=3),
    seed=st.integers(0, 2**16),
)
def test_any_shift_within_the_margin_is_recovered(shifts, seed):
    """Frames up to 6 px apart, plus a 2 px border, plus the gradient's one
    pixel, stay inside the 9.2 px that align's 10 % crop leaves of a 92 px
    third: the border's edge never joins the comparison."""
    plate = tc.photograph(
        tc.mondrian(seed=seed), shifts=dict(zip("rgb", shifts, strict=True)), margin=3, seed=seed
    )
    assert tc.colourise(plate).shifts == plate.true_shifts("b")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_small_rotation_is_recovered_by_ecc(seed):
    """The camera also rolls by up to 0.01 rad between shots: the Euclidean
    warps colorize_plate finds move no frame corner more than 0.25 px from
    the true ones (measured: 0.05-0.15; both sides resample bilinearly).
    On green, which the red and blue frames of a photograph-like scene
    resemble; ECC refines on the gradient magnitudes the search used."""
    rng = np.random.default_rng(seed)
    turns = {c: float(rng.uniform(-0.01, 0.01)) for c in "rgb"}
    moves = {c: (int(rng.integers(-3, 4)), int(rng.integers(-3, 4))) for c in "rgb"}
    plate = tc.photograph(
        textured_scene(seed, (160, 192)), shifts=moves, rotation=turns, margin=6, seed=seed
    )
    _, found = colorize_plate(
        plate.image, reference="g", motion="euclidean", features="gradient", frame=False
    )
    h, w = plate.frame_shape
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float)
    for c, truth in plate.true_matrices("g").items():
        assert found[c].converged
        assert np.abs(corners @ (found[c].matrix - truth).T).max() < 0.25, c
        assert found[c].rotation == pytest.approx(turns[c] - turns["g"], abs=2e-3)


def test_the_plate_geometry_is_the_np_roll_convention():
    """Independently of colorize_plate: a grey scene exposes every filter
    alike, so each frame rolled by its true shift equals the reference frame
    where both have image (to the upsampling's 0.1 % departure from flat)."""
    grey = textured_scene(5).mean(axis=-1, keepdims=True).repeat(3, axis=-1)
    plate = tc.photograph(
        grey,
        shifts={"r": (3, -2), "g": (0, 4), "b": (-1, 1)},
        margin=4,
        exposure_ev={"r": 0.0, "g": 0.0, "b": 0.0},
        grain=False,
    )
    h, w = plate.frame_shape
    b, third = plate.border, plate.image.shape[0] // 3
    frames = {
        c: plate.image[i * third + b : i * third + b + h, b : b + w].astype(float)
        for i, c in enumerate(tc.PLATE_ORDER)
    }
    assert plate.true_shifts("b") == {"r": (4, -3), "g": (1, 3), "b": (0, 0)}
    inner = (slice(6, -6), slice(6, -6))
    for c, shift in plate.true_shifts("b").items():
        landed = np.roll(frames[c], shift, axis=(0, 1))
        diff = np.abs(landed - frames["b"])[inner] * tc.SCAN_DENSITY_RANGE / 65535
        assert diff.max() < 0.003, c  # density


def test_the_colour_error_is_the_filters_spectral_mismatch():
    """On a ColorChecker scene with the exposures known, each patch's mean
    CIEDE2000 is the 3x3 fit's own error on that patch within 0.1: the plate
    (curve, halation, grain, 16-bit scan, alignment) adds almost nothing to
    the error no 3x3 can remove, because the filtered plate's sensitivities
    are no mix of the CIE observer's. The fit's mean error is below 3.

    The chart's grid repeats every 20 px, and any search reaching half of
    that can land a frame one patch over: the search is kept to 8 px."""
    refl, boxes = chart_scene()
    plate = tc.photograph(refl, seed=2, margin=3, ev_spread=0.3)
    result = tc.colourise(plate, exposure_ev=plate.exposure_ev, max_shift=8)
    comparison = tc.compare(result, plate, refl)
    fit = tc.colour_matrix(CAMERA)
    assert comparison.shifts_exact
    assert fit.mean_delta_e < 3.0
    oy, ox = comparison.scene_origin
    de = comparison.delta_e
    checked = 0
    for (rows, cols), expected in zip(boxes, fit.delta_e, strict=True):
        y0, y1 = rows.start - oy + 3, rows.stop - oy - 3
        x0, x1 = cols.start - ox + 3, cols.stop - ox - 3
        if y0 < 0 or x0 < 0 or y1 > de.shape[0] or x1 > de.shape[1]:
            continue  # the patch is not wholly inside every frame
        assert abs(de[y0:y1, x0:x1].mean() - expected) < 0.1
        checked += 1
    assert checked >= 20


def test_unknown_exposure_errors_tint_the_result():
    scene = textured_scene(1)
    errors = {"r": 0.3, "g": 0.0, "b": -0.3}
    known = tc.experiment(scene, exposure_ev=errors, seed=1).comparison
    nominal = tc.experiment(scene, exposure_ev=errors, seed=1, known_exposures=False).comparison
    assert known.shifts_exact and nominal.shifts_exact
    assert nominal.mean_delta_e > known.mean_delta_e + 3.0


def test_rgb_and_spectral_scenes_expose_alike():
    """An sRGB scene is the Mallett-Yuksel reflectance of it: exposing the
    materialised spectra gives the same plate exposures."""
    rgb = textured_scene(2, (20, 24))
    refl = sp.rgb_to_reflectance(rgb, CAMERA.wavelengths).astype(np.float32)
    np.testing.assert_allclose(CAMERA.exposures(rgb), CAMERA.exposures(refl), rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(tc.scene_srgb(refl), rgb, atol=2e-3)


def test_a_white_exposes_every_frame_to_one():
    white = np.ones((2, 2, len(CAMERA.wavelengths)), np.float32)
    np.testing.assert_allclose(CAMERA.exposures(white), 1.0, rtol=1e-5)
    assert (CAMERA.filter_factors() > 1.0).all()


def test_the_scan_inverts_to_the_exposure():
    stock = film.load_stock("generic-bw-pan")
    H = np.geomspace(0.01, 2.0, 50, dtype=np.float32)[None, :, None]
    dens = film.develop(H, stock, couplers=False, halation=False)[..., 0]
    scan = np.floor((dens + stock.base_density.mean()) / tc.SCAN_DENSITY_RANGE * 65535 + 0.5)
    back = tc.exposure_from_scan(scan, CAMERA)
    np.testing.assert_allclose(back, H[..., 0], rtol=2e-3)


def test_one_seed_one_plate():
    scene = textured_scene(3, (60, 64))
    a, b = tc.photograph(scene, seed=7), tc.photograph(scene, seed=7)
    assert np.array_equal(a.image, b.image) and a.offsets == b.offsets
    assert a.exposure_ev == b.exposure_ev
    c = tc.photograph(scene, seed=8)
    assert not np.array_equal(a.image, c.image)


def test_the_plate_does_not_depend_on_the_thread_count():
    code = """
        import sys
        import numpy as np
        from imgform_rs import three_colour as tc
        y, x = np.mgrid[:64, :72] / 7.0
        scene = np.stack([0.5 + 0.3 * np.sin(x), 0.4 + 0.3 * np.cos(y), 0.3 + 0.0 * x], -1)
        turns = {"r": 0.003, "g": 0.0, "b": -0.002}
        moves = {"r": (1, 0), "g": (0, -1), "b": (-1, 1)}
        plate = tc.photograph(scene, shifts=moves, margin=4, rotation=turns, seed=4)
        sys.stdout.buffer.write(plate.image.tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


def test_filters_on_a_wrong_grid_are_refused():
    with pytest.raises(ValueError, match=r"filters must have shape \(3, 41\).*got \(3, 31\)"):
        tc.Camera(filters=np.full((3, 31), 0.5))


@pytest.mark.parametrize("value", [-0.01, 1.2, np.nan])
def test_transmittances_outside_zero_one_are_refused(value):
    filters = tc.separation_filters()
    filters[1, 12] = value
    with pytest.raises(
        ValueError,
        match=r"green filter's transmittance must lie in \[0, 1\]; "
        r"at 500 nm",
    ):
        tc.Camera(filters=filters)


def test_a_filter_the_plate_cannot_see_through_is_refused():
    filters = tc.separation_filters()
    filters[2] = 0.0
    with pytest.raises(ValueError, match="the blue filter passes no light"):
        tc.Camera(filters=filters)


def test_a_colour_stock_is_not_a_plate():
    with pytest.raises(ValueError, match=r"one-layer .* negative stock, got the 3-layer"):
        tc.Camera(plate="generic-negative")


def test_shifts_too_large_for_the_plate_are_refused():
    scene = textured_scene(0, (60, 64))
    with pytest.raises(
        ValueError,
        match=r"shift 'g' = \(0, 6\) is too large for the plate.*"
        r"\[-5, 5\]",
    ):
        tc.photograph(scene, shifts={"r": (0, 0), "g": (0, 6), "b": (1, 1)}, margin=5)
    with pytest.raises(ValueError, match=r"rotation 'g' = 0.1 rad .* margin is 5 px"):
        tc.photograph(scene, rotation={"r": 0.0, "g": 0.1, "b": 0.0}, margin=5)
    with pytest.raises(ValueError, match="frame of at least 16 x 16"):
        tc.photograph(scene, margin=23)
    with pytest.raises(ValueError, match="pair of integers"):
        tc.photograph(scene, shifts={"r": (0, 0.5), "g": (0, 0), "b": (0, 0)})
    with pytest.raises(ValueError, match='keys "r", "g", "b"'):
        tc.photograph(scene, shifts={"r": (0, 0)})


def test_separation_filters_of_bad_parameters_are_refused():
    # Before: transmittances of 5 and NaN came back.
    bright = dict(tc.WRATTEN_LIKE, r=dict(tc.WRATTEN_LIKE["r"], peak_transmittance=5.0))
    with pytest.raises(ValueError, match=r"red filter's transmittance must lie in \[0, 1\]"):
        tc.separation_filters(params=bright)
    flat = dict(tc.WRATTEN_LIKE, g=dict(tc.WRATTEN_LIKE["g"], width=0))
    with pytest.raises(ValueError, match=r"green filter's .* is nan"):
        tc.separation_filters(params=flat)


def test_mondrian_names_a_bad_shape_or_count():
    # Before: "too many values to unpack" and "'<' not supported".
    with pytest.raises(ValueError, match=r"shape must be \(height, width\)"):
        tc.mondrian((20, 20, 3))
    with pytest.raises(TypeError, match="rectangles must be an integer"):
        tc.mondrian((20, 20), rectangles="3")


def test_bad_scenes_and_scans_are_refused():
    with pytest.raises(ValueError, match=r"\(H, W, 3\) or reflectance \(H, W, 41\)"):
        tc.photograph(np.zeros((40, 40, 5)))
    with pytest.raises(ValueError, match="scene must be finite"):
        tc.photograph(np.full((40, 40, 3), np.inf))
    with pytest.raises(TypeError, match="scene must be float"):
        tc.photograph(np.zeros((40, 40, 3), complex))
    # Before, an 8-bit picture was taken as reflectances up to 255.
    with pytest.raises(TypeError, match="got dtype uint8: divide an 8-bit picture by 255"):
        tc.photograph(np.full((40, 40, 3), 128, np.uint8))
    with pytest.raises(TypeError, match="uint16 scan"):
        tc.colourise(np.zeros((90, 30), np.float32))
    with pytest.raises(ValueError, match='reference must be "r", "g" or "b"'):
        tc.colourise(tc.photograph(textured_scene(0, (40, 40))), reference="x")
    plate = tc.photograph(textured_scene(0, (40, 40)))
    with pytest.raises(ValueError, match='exposure_ev must be a dict with keys "r", "g", "b"'):
        tc.colourise(plate, exposure_ev={"r": 0.1})
    with pytest.raises(ValueError, match="exposure_ev must be finite"):
        tc.colourise(plate, exposure_ev={"r": 0.1, "g": np.nan, "b": 0.0})
    with pytest.raises(ValueError, match=r"matrix must be a finite 3x3 array, got shape \(2, 3\)"):
        tc.colourise(plate, matrix=np.eye(3)[:2])
    with pytest.raises(ValueError, match="ev_spread"):
        tc.photograph(textured_scene(0, (40, 40)), ev_spread=-1)


def test_exposure_errors_beyond_films_range_are_refused():
    scene = textured_scene(0, (40, 40))
    # Film's whole range is usable: red 100 stops over saturates its frame,
    # green 100 under leaves its frame at base plus fog.
    extreme = tc.photograph(scene, exposure_ev={"r": film.MAX_EV, "g": -film.MAX_EV, "b": 0.0})
    (h, w), b = extreme.frame_shape, extreme.border
    blue, green, red = (extreme.image[i * (h + 2 * b) + b :][:h, b : b + w] for i in range(3))
    assert red.min() > blue.max() and blue.min() > green.max()
    # 2 ** 1e6 overflowed a float: OverflowError, not a word on the range.
    for ev in (1e6, -1e6):
        errors = {"r": ev, "g": 0.0, "b": 0.0}
        stops = r"exposure_ev must be finite numbers of stops in \[-100, 100\], got "
        with pytest.raises(ValueError, match=stops + re.escape(repr(errors))):
            tc.photograph(scene, exposure_ev=errors)
        with pytest.raises(ValueError, match=stops):
            tc.colourise(extreme, exposure_ev=errors)
    with pytest.raises(ValueError, match=r"ev_spread must be .* from 0 to 100, got 1000000\.0"):
        tc.photograph(scene, ev_spread=1e6)


@pytest.mark.slow
def test_the_figure_captions_quote_what_the_demo_measures(monkeypatch):
    from imgform_rs import demo

    pinhole, _ = demo._render(demo._camera(demo.SUPERSAMPLE))
    experiment = tc.experiment
    measured = []
    for known in (True, False):
        # The figure's own code, run with and without the exposure record.
        monkeypatch.setattr(tc, "experiment", functools.partial(experiment, known_exposures=known))
        lines: list[str] = []
        demo._three_colour_figure(pinhole, lines.append)
        measured += re.findall(r"over (\d+) px: mean (\d+\.\d\d), max (\d+\.\d\d)", lines[-1])
    (pixels, mean, top), (_, tinted_mean, tinted_top) = measured
    root = Path(__file__).resolve().parents[1]
    guide = " ".join((root / "docs" / "guide" / "three_colour.rst").read_text().split())
    count = f"{int(pixels):,}".replace(",", " ")  # the guide's thousands separator
    assert f"CIEDE2000 mean {mean}, max {top} over the {count} pixels" in guide
    assert f"({tinted_mean} and {tinted_top} without the exposure record)" in guide
    readme = " ".join((root / "README.md").read_text().split())
    assert f"mean CIEDE2000 {float(mean):.1f} (max {float(top):.1f})" in readme


@pytest.mark.parametrize("seed", [True, -1, 1.5, "1"])
def test_a_seed_that_is_no_natural_int_is_refused(seed):
    with pytest.raises(ValueError, match=r"seed must be an int in \[0, 2\*\*64\)"):
        tc.photograph(np.full((40, 48, 3), 0.5), seed=seed)
    with pytest.raises(ValueError, match=r"seed must be an int in \[0, 2\*\*64\)"):
        tc.mondrian((40, 50), seed=seed)
