"""Dispersion: glass indices, focal shift per wavelength, chromatic aberrations."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imgform_rs.dispersion import (
    LINE_C,
    LINE_D,
    LINE_F,
    Glass,
    focal_lengths,
    focal_shift,
    render_dispersion,
)

# Schott N-BK7's Sellmeier coefficients and catalogue n_d, V_d (datasheet facts).
BK7 = Glass.from_sellmeier(
    [1.03961212, 0.231792344, 1.01046945], [0.00600069867, 0.0200179144, 103.560653]
)

# Schott F2's (the same datasheet facts).
F2 = Glass.from_sellmeier(
    [1.34533359, 0.209073176, 0.937357162], [0.00997743871, 0.0470450767, 111.886764]
)


def test_sellmeier_bk7_has_its_catalogue_index_and_abbe_number():
    assert float(BK7.index(LINE_D)) == pytest.approx(1.5168, abs=1e-4)
    assert BK7.abbe_number == pytest.approx(64.17, abs=0.05)
    assert float(F2.index(LINE_D)) == pytest.approx(1.62004, abs=1e-4)
    assert F2.abbe_number == pytest.approx(36.37, abs=0.05)


@pytest.mark.parametrize(
    ("glass", "shifts"),
    [
        (BK7, (-1.32, 0.36)),
        (Glass.from_abbe(1.5168, 64.17), (-1.33, 0.35)),
        (F2, (-2.46, 0.61)),
        (Glass.from_abbe(1.62004, 36.37), (-2.30, 0.62)),
    ],
)
def test_the_guides_focal_shifts_of_a_50_mm_singlet(glass, shifts):
    """docs/guide/spectral.rst quotes these, at 400 and 700 nm (its F2 figures
    were the (n_d, V_d) glass's, beside N-BK7's from Sellmeier)."""
    np.testing.assert_allclose(focal_shift(glass, [400.0, 700.0], 50.0), shifts, atol=0.005)


def test_the_abbe_glass_follows_the_sellmeier_glass_across_the_visible():
    cauchy = Glass.from_abbe(1.5168, 64.17)
    wl = np.arange(400.0, 701.0, 10.0)
    assert np.abs(cauchy.index(wl) - BK7.index(wl)).max() < 2e-4
    # Figure 4a for both: the focal shifts of a 50 mm lens agree within 2 %
    # of the blue end's 1.3 mm.
    shift = focal_shift(cauchy, wl, 50.0)
    assert np.abs(shift - focal_shift(BK7, wl, 50.0)).max() < 0.02 * abs(shift[0])


@settings(max_examples=50, deadline=None)
@given(n_d=st.floats(1.4, 2.0), v_d=st.floats(18.0, 95.0), f_d=st.floats(5.0, 500.0))
def test_abbe_glasses_keep_their_numbers_and_spread_focus_by_f_over_v(n_d, v_d, f_d):
    glass = Glass.from_abbe(n_d, v_d)
    assert float(glass.index(LINE_D)) == pytest.approx(n_d, rel=1e-12)
    assert glass.abbe_number == pytest.approx(v_d, rel=1e-9)
    f_f, f_dd, f_c = focal_lengths(glass, [LINE_F, LINE_D, LINE_C], f_d)
    assert f_dd == pytest.approx(f_d, rel=1e-12)
    # Normal dispersion: red focuses farther than blue, by ~f_d / V_d (the
    # first-order result; higher orders add (n - 1)^2 / (n_C - 1)(n_F - 1)).
    assert f_f < f_dd < f_c
    assert (f_c - f_f) == pytest.approx(f_d / v_d, rel=0.05)


def test_bad_glasses_and_wavelengths_are_refused():
    with pytest.raises(ValueError, match="n_d must be"):
        Glass.from_abbe(0.9, 50)
    with pytest.raises(ValueError, match="abbe_number must be"):
        Glass.from_abbe(1.5, -3)
    with pytest.raises(ValueError, match="3 values each"):
        Glass.from_sellmeier([1, 2], [0, 0, 0])
    with pytest.raises(ValueError, match="finite and > 0"):
        BK7.index([500.0, np.nan])
    with pytest.raises(ValueError, match="absorption pole"):
        BK7.index([10_170.0])  # sqrt(C3) = 10.18 µm
    with pytest.raises(ValueError, match="f_d must be"):
        focal_lengths(BK7, [500.0], 0.0)
    # Built directly: before, an index of 1 gave NaN focal lengths, one of
    # 0.53 came back as it was, and a negative C only warned.
    for coefficients in [(1.0, 0.0), (0.5, 0.01)]:
        with pytest.raises(ValueError, match=r"no index > 1 at 587\.562 nm"):
            Glass("cauchy", coefficients)
    with pytest.raises(ValueError, match="no index > 1 at 300 nm"):
        Glass("cauchy", (1.6, -0.1)).index([300.0])
    with pytest.raises(ValueError, match="finite and >= 0"):
        Glass("sellmeier", (1, 0, 0, -0.01, 0, 0))


def test_sellmeier_indices_exist_only_between_the_poles_around_the_d_line():
    """N-BK7's poles lie at sqrt(C) = 77.5 nm, 141.5 nm (ultraviolet) and
    10.18 µm (infrared). At a pole the formula divides by 0 and across one
    it describes no glass (beyond 10.18 µm it gives n ~ 1.8 again): both are
    refused; the window between 141.5 nm and 10.18 µm is answered."""
    uv, ir = np.sqrt(0.0200179144) * 1e3, np.sqrt(103.560653) * 1e3
    window = r"between the poles at 141\.485 and 10176\.5 nm"
    for wl in (np.sqrt(0.00600069867) * 1e3, uv, ir, 100.0, 20_000.0, 1e6):
        with pytest.raises(
            ValueError, match=rf"{re.escape(f'{wl:g}')} nm is at or across .* {window}"
        ):
            BK7.index([500.0, wl])
    with pytest.raises(ValueError, match="at or across a Sellmeier pole"):
        focal_lengths(BK7, [np.sqrt(0.00600069867) * 1e3], 50.0)
    n = BK7.index([200.0, 300.0, 2_000.0, 5_000.0])
    assert np.isfinite(n).all() and (n > 1).all()
    # A vanishing B_i makes no pole: a glass without an infrared term has
    # no upper end.
    uv_only = Glass.from_sellmeier([1.03961212, 0.231792344, 0.0], [0.006, 0.02, 103.56])
    assert np.isfinite(uv_only.index([20_000.0])).all()


def _two_points() -> np.ndarray:
    cube = np.zeros((41, 61, 3), np.float32)
    cube[20, 30] = 1.0  # on the axis
    cube[20, 50] = 1.0  # 20 px off it
    return cube


def test_each_wavelength_is_defocused_and_magnified_by_its_focal_length():
    glass = Glass.from_abbe(1.5168, 64.17)
    wl = [400.0, LINE_D, 700.0]
    out = render_dispersion(
        _two_points(),
        wl,
        glass,
        f_d=50.0,
        N=4.0,
        focus_distance=2000.0,
        depth=2000.0,
        pixel_pitch=0.05,
    )
    # The d line is focused and unmagnified: the image is the input.
    np.testing.assert_array_equal(out[:, :, 1], _two_points()[:, :, 1])
    f = focal_lengths(glass, wl, 50.0)
    columns = np.arange(40, 61)
    for i in (0, 2):
        plane = out[:, :, i]
        assert plane.max() < 0.5  # spread over a disc
        # Lateral: the off-axis point's centroid lands at 30 + 20 f / f_d.
        right = plane[:, 40:]
        centroid = (right.sum(axis=0) * columns).sum() / right.sum()
        assert centroid == pytest.approx(30 + 20 * f[i] / 50.0, abs=0.05)
    # Blue is 1.3 mm short of focus, red 0.35 mm long: blue spreads wider.
    assert out[:, :, 0].max() < out[:, :, 2].max()
    still = render_dispersion(
        _two_points(),
        wl,
        glass,
        f_d=50.0,
        N=4.0,
        focus_distance=2000.0,
        depth=2000.0,
        pixel_pitch=0.05,
        lateral=False,
    )
    # Without lateral aberration, each disc stays centred on its point.
    for i in (0, 2):
        right = still[:, 40:, i]
        assert (right.sum(axis=0) * columns).sum() / right.sum() == pytest.approx(50.0, abs=1e-3)


def test_one_wavelength_renders_as_it_does_among_others():
    """A monochromatic render was refused as a grid of one sample."""
    glass = Glass.from_abbe(1.5168, 64.17)
    args = dict(f_d=50.0, N=4.0, focus_distance=2000.0, depth=2000.0, pixel_pitch=0.05)
    every = render_dispersion(_two_points(), [400.0, LINE_D, 700.0], glass, **args)
    one = render_dispersion(np.ascontiguousarray(_two_points()[:, :, :1]), [400.0], glass, **args)
    np.testing.assert_array_equal(one[:, :, 0], every[:, :, 0])
    with pytest.raises(ValueError, match="finite and > 0 nm"):
        render_dispersion(_two_points()[:, :, :1], [-400.0], glass, **args)
    with pytest.raises(TypeError, match="lateral must be a bool"):
        render_dispersion(_two_points(), [400.0, 500.0, 600.0], glass, **args, lateral="no")


def test_a_glass_is_the_same_whatever_sequence_holds_its_coefficients():
    listed = Glass("cauchy", [1.5, 0.01])
    assert listed == Glass("cauchy", (1.5, 0.01)) and hash(listed) == hash(
        Glass("cauchy", (1.5, 0.01))
    )
    assert Glass("cauchy", np.array([1.5, 0.01])).coefficients == (1.5, 0.01)


def test_render_dispersion_refuses_bad_input_by_name():
    glass = Glass.from_abbe(1.5168, 64.17)
    args = dict(f_d=50.0, N=4.0, focus_distance=2000.0, depth=2000.0, pixel_pitch=0.05)
    with pytest.raises(TypeError, match="float32"):
        render_dispersion(_two_points().astype(np.float64), [400, 500, 600], glass, **args)
    with pytest.raises(ValueError, match="3 samples"):
        render_dispersion(_two_points(), [400, 500], glass, **args)
    # Focused at 10 km, the sensor is 0.25 µm behind the d line's focus:
    # red's focal length, 0.35 mm longer, reaches past it.
    with pytest.raises(ValueError, match="at 700 nm the focal length reaches the sensor"):
        render_dispersion(_two_points(), [400, 500, 700], glass, **{**args, "focus_distance": 1e7})


def test_bad_glasses_spectra_grids_and_depths_are_refused():
    glass = Glass.from_abbe(1.5168, 64.17)
    args = dict(f_d=50.0, N=4.0, focus_distance=2000.0, depth=2000.0, pixel_pitch=0.05)
    wl = [400.0, 500.0, 600.0]
    with pytest.raises(ValueError, match="finite and >= 0"):
        Glass.from_sellmeier([1, 0, 0], [-1, 0, 0])
    with pytest.raises(ValueError, match='law must be "cauchy" or "sellmeier"'):
        Glass("foo", (1.0, 2.0))
    with pytest.raises(ValueError, match="needs 2 finite coefficients"):
        Glass("cauchy", (1.5,))
    with pytest.raises(TypeError, match="glass must be a Glass"):
        render_dispersion(_two_points(), wl, "N-BK7", **args)  # type: ignore[arg-type]
    for bad in (np.nan, -1.0):
        cube = _two_points()
        cube[7, 9, 2] = bad
        with pytest.raises(ValueError, match=r"pixel \(row 7, column 9\) is not"):
            render_dispersion(cube, wl, glass, **args)
    with pytest.raises(ValueError, match="strictly increasing"):
        render_dispersion(_two_points(), wl[::-1], glass, **args)
    with pytest.raises(ValueError, match=r"\(H, W\) = \(41, 61\) map, got shape \(3, 3\)"):
        render_dispersion(_two_points(), wl, glass, **{**args, "depth": np.ones((3, 3))})
    with pytest.raises(ValueError, match="focus_distance must be finite and beyond"):
        render_dispersion(_two_points(), wl, glass, **{**args, "focus_distance": 20.0})
