"""Numbers given to the public API: one real number or one integer, never a
str to parse, a bool or None (``_arrays.real`` and ``_arrays.integer``).

Before, ``float()`` parsed strings (``full_well="1e4"`` simulated a sensor),
and other parameters failed deep inside with messages that named nothing
("'<=' not supported between instances of 'int' and 'str'").
"""

from __future__ import annotations

import os
import re
from fractions import Fraction

import numpy as np
import pytest

import imgform_rs as ig
from imgform_rs import film
from imgform_rs import three_colour as tc
from imgform_rs._arrays import integer, real
from imgform_rs.dispersion import Glass, focal_lengths, render_dispersion
from imgform_rs.dng import write_dng
from imgform_rs.lens import find_profile

REALS = [3, 2.5, np.float32(2.5), np.float64(2.5), np.int64(3), np.uint8(3), np.array(2.5)]
INTEGERS = [3, np.int64(3), np.uint16(3), np.array(3)]
NOT_NUMBERS = ["1", b"1", True, np.True_, None, 1j, np.complex64(1), [1.0], np.array([1.0])]


@pytest.mark.parametrize("value", [*REALS, Fraction(5, 2)], ids=repr)
def test_real_takes_every_real_number(value):
    assert real(value, "x") == float(value)


@pytest.mark.parametrize("value", [*NOT_NUMBERS, np.array(True)], ids=repr)
def test_real_names_the_parameter_of_anything_else(value):
    with pytest.raises(TypeError, match=re.escape(f"x must be a real number, got {value!r}")):
        real(value, "x")


def test_an_int_beyond_float64_is_infinite_for_the_range_checks():
    assert real(10**400, "x") == np.inf
    assert real(-(10**400), "x") == -np.inf


@pytest.mark.parametrize("value", INTEGERS, ids=repr)
def test_integer_takes_python_and_numpy_ints(value):
    assert integer(value, "n") == 3
    assert type(integer(value, "n")) is int


@pytest.mark.parametrize("value", [*NOT_NUMBERS, 1.5, 3.0, np.float32(3), np.array(3.0)], ids=repr)
def test_integer_names_the_parameter_of_anything_else(value):
    with pytest.raises(TypeError, match=re.escape(f"n must be an integer, got {value!r}")):
        integer(value, "n")


# --- the public functions ------------------------------------------------------------------

Y, X = np.mgrid[:64, :64]
REF = (np.sin(X / 5.0) + np.cos(Y / 7.0 + X / 11.0)).astype(np.float32)
MOVED = np.roll(REF, (-3, 2), axis=(0, 1))
RGB = np.random.default_rng(0).uniform(0.1, 0.9, (8, 8, 3)).astype(np.float32)
MAP = (np.full((4, 4), 1.5, np.float32), np.full((4, 4), 2.0, np.float32))
K = np.array([[20.0, 0.0, 8.0], [0.0, 20.0, 8.0], [0.0, 0.0, 1.0]])
SEGMENTS = [[0, 0, 100, 50], [0, 100, 100, 100], [0, 200, 100, 150]]
GROUND = {
    "horizon": [0.0, 1.0, -100.0],
    "ref_base": [10.0, 300.0],
    "ref_top": [10.0, 250.0],
    "vertical_vp": [10.0, 1e5],
}
BK7 = Glass.from_abbe(1.5168, 64.17)

PSF = {"n_pixels": 9, "pixel_pitch": 5e-4, "f_number": 4, "wavelength": 5e-4}
SPOT = {"f": 50.0, "f_number": 2.0, "spherical_lsa": 0.3, "n_rays": 11, "image_plane": 49.7}
LENS = {"f": 50.0, "f_number": 2.0, "spherical_lsa": 0.3}
DEFOCUS = {
    "image": np.zeros((8, 8), np.uint8),
    "depth": np.full((8, 8), 1100.0),
    "f": 50.0,
    "N": 2.0,
    "focus_distance": 1000.0,
    "pixel_pitch": 0.1,
}
ALIGN = {"reference": REF, "moving": MOVED, "max_shift": 5}
ECC = {**ALIGN, "motion": "euclidean"}
DISPERSION = {
    "radiance": np.ones((4, 4, 3), np.float32),
    "wavelengths": [500.0, 550.0, 600.0],
    "glass": BK7,
    "f_d": 50.0,
    "N": 2.0,
    "focus_distance": 1000.0,
    "depth": 1100.0,
    "pixel_pitch": 0.01,
}
DNG = {
    "path": os.devnull,  # where nothing lands should a check be missing
    "cfa": np.zeros((32, 32), np.uint16),
    "pattern": "RGGB",
    "white_level": 4095,
}
FILM = {"stock": "generic-negative"}
H = np.full((2, 2, 3), 0.18, np.float32)
SCENE = {"scene": RGB.repeat(5, axis=0).repeat(5, axis=1)}

# (function, valid keyword arguments, the parameter given a non-number)
CASES = [
    *(
        (ig.pupil_psf, PSF, p)
        for p in ("pixel_pitch", "f_number", "wavelength", "defocus", "spherical")
    ),
    *((ig.spot_diagram, SPOT, p) for p in ("f", "f_number", "spherical_lsa", "image_plane")),
    (ig.best_focus, LENS, "f"),
    *((ig.render_defocus, DEFOCUS, p) for p in ("f", "N", "focus_distance", "pixel_pitch")),
    *((ig.align, ALIGN, p) for p in ("max_shift", "crop")),
    *((ig.align, ECC, p) for p in ("max_iterations", "tolerance")),
    (ig.apply_warp, {"image": REF, "matrix": [[1, 0, 0], [0, 1, 0]]}, "fill"),
    (ig.apply_shift, {"image": REF, "shift": (0, 1)}, "fill"),
    (ig.auto_balance, {"rgb": RGB}, "clip"),
    *(
        (ig.simulate_sensor, {"rgb": RGB, "pattern": "RGGB"}, p)
        for p in ("full_well", "read_noise")
    ),
    (ig.project_pinhole, {"points": [1.0, 2.0, 4.0], "f": 2.0}, "f"),
    (ig.project_orthographic, {"points": [1.0, 2.0, 4.0]}, "scale"),
    (ig.Camera.from_fov, {"fov": 1.0, "image_size": (16, 16)}, "fov"),
    *(
        (ig.add_lateral_ca, {"image": RGB, "scale_r": 1.01, "scale_b": 1.0}, p)
        for p in ("scale_r", "fill")
    ),
    (ig.correct_lateral_ca, {"image": RGB, "scale_r": 1.01, "scale_b": 1.0}, "scale_b"),
    (ig.remap, {"image": RGB, "map": MAP}, "fill"),
    (ig.undistort_image, {"image": RGB, "camera_or_K": K, "dist": [-0.1, 0, 0, 0]}, "fill"),
    (ig.fit_vanishing_point, {"segments": SEGMENTS}, "threshold"),
    (ig.camera_height, GROUND, "ref_height"),
    *((Glass.from_abbe, {"n_d": 1.5, "abbe_number": 60.0}, p) for p in ("n_d", "abbe_number")),
    (focal_lengths, {"glass": BK7, "wavelengths": [500.0], "f_d": 50.0}, "f_d"),
    *((render_dispersion, DISPERSION, p) for p in ("f_d", "focus_distance", "pixel_pitch")),
    (find_profile, {"lens": "x", "camera": ("a", "b"), "focal_length": 50.0}, "focal_length"),
    *((write_dng, DNG, p) for p in ("white_level", "orientation", "pixel_aspect", "focal_length")),
    (write_dng, DNG, "f_number"),
    (film.expose, {"image": RGB, **FILM}, "exposure_ev"),
    (film.simulate, {"image": RGB, **FILM}, "exposure_ev"),
    (
        film.print,
        {"density": H, "negative": "generic-negative", "paper": "generic-paper"},
        "exposure_ev",
    ),
    *((film.gaussian, {"wl": [500.0], "peak": 500.0, "width": 10.0}, p) for p in ("peak", "width")),
    *(
        (
            film.logistic_curve,
            {"log_exposure": [0.0], "d_min": 0.1, "d_max": 2, "gamma": 0.6, "x0": 0},
            p,
        )
        for p in ("d_min", "d_max", "gamma", "x0")
    ),
    (film.pixel_granularity, {**FILM, "pixel_um": 5.0}, "pixel_um"),
    (film.develop, {"exposure": H, **FILM}, "frame_width_mm"),
    (film.balance_print, {"negative": "generic-negative", "paper": "generic-paper"}, "grey"),
    *((tc.photograph, SCENE, p) for p in ("margin", "ev_spread")),
]


def _case_id(case) -> str:
    function, _, parameter = case
    return f"{function.__qualname__}-{parameter}"


@pytest.mark.parametrize("case", CASES, ids=_case_id)
@pytest.mark.parametrize("bad", ["2", True], ids=repr)
def test_a_parameter_that_is_no_number_is_a_type_error_naming_it(case, bad):
    function, kwargs, parameter = case
    expected = (
        rf"{re.escape(parameter)} must be (a real number|an integer), got {re.escape(repr(bad))}"
    )
    with pytest.raises(TypeError, match=f"^{expected}$"):
        function(**{**kwargs, parameter: bad})


@pytest.mark.parametrize(
    ("function", "kwargs", "parameter"),
    [
        *((ig.align, ALIGN, p) for p in ("max_shift", "pyramid")),
        (ig.align, ECC, "max_iterations"),
        *((write_dng, DNG, p) for p in ("white_level", "orientation")),
        (tc.photograph, SCENE, "border"),
    ],
    ids=[
        "align-max_shift",
        "align-pyramid",
        "align-max_iterations",
        "write_dng-white_level",
        "write_dng-orientation",
        "photograph-border",
    ],
)
def test_a_count_given_a_float_says_an_integer_is_expected(function, kwargs, parameter):
    """``operator.index`` said "'float' object cannot be interpreted as an
    integer"; ``int()`` truncated 4095.5 to a white level of 4095."""
    for bad in (1.5, 3.0):
        with pytest.raises(TypeError, match=f"^{parameter} must be an integer, got {bad}$"):
            function(**{**kwargs, parameter: bad})


def test_an_entry_of_a_dict_or_pair_is_named():
    with pytest.raises(TypeError, match=r'^exposure_ev\["g"\] must be a real number'):
        tc.photograph(**SCENE, exposure_ev={"r": 0.0, "g": "1", "b": 0.0})
    with pytest.raises(TypeError, match=r'^rotation\["b"\] must be a real number'):
        tc.photograph(**SCENE, rotation={"r": 0.0, "g": 0.0, "b": None})
    with pytest.raises(TypeError, match=r"^center\[1\] must be a real number, got '8'"):
        ig.add_lateral_ca(RGB, 1.01, 1.0, center=(8.0, "8"))


def test_a_matrix_of_strings_is_not_parsed():
    with pytest.raises(TypeError, match="matrix must be an array of real numbers, got dtype <U"):
        ig.apply_warp(REF, [["1", "0", "0"], ["0", "1", "0"]])


def test_film_switches_are_bools_not_any_truthy_value():
    """``"no"`` is truthy: it switched the effect on."""
    xyz = np.full((1, 1, 3), 0.5, np.float32)
    with pytest.raises(TypeError, match=r"^encode must be a bool, got 'no'$"):
        film.to_srgb(xyz, encode="no")
    for switch in ("encode", "couplers", "halation", "grain"):
        with pytest.raises(TypeError, match=rf"^{switch} must be a bool, got 'no'$"):
            film.simulate(RGB, **{switch: "no"})
    exposure = film.expose(RGB, "generic-negative")
    with pytest.raises(TypeError, match=r"^couplers must be a bool, got 0$"):
        film.print(
            film.develop(exposure, "generic-negative"),
            "generic-negative",
            "generic-paper",
            couplers=0,
        )
    np.testing.assert_array_equal(
        film.to_srgb(xyz, encode=np.False_), film.to_srgb(xyz, encode=False)
    )


def test_geometry_switches_are_bools_not_any_truthy_value():
    # "no" is truthy: it inverted the image, refined to subpixels, allowed
    # points at infinity.
    with pytest.raises(TypeError, match=r"^invert must be a bool, got 'no'$"):
        ig.project_pinhole([1.0, 2.0, 4.0], 2.0, invert="no")
    plate = np.random.default_rng(0).random((40, 40)).astype(np.float32)
    with pytest.raises(TypeError, match=r"^subpixel must be a bool, got 'no'$"):
        ig.align(plate, plate, max_shift=2, subpixel="no")
    segments = [[0, 0, 100, 50], [0, 100, 100, 100], [0, 200, 100, 150]]
    with pytest.raises(TypeError, match=r"^allow_infinite must be a bool, got 1$"):
        ig.fit_vanishing_point(segments, allow_infinite=1)


# Each call with a NumPy number, and the plain Python number it equals.
SCALARS = [
    (lambda v: ig.pupil_psf(**{**PSF, "pixel_pitch": v}), np.float32(0.5e-3)),
    (lambda v: ig.pupil_psf(**{**PSF, "n_pixels": v}), np.int64(9)),
    (lambda v: ig.spot_diagram(**{**SPOT, "f": v}).hits, np.int64(50)),
    (lambda v: ig.render_defocus(**{**DEFOCUS, "N": v}), np.array(2.0)),
    (lambda v: ig.align(REF, MOVED, max_shift=v, crop=np.float32(0.125)).shift, np.int64(5)),
    (lambda v: ig.align(REF, MOVED, max_shift=5, pyramid=v).shift, np.array(1)),
    (lambda v: ig.auto_balance(RGB, clip=v), np.float32(0.125)),
    (
        lambda v: ig.simulate_sensor(RGB, "RGGB", full_well=v, read_noise=np.uint8(2)),
        np.int64(1000),
    ),
    (lambda v: ig.project_pinhole([1.0, 2.0, 4.0], v), np.float32(2.5)),
    (lambda v: ig.remap(RGB, MAP, fill=v), np.float32(0.25)),
    (lambda v: film.expose(RGB, "generic-negative", exposure_ev=v), np.float32(1.5)),
    (lambda v: film.develop(H, "generic-negative", frame_width_mm=v), np.int64(36)),
]


@pytest.mark.parametrize(("call", "number"), SCALARS, ids=[repr(n) for _, n in SCALARS])
def test_numpy_scalars_and_0d_arrays_are_the_numbers_they_hold(call, number):
    plain = number.item()
    np.testing.assert_array_equal(call(number), call(plain))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs resource limits of a child process")
@pytest.mark.parametrize(
    "call",
    [
        "ig.demosaic(np.broadcast_to(np.uint8(7), (40000, 40000)), 'RGGB', 'bilinear')",
        "ig.mosaic(np.broadcast_to(np.uint8(7), (25000, 25000, 3)), 'RGGB')",
    ],
)
def test_a_copy_beyond_the_memory_left_is_a_memory_error_not_an_abort(call):
    """A strided view whose contiguous copy cannot be had: Rust's failed
    allocation aborted the interpreter (SIGABRT). Run where the address
    space is capped at 1.5 GB; the views themselves take no memory."""
    import subprocess
    import sys

    code = (
        "import resource, numpy as np, imgform_rs as ig\n"
        "resource.setrlimit(resource.RLIMIT_AS, (1_500_000_000, 1_500_000_000))\n"
        f"try:\n    {call}\nexcept MemoryError as e:\n    print('MemoryError', e)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-500:]
    assert done.stdout.startswith("MemoryError"), done.stdout


def _in_a_child(code: str, timeout: float = 60) -> str:
    """``code`` run in a fresh interpreter capped at 3 GB of address space:
    an abort, a crash or a hang is a failure here, not the end of the run."""
    import subprocess
    import sys

    head = "import resource, numpy as np, imgform_rs as ig, imgform_rs._native as n\n"
    head += "resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))\n"
    done = subprocess.run(
        [sys.executable, "-c", head + code], capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, done.stderr[-800:]
    return done.stdout


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs resource limits of a child process")
@pytest.mark.parametrize(
    ("call", "error"),
    [
        # Each hung, panicked or aborted (the native layer's own callers).
        ("ig.distortion.undistort_points(np.zeros((1, 2)) + 0.3, [0, 0, 1e308, 0, 0])", None),
        ("n.film_halation(np.ones((4, 4, 3), np.float32), [0.1] * 3, 1e9)", "at most 1000"),
        (
            "n.focal_stack(np.ones((4, 4, 1), np.uint8), (3, 0xAAAAAAAAAAAAAAAB), [0.0], [True])",
            "views of equal height",
        ),
        ("n.spectral_integrate(np.ones((2, 2, 0), np.float32), np.ones((3, 0)))", "L >= 1"),
        ("n.field_of_view(np.broadcast_to(0.05, (2**28,)), np.array([1.0]))", "no memory for"),
        (
            "n.simulate_sensor(np.full((2, 2, 3), np.inf, np.float32), 'RGGB', 1e3, 0, 12, 64, 1)",
            "finite values, got inf at row 0, column 0",
        ),
        # Silently wrong: NaN black levels made every sample 0; a matrix was
        # refused as a "spectral response ... at wavelength index 1".
        (
            "n.NativeLensCorrection(8, 8, 1.0, 1.0, 1.0, (0.0, 0.0), 'none', [], 'none', [],"
            " vignetting=(0.1, 0.1, 0.1)).devignette(np.ones((8, 8), np.uint16),"
            " np.full((2, 2), np.nan))",
            "black levels must be finite, got NaN",
        ),
        (
            "n.NativeSensor(exposure_time=0.01, full_well=1e4, read_noise=2.0,"
            " electrons_per_dn=1.0, analog_gain=1.0, black_level=64, bit_depth=12,"
            " dark_current=0.1, temperature=25.0, reference_temperature=25.0,"
            " doubling_temperature=6.0, dsnu=0.01, prnu=0.01, column_noise=0.5, seed=1,"
            " pattern_seed=2).capture_rgb(np.ones((2, 2, 3), np.float32),"
            " np.eye(3) - 0.2 * np.eye(3, k=1), 'RGGB')",
            r"RGB response matrix must be finite and >= 0 .*entry \(0, 1\) is -0.2",
        ),
        (
            "ig.similarity(np.full((9, 9), 3e38, np.float32), np.ones((9, 9), np.float32))",
            r"within ±2\^50",
        ),
    ],
)
def test_the_native_layer_neither_hangs_nor_aborts_on_extreme_input(call, error):
    printed = _in_a_child(
        f"try:\n    print('returned', {call})\nexcept Exception as e:\n"
        "    print(type(e).__name__, e)\n"
    )
    if error is None:
        assert printed.startswith("returned") and "nan" in printed
    else:
        assert re.search(error, printed), printed
