"""Colour film: stocks, exposure, development with couplers, printing, viewing."""

from __future__ import annotations

import contextlib
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from film_reference import develop as ref_develop
from film_reference import negative_print as ref_negative_print
from hypothesis import given
from hypothesis import strategies as st

from conftest import output_with_threads
from imgform_rs import _native, film
from imgform_rs import spectral as sp

pytest.importorskip("colour")

STOCKS = film.shipped_stocks()


def wedge(stock: film.Stock, steps: int = 25, width: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A neutral step wedge over the stock's curve range: log exposures and an
    RGB image of ``steps`` uniform steps, each ``width`` pixels wide."""
    lo = max(lay.log_exposure[0] for lay in stock.layers)
    hi = min(lay.log_exposure[-1] for lay in stock.layers)
    x = np.linspace(lo + 0.05, hi - 0.05, steps)
    rgb = np.repeat(10.0**x, width)[None, :, None] * np.ones((6, 1, 3))
    return x, rgb.astype(np.float32)


def step_centres(image: np.ndarray, width: int = 24) -> np.ndarray:
    return image[3, width // 2 :: width]


def test_the_shipped_stocks_are_the_parametric_ones():
    """The JSON files are reproducible from the equations of parametric_stock."""
    assert set(STOCKS) == set(film._GENERIC)
    for name in STOCKS:
        shipped, made = film.load_stock(name), film.parametric_stock(name)
        assert film.stock_to_dict(shipped) == film.stock_to_dict(made), name
        assert "license" in shipped.provenance and "source" in shipped.provenance


@pytest.mark.parametrize("name", STOCKS)
def test_a_neutral_wedge_reproduces_the_curves_with_couplers_on(name):
    stock = film.load_stock(name)
    x, rgb = wedge(stock)
    dens = step_centres(film.develop(film.expose(rgb, stock), stock, couplers=True))
    for i, layer in enumerate(stock.layers):
        err = np.abs(dens[:, i] - layer.curve(x)).max()
        assert err < 0.02, (name, layer.name, err)


@pytest.mark.parametrize("name", STOCKS)
def test_without_couplers_density_is_the_curve_exactly(name):
    stock = film.load_stock(name)
    x, rgb = wedge(stock)
    exposure = film.expose(rgb, stock)
    assert np.allclose(exposure, rgb[..., :1], rtol=2e-6)  # neutral: H = g in every layer
    dens = step_centres(film.develop(exposure, stock, couplers=False))
    for i, layer in enumerate(stock.layers):
        np.testing.assert_allclose(dens[:, i], layer.curve(x), atol=2e-6)


def reference_white(stock: film.Stock) -> np.ndarray:
    """The documented reference white, built here from its definition: the
    black body at the stock's balance temperature with Y = ∫ W ȳ dλ = 1."""
    wl = stock.wavelengths
    bb = sp.blackbody(wl, stock.balance_kelvin)
    return bb / np.sum(bb * sp.cie_cmfs(wl)[:, 1] * sp.quadrature_weights(wl))


@pytest.mark.parametrize("name", ["generic-negative", "generic-bw-pan"])
def test_a_spectral_image_of_the_reference_white_exposes_one_in_every_layer(name):
    stock = film.load_stock(name)
    white = reference_white(stock).astype(np.float32)
    H = film.expose(np.tile(0.25 * white, (2, 3, 1)), stock, exposure_ev=2.0)
    np.testing.assert_allclose(H, 1.0, rtol=1e-5)
    # In radiance units that white is 683 cd/m² (Y = luminance / 683).
    wl = stock.wavelengths
    bright = sp.luminance_scale(sp.blackbody(wl, stock.balance_kelvin), wl, 683.0)
    np.testing.assert_allclose(film.expose(bright[None, None], stock), 1.0, rtol=1e-5)


def test_rgb_and_its_spectra_under_the_reference_white_expose_alike():
    """The RGB path is the spectral one with the upsampled reflectances lit
    by the reference white: both give the same exposures, within the 0.1 %
    by which the basis's sum departs from 1 (the RGB path's normalisation
    takes it out, so that (1, 1, 1) exposes exactly 1)."""
    stock = film.load_stock("generic-negative")
    rgb = np.random.default_rng(5).uniform(0, 1, (4, 5, 3)).astype(np.float32)
    spectra = sp.rgb_to_reflectance(rgb, stock.wavelengths) * reference_white(stock)
    np.testing.assert_allclose(
        film.expose(spectra.astype(np.float32), stock), film.expose(rgb, stock), rtol=1e-3
    )


def test_the_spectral_guides_chart_exposes_its_white_patch_below_the_reference():
    """The spectral guide's ColorChecker, lit by D65 at 300 cd/m²: its white
    patch (Y 0.89 of the light) exposes about 0.89 x 300 / 683 = 0.39 and
    develops well below D_max, not crushed into it."""
    stock = film.load_stock("generic-negative")
    wl = stock.wavelengths
    light = sp.luminance_scale(sp.illuminant("D65", wl), wl, 300.0)
    scene, boxes = sp.colorchecker_scene(wl, light, patch=6, gap=2)
    ys, xs = boxes[18]
    H = film.expose(scene, stock)[ys, xs].mean(axis=(0, 1))
    np.testing.assert_allclose(H, 0.887 * 300 / 683, rtol=0.15)
    D = film.develop(film.expose(scene, stock), stock)[ys, xs].mean(axis=(0, 1))
    assert (D < stock.dye_max - 0.5).all(), (D, stock.dye_max)


def test_a_reversal_curve_falls_and_a_negative_rises():
    rev, neg = film.load_stock("generic-reversal"), film.load_stock("generic-negative")
    for stock, sign in ((rev, -1), (neg, 1)):
        _, rgb = wedge(stock)
        d = step_centres(film.develop(film.expose(rgb, stock), stock))
        assert (sign * np.diff(d, axis=0) > 0).all(), stock.name


def test_transmittance_is_beer_lambert_of_the_dyes():
    """-log10 T is linear in the dye amounts: least squares recovers them."""
    stock = film.load_stock("generic-negative")
    rng = np.random.default_rng(3)
    d = rng.uniform(0.2, 2.4, (4, 5, 3)).astype(np.float32)
    od = -np.log10(film.transmittance(d, stock).astype(np.float64))
    base, dyes = film._dyes(stock)
    amounts = np.linalg.lstsq(dyes.T, (od - base).reshape(-1, len(base)).T, rcond=None)[0]
    np.testing.assert_allclose(amounts.T.reshape(d.shape), d, atol=2e-5)


def test_masking_couplers_keep_the_unwanted_absorption_constant():
    """Exposing the red layer alone: the cyan dye's unwanted green absorption
    is replaced by its mask, so at 540 nm only the main band's tail grows;
    without masks the unwanted absorption grows with the cyan too."""
    stock = film.load_stock("generic-negative")
    unmasked = film.Stock(
        **{
            **vars(stock),
            "layers": tuple(
                film.Layer(**{**vars(lay), "mask_density": 0 * lay.mask_density})
                for lay in stock.layers
            ),
        }
    )
    k = int(np.argmin(np.abs(stock.wavelengths - 540)))
    d = np.zeros((1, 6, 3), np.float32)
    d[..., 0] = np.linspace(0.3, 2.4, 6)
    d[..., 1:] = 0.8
    masked = -np.log10(film.transmittance(d, stock)[0, :, k])
    plain = -np.log10(film.transmittance(d, unmasked)[0, :, k])
    # With masks only the cyan's main band (its tail at 540 nm) adds density.
    tail = 2.1 * film.gaussian(stock.wavelengths[k], 665.0, 45.0)
    assert abs(np.ptp(masked) - tail) < 1e-3
    assert np.ptp(plain) > np.ptp(masked) + 0.2


def test_couplers_raise_colour_contrast_of_a_saturated_patch():
    """Interimage effect: a red patch inhibits its neighbours' layers less
    than grey of the same red exposure does, so cyan-red separation grows."""
    stock = film.load_stock("generic-negative")
    rgb = np.zeros((8, 8, 3), np.float32)
    rgb[..., 0] = 0.6
    rgb[..., 1:] = 0.05
    h = film.expose(rgb, stock)
    on, off = film.develop(h, stock), film.develop(h, stock, couplers=False)
    spread_on = on[4, 4, 0] - on[4, 4, 1]
    spread_off = off[4, 4, 0] - off[4, 4, 1]
    assert spread_on > spread_off + 0.02


def test_kernels_agree_with_the_numpy_reference():
    neg, paper = film.load_stock("generic-negative"), film.load_stock("generic-paper")
    rng = np.random.default_rng(1)
    rgb = rng.uniform(0, 1, (40, 60, 3)).astype(np.float32) ** 2
    rgb[10:30, 20:40] *= 0.1  # a dark square: edges for the couplers' diffusion
    frame = 60 * 0.04  # 40 µm pixels: a diffusion of 0.3 px
    h = film.expose(rgb, neg)
    ours = film.develop(h, neg, frame_width_mm=frame)
    np.testing.assert_allclose(ours, ref_develop(h, neg, frame), atol=2e-3)
    # A wide diffusion: 12 µm at 4 µm pixels is 3 px.
    np.testing.assert_allclose(
        film.develop(h, neg, frame_width_mm=0.24), ref_develop(h, neg, 0.24), atol=2e-3
    )
    printed = film.print(film.develop(h, neg), neg, paper)
    np.testing.assert_allclose(printed, ref_negative_print(rgb, neg, paper), atol=5e-3)


def test_a_grey_prints_grey():
    neg, paper = film.load_stock("generic-negative"), film.load_stock("generic-paper")
    fil = film.balance_print(neg, paper)
    assert min(fil.yellow, fil.magenta, fil.cyan) == 0.0 and fil.exposure > 0
    greys = np.array([0.18])[None, :, None] * np.ones((1, 1, 3), np.float32)
    mid = film.print(film.develop(film.expose(greys, neg), neg), neg, paper)
    np.testing.assert_allclose(mid, film.PRINT_GREY_DENSITY, atol=1e-3)
    # Over a range of greys the paper layers stay together and the print neutral.
    g = np.geomspace(0.02, 0.9, 8)[None, :, None] * np.ones((1, 1, 3))
    printed = film.print(film.develop(film.expose(g.astype(np.float32), neg), neg), neg, paper)
    assert np.ptp(printed, axis=-1).max() < 0.05
    xyz = film.scan(printed, paper)[0].astype(np.float64)
    white = sp.illuminant("D65", neg.wavelengths) @ sp.cie_cmfs(neg.wavelengths)
    lab = sp.xyz_to_lab(xyz, white / white[1])
    assert np.hypot(lab[:, 1], lab[:, 2]).max() < 2.5, lab


def test_simulate_gives_srgb_in_range_and_keeps_greys_neutral():
    ramp = np.geomspace(0.03, 0.9, 16, dtype=np.float32)
    img = np.stack(np.broadcast_arrays(ramp, ramp, ramp), -1)[None]
    for stock in ("generic-negative", "generic-reversal", "generic-bw-pan"):
        out = film.simulate(img, stock)
        assert out.shape == img.shape and out.dtype == np.float32
        assert 0 <= out.min() and out.max() <= 1
        assert (np.diff(out[0, :, 1]) > 0).all(), stock  # brighter scene, brighter picture
        assert np.ptp(out[0], axis=-1).max() < 0.08, stock
    with pytest.raises(ValueError, match="is a paper"):
        film.simulate(img, "generic-paper")


def test_the_output_does_not_depend_on_the_thread_count():
    code = """
        import sys, numpy as np
        from imgform_rs import film
        rng = np.random.default_rng(0)
        rgb = rng.uniform(0, 1, (130, 70, 3)).astype(np.float32)
        sys.stdout.buffer.write(film.simulate(rgb, frame_width_mm=0.5).tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


# --- stock files and bad input ------------------------------------------------------------


def test_a_user_file_round_trips(tmp_path):
    stock = film.parametric_stock("generic-reversal")
    path = tmp_path / "mine.json"
    film.save_stock(stock, path)
    back = film.load_stock(path)
    assert film.stock_to_dict(back) == film.stock_to_dict(stock)


def _broken(tmp_path, edit) -> str:
    data = film.stock_to_dict(film.parametric_stock("generic-negative"))
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    return str(path)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["layers"][1]["curve"]["density"].__setitem__(300, 0.0), "must rise strictly"),
        (lambda d: d["layers"][0]["curve"]["density"].__setitem__(0, -0.1), ">= 0"),
        (lambda d: d["layers"][2]["dye_density"].pop(), "must have 41 samples"),
        (lambda d: d["wavelengths"].__setitem__(5, 300.0), "wavelengths"),
        (lambda d: d["layers"][0]["curve"]["log_exposure"].reverse(), "increase strictly"),
        (lambda d: d.__setitem__("base_density", [-0.1] * 41), "base_density must be >= 0"),
        (lambda d: d.__setitem__("format", "other/2"), "format must be"),
        (lambda d: d.__setitem__("kind", "print"), "kind must be one of"),
        (lambda d: d["couplers"].__setitem__("matrix", [[0.1, -0.1, 0]] * 3), "coupler_matrix"),
        (lambda d: d["layers"][0].pop("dye_density"), "missing field 'dye_density'"),
        (lambda d: d["layers"].append(3), "list of layer objects"),
        (lambda d: d.__setitem__("halation", {"strength": [2.0, 0, 0]}), "halation must hold"),
        (lambda d: d.__setitem__("couplers", [0.1]), "couplers must be a JSON object.*list"),
        (lambda d: d.__setitem__("provenance", ["me"]), "provenance must be a JSON object"),
        (lambda d: d.__setitem__("grain", 0.01), "grain must be a JSON object.*float"),
        (lambda d: d["layers"][1].__setitem__("curve", [0, 1]), "curve must be a JSON object"),
        (lambda d: d.__setitem__("balance_kelvin", [5500]), "balance_kelvin must be a number"),
        (lambda d: d["halation"].__setitem__("spread_um", "wide"), "spread_um must be a number"),
    ],
)
def test_bad_stocks_are_refused_with_a_clear_error(tmp_path, edit, message):
    with pytest.raises(ValueError, match=message):
        film.load_stock(_broken(tmp_path, edit))


def test_bad_names_json_and_images_are_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown stock"):
        film.load_stock("kodachrome")
    with pytest.raises(ValueError, match="a stock is a JSON object"):
        film.stock_from_dict([1, 2])
    (tmp_path / "x.json").write_text("{nope")
    with pytest.raises(ValueError, match="not valid JSON"):
        film.load_stock(tmp_path / "x.json")
    with pytest.raises(ValueError, match=r"3 channels .* or 41"):
        film.expose(np.zeros((2, 2, 4), np.float32), "generic-negative")
    bad = np.full((2, 3, 3), 0.5, np.float32)
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match=r"row 1, column 2"):
        film.simulate(bad)
    # Before: NaN out of to_srgb, inf out of expose.
    with pytest.raises(
        ValueError, match=r"xyz must hold finite numbers, got nan at index \(1, 2, 0\)"
    ):
        film.to_srgb(bad)
    with pytest.raises(ValueError, match="beyond float32's range"):
        film.expose(np.full((1, 1, 3), 1e10, np.float32), "generic-negative", exposure_ev=100)
    for width in (0, -1.0, np.inf, np.nan):
        with pytest.raises(ValueError, match="frame_width_mm must be a finite number > 0, got"):
            film.develop(np.ones((2, 2, 3), np.float32), "generic-negative", frame_width_mm=width)
    with pytest.raises(TypeError, match="frame_width_mm must be a real number, got '36'"):
        film.develop(np.ones((2, 2, 3), np.float32), "generic-negative", frame_width_mm="36")
    # A frame so small that a spread covers more than the image: its taps
    # would not fit in memory (an abort, before this was checked).
    for kw in ({}, {"halation": False}):
        with pytest.raises(ValueError, match=r"frame_width_mm must be at least 0\.0"):
            film.simulate(np.ones((4, 4, 3), np.float32), frame_width_mm=1e-12, **kw)
    # Wider than the kernels' widest blur (1000 px), not than this image: the
    # kernel's refusal spoke of pixels and named no frame width.
    stock = film.load_stock("generic-negative")
    frame_mm = stock.halation_um / 1050 * 1200 / 1000  # a 1050 px halation
    exposure = np.full((2, 1200, 3), 0.18, np.float32)
    with pytest.raises(ValueError, match=r"wider than 1000 px .* at least 0\.0"):
        film.develop(exposure, stock, frame_width_mm=frame_mm, grain=False)
    with pytest.raises(ValueError, match="print needs a negative and a paper"):
        film.print(np.ones((2, 2, 3), np.float32), "generic-reversal", "generic-paper")
    # balance_print refuses what print refuses: a negative is no paper.
    with pytest.raises(ValueError, match="balance_print needs a negative and a paper"):
        film.balance_print("generic-negative", "generic-negative")
    with pytest.raises(ValueError, match=r"needs a negative and a paper, got a negative"):
        film.simulate(np.ones((2, 2, 3), np.float32), paper="generic-negative")


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int32])
def test_integer_images_are_refused_not_read_as_reflectances(dtype):
    """An integer picture has no one reading as reflectances (uint8 46 would
    expose 46 times a perfect white): the error says how to convert it."""
    image = np.full((2, 2, 3), 46, dtype)
    for call in (film.expose, film.simulate):
        with pytest.raises(TypeError, match=f"must be float.*got dtype {np.dtype(dtype)}"):
            call(image, "generic-negative")


def test_out_of_range_seeds_and_exposures_are_value_errors():
    h = np.full((2, 2, 3), 0.18, np.float32)
    for seed in (-1, 2**64, 1.5):
        with pytest.raises(ValueError, match=r"seed must be an int in \[0, 2\*\*64\)"):
            film.develop(h, "generic-negative", grain=True, seed=seed)
    for ev in (2000.0, -2000.0, np.nan, np.inf):
        with pytest.raises(ValueError, match=r"exposure_ev must be .* stops in \[-100, 100\]"):
            film.expose(h, "generic-negative", exposure_ev=ev)
        with pytest.raises(ValueError, match="exposure_ev must be"):
            film.print(h, "generic-negative", "generic-paper", exposure_ev=ev)
    # The ends of the range still work: the grey lands on the curves' ends.
    neg = film.load_stock("generic-negative")
    for ev, end in ((100.0, -1), (-100.0, 0)):
        d = film.develop(film.expose(h, neg, exposure_ev=ev), neg, couplers=False)
        np.testing.assert_allclose(d[0, 0], [lay.density[end] for lay in neg.layers], atol=1e-6)


def test_the_native_functions_refuse_bad_arguments_without_crashing():
    curves = [(0.0, 0.1, [0.1, 0.2, 0.3])]
    with pytest.raises(TypeError, match="float32"):
        _native.film_develop(np.ones((2, 2, 1)), 1.0, curves, [0.0], 0.0)
    with pytest.raises(ValueError, match="strictly monotone"):
        _native.film_develop(
            np.ones((2, 2, 1), np.float32), 1.0, [(0.0, 0.1, [0.2, 0.2])], [0.0], 0.0
        )
    with pytest.raises(ValueError, match="too strong"):
        _native.film_develop(
            np.ones((2, 2, 1), np.float32), 1.0, [(0.0, 0.1, [0.0, 0.5])], [5.0], 0.0
        )
    with pytest.raises(ValueError, match="shape"):
        _native.film_transmit(np.ones((2, 2, 2), np.float32), [0.0, 0.0], [1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="response"):
        _native.film_transmit(np.ones((2, 2, 1), np.float32), [0.0, 0.0], [1.0, 1.0], [1.0])
    one = np.ones((2, 2, 1), np.float32)
    with pytest.raises(ValueError, match=r"print light must be finite and >= 0; layer 0"):
        _native.film_print(one, [0.0], [1.0], [-1.0], curves, [0.0], 0.0, 1.0)
    with pytest.raises(ValueError, match=r"print light must be \(paper layers"):
        _native.film_print(one, [0.0], [1.0], [1.0, 1.0], curves, [0.0], 0.0, 1.0)
    with pytest.raises(ValueError, match="halation of 2 layers for an emulsion of 1"):
        _native.film_develop(one, 1.0, curves, [0.0], 0.0, ([0.1, 0.1], 2.0))
    with pytest.raises(ValueError, match="halation strengths"):
        _native.film_develop(one, 1.0, curves, [0.0], 0.0, ([1.5], 2.0))


# --- properties ---------------------------------------------------------------------------


@st.composite
def stocks(draw) -> film.Stock:
    """A one-layer stock of random logistic curve, gamma of either sign."""
    fog = draw(st.floats(0.0, 0.5))
    span = draw(st.floats(0.5, 3.0))
    # |gamma| / span <= 2 keeps the logistic strictly monotone in float64 over
    # the 5 log units sampled (steeper curves are flat at their ends: refused).
    gamma = draw(st.floats(0.15, 2.0)) * span * draw(st.sampled_from([-1, 1]))
    x0 = draw(st.floats(-2.0, 0.0))
    wl = sp.wavelengths(400, 700, 20)
    x = np.round(np.arange(-3.5, 1.5001, 0.01), 6)
    layer = film.Layer(
        name="pan",
        log_sensitivity=np.zeros_like(wl),
        log_exposure=x,
        density=film.logistic_curve(x, fog, fog + span, gamma, x0),
        dye_density=np.ones_like(wl),
        mask_density=np.zeros_like(wl),
    )
    return film.Stock(
        name="drawn",
        kind="reversal" if gamma < 0 else "negative",
        description="",
        wavelengths=wl,
        layers=(layer,),
        base_density=np.full_like(wl, draw(st.floats(0.0, 0.3))),
        balance_kelvin=5500.0,
        # A coupler c inhibits by c D(x), so the pre-corrected curve exists only
        # while x - c D(x) rises: c |gamma| < 1 (stronger ones are refused).
        coupler_matrix=np.array([[draw(st.floats(0.0, min(0.3, 0.9 / abs(gamma))))]]),
        coupler_diffusion_um=draw(st.floats(0.0, 20.0)),
        halation=np.array([draw(st.floats(0.0, 0.2))]),
        halation_um=50.0,
        rms_granularity=np.zeros(1),
    )


@given(stocks(), st.lists(st.floats(-12, 4), min_size=2, max_size=12))
def test_development_is_monotone_bounded_and_deterministic(stock, log_h):
    h = np.sort(10.0 ** np.array(log_h, np.float32))[None, :, None].astype(np.float32)
    d = film.develop(h, stock, frame_width_mm=1e3)  # wide pixels: no diffusion across them
    layer = stock.layers[0]
    sign = -1 if stock.kind == "reversal" else 1
    assert (sign * np.diff(d[0, :, 0]) >= -1e-6).all()
    assert layer.density.min() - 1e-6 <= d.min() and d.max() <= layer.density.max() + 1e-6
    np.testing.assert_array_equal(d, film.develop(h, stock, frame_width_mm=1e3))
    t = film.transmittance(d, stock)
    assert (t >= 0).all() and (t <= 10.0 ** -stock.base_density.min() * (1 + 1e-6)).all()


def test_the_cli_writes_a_print_of_each_image_and_reports_bad_files(tmp_path, capsys):
    import imageio.v3 as iio

    from imgform_rs import cli

    img = (np.random.default_rng(2).random((24, 32, 3)) * 255).astype(np.uint8)
    iio.imwrite(tmp_path / "scene.png", img)
    (tmp_path / "broken.png").write_bytes(b"not a png")
    code = cli.main(
        [
            "film",
            str(tmp_path / "scene.png"),
            str(tmp_path / "broken.png"),
            "-o",
            str(tmp_path / "o"),
        ]
    )
    assert code == 1
    written = (tmp_path / "o" / "scene.png").read_bytes()
    assert written[24] == 16  # IHDR bit depth (Pillow would read it back as 8 bits)
    assert iio.imread(tmp_path / "o" / "scene.png").shape == (24, 32, 3)
    assert "broken.png" in capsys.readouterr().err
    assert cli.main(["film", str(tmp_path / "scene.png"), "-o", str(tmp_path), "--stock", "x"]) == 2


def test_the_film_cli_keeps_outputs_unless_asked_and_refuses_clashing_names(tmp_path, capsys):
    import imageio.v3 as iio

    from imgform_rs import cli

    img = (np.random.default_rng(3).random((16, 24, 3)) * 255).astype(np.uint8)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    iio.imwrite(tmp_path / "a" / "x.png", img)
    iio.imwrite(tmp_path / "b" / "x.tif", img)
    out = tmp_path / "o"
    out.mkdir()
    (out / "x.png").write_bytes(b"kept")
    assert cli.main(["film", str(tmp_path / "a" / "x.png"), "-o", str(out)]) == 0
    assert (out / "x.png").read_bytes() == b"kept" and "kept" in capsys.readouterr().out
    assert cli.main(["film", str(tmp_path / "a" / "x.png"), "-o", str(out), "--overwrite"]) == 0
    assert iio.imread(out / "x.png").shape == (16, 24, 3)
    clash = [str(tmp_path / "a" / "x.png"), str(tmp_path / "b" / "x.tif")]
    assert cli.main(["film", *clash, "-o", str(tmp_path / "new"), "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "overwrite each other" in err and not (tmp_path / "new").exists()
    assert cli.main(["film", clash[0], "-o", str(tmp_path / "a" / "x.png")]) == 2
    assert "is a file" in capsys.readouterr().err


# --- halation and grain -------------------------------------------------------------------


def test_halation_conserves_energy_and_glows_red_first():
    stock = film.load_stock("generic-negative")
    h = np.zeros((81, 81, 3), np.float32)
    h[40, 40] = 50.0
    spread = film._native.film_halation(h, stock.halation.tolist(), 5.0)
    np.testing.assert_allclose(spread.sum(axis=(0, 1)), h.sum(axis=(0, 1)), rtol=1e-5)
    # A highlight on black: around it the red layer gains the most density.
    scene = np.full((81, 81, 3), 1e-3, np.float32)
    scene[38:43, 38:43] = 1.0
    frame = 81 * stock.halation_um / 5.0 / 1000  # the spread is 5 px
    on = film.develop(film.expose(scene, stock), stock, frame_width_mm=frame)
    off = film.develop(film.expose(scene, stock), stock, halation=False, frame_width_mm=frame)
    gain = (on - off)[40, 48]
    assert gain[0] > gain[1] > gain[2] >= 0, gain


@pytest.mark.parametrize("name", ["generic-negative", "generic-reversal", "generic-bw-pan"])
def test_rms_granularity_at_density_one_is_the_stock_parameter(name):
    stock = film.load_stock(name)
    h = np.empty((256, 256, len(stock.layers)), np.float32)
    for i, layer in enumerate(stock.layers):
        order = np.argsort(layer.density)
        x = np.interp(1.0, layer.density[order], layer.log_exposure[order])
        h[..., i] = 10.0**x
    pixel_um = 6.0  # a 36 mm frame 6000 px wide
    frame = 256 * pixel_um / 1000
    # Couplers off: each layer is exposed on its own to reach density 1.
    d = film.develop(h, stock, couplers=False, grain=True, seed=5, frame_width_mm=frame)
    per_pixel = d.reshape(-1, d.shape[-1]).std(axis=0)
    np.testing.assert_allclose(d.mean(axis=(0, 1)), 1.0, atol=2e-3)
    np.testing.assert_allclose(per_pixel, film.pixel_granularity(stock, pixel_um), rtol=0.1)
    # Through 8 x 8 pixels (a 48 µm square, 2304 µm²) Selwyn's law gives the
    # stock's figure for the 48 µm circle (1810 µm²) scaled by the areas.
    blocks = d.reshape(32, 8, 32, 8, -1).mean(axis=(1, 3)).reshape(-1, d.shape[-1]).std(axis=0)
    want = stock.rms_granularity * np.sqrt(np.pi * 24**2 / 48**2)
    np.testing.assert_allclose(blocks, want, rtol=0.1)
    again = film.develop(h, stock, couplers=False, grain=True, seed=5, frame_width_mm=frame)
    np.testing.assert_array_equal(d, again)
    other = film.develop(h, stock, couplers=False, grain=True, seed=6, frame_width_mm=frame)
    assert not np.array_equal(d, other)


def test_the_film_cli_refuses_integer_images_of_no_agreed_white(tmp_path, capsys):
    tifffile = pytest.importorskip("tifffile")
    from imgform_rs import cli

    tifffile.imwrite(tmp_path / "deep.tif", np.full((8, 8, 3), 1000, np.int32), photometric="rgb")
    assert cli.main(["film", str(tmp_path / "deep.tif"), "-o", str(tmp_path / "o")]) == 1
    assert "8- or 16-bit or float images, got int32" in capsys.readouterr().err
    assert list((tmp_path / "o").iterdir()) == []


def test_the_film_cli_reads_a_cmyk_jpeg_and_an_exif_turn_as_they_are_seen(tmp_path, capsys):
    from PIL import Image

    from imgform_rs import cli

    rng = np.random.default_rng(3)
    rgb = np.repeat(np.repeat(rng.integers(0, 256, (6, 8, 3), np.uint8), 8, 0), 8, 1)
    Image.fromarray(rgb).save(tmp_path / "rgb.png")
    Image.fromarray(rgb).convert("CMYK").save(tmp_path / "cmyk.jpg", quality=95)
    turned = Image.fromarray(rgb)
    exif = turned.getexif()
    exif[0x0112] = 6  # shown turned 90 degrees clockwise
    turned.save(tmp_path / "turned.jpg", exif=exif, quality=95)
    out = tmp_path / "o"
    names = ["rgb.png", "cmyk.jpg", "turned.jpg"]
    assert cli.main(["film", *(str(tmp_path / n) for n in names), "-o", str(out)]) == 0
    base, cmyk, turned_out = (np.asarray(Image.open(out / f"{Path(n).stem}.png")) for n in names)
    # Before: C, M, Y read as R, G, B (the red channel's correlation was -0.94),
    # and the turned photograph came out lying on its side.
    assert np.corrcoef(base[..., 0].ravel(), cmyk[..., 0].ravel())[0, 1] > 0.9
    assert turned_out.shape[:2] == base.shape[1::-1]
    assert np.corrcoef(np.rot90(base, -1)[..., 1].ravel(), turned_out[..., 1].ravel())[0, 1] > 0.9


@pytest.mark.parametrize(
    ("options", "match"),
    [
        (["--ev", "nan"], "argument --ev: must be a finite number of stops"),
        (["--ev", "1e9"], "argument --ev: must be a finite number of stops"),
        (["--stock", "generic-paper"], "is a paper: simulate takes a negative or reversal"),
        (["--paper", "generic-negative"], "needs a negative and a paper"),
        (["--stock", "generic-reversal", "--paper", "generic-paper"], "viewed directly"),
    ],
)
def test_the_film_cli_refuses_bad_options_before_any_image(tmp_path, capsys, options, match):
    """Each was a failure of every image, after its whole simulation, and a
    paper for a slide was silently ignored."""
    from PIL import Image

    from imgform_rs import cli

    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(tmp_path / "a.png")
    out = tmp_path / "o"
    with contextlib.suppress(SystemExit):  # argparse's own refusals exit 2
        assert cli.main(["film", str(tmp_path / "a.png"), "-o", str(out), *options]) == 2
    assert re.search(match, capsys.readouterr().err)
    assert not out.exists()


def test_an_interrupted_command_says_so_in_one_line(tmp_path, capsys, monkeypatch):
    from PIL import Image

    from imgform_rs import cli

    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(tmp_path / "a.png")

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(film, "simulate", interrupt)
    assert cli.main(["film", str(tmp_path / "a.png"), "-o", str(tmp_path / "o")]) == 130
    assert capsys.readouterr().err == "imgform film: interrupted\n"
    assert os.listdir(tmp_path / "o") == []


def test_the_film_cli_takes_a_float_image_s_negatives_as_no_light(tmp_path):
    """The sRGB decoding's power of a negative warned of NaN twice."""
    import warnings

    tifffile = pytest.importorskip("tifffile")
    from imgform_rs import cli

    img = np.linspace(-0.5, 1.0, 8 * 8 * 3, dtype=np.float32).reshape(8, 8, 3)
    tifffile.imwrite(tmp_path / "neg.tif", img, photometric="rgb")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert cli.main(["film", str(tmp_path / "neg.tif"), "-o", str(tmp_path / "o")]) == 0
