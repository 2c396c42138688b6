"""Lens corrections from the lensfun database (imgform_rs.lens): our Rust
maps and gains against lensfunpy's, matching, and develop / CLI integration."""

from __future__ import annotations

import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imgform_rs import develop
from imgform_rs.dng import write_dng
from imgform_rs.lens import LensMatch, LensProfile, find_profile, match_lens
from imgform_rs.raw import load_raw

lf = pytest.importorskip("lensfunpy")

RAW_DIR = Path(__file__).resolve().parents[2] / "shared" / "data" / "raw"
KISS_X4 = RAW_DIR / "canon_eos_kiss_x4_magiclantern_colorchart.dng"

# lensfun's flags without geometry conversion (fisheye -> rectilinear),
# which imgform_rs does not do.
FLAGS = lf.ModifyFlags.DISTORTION | lf.ModifyFlags.TCA | lf.ModifyFlags.VIGNETTING


def _db_sample(per_kind: int = 6) -> list[tuple[object, str]]:
    """Real database entries, a few of every distortion, TCA and vignetting
    model, picked by a fixed stride so the sample is the same every run."""
    from imgform_rs.lens import lens_database

    by_kind: dict[str, list] = {}
    for lens in lens_database().lenses:
        f = lens.min_focal
        if not f:
            continue
        kinds = []
        if (d := lens.interpolate_distortion(f)) is not None:
            kinds.append("distortion-" + d.model.name.lower())
        if (t := lens.interpolate_tca(f)) is not None:
            kinds.append("tca-" + t.model.name.lower())
        if lens.calib_vignetting:
            kinds.append("vignetting-pa")
        for k in kinds:
            by_kind.setdefault(k, []).append(lens)
    sample = []
    for kind, lenses in sorted(by_kind.items()):
        stride = max(1, len(lenses) // per_kind)
        sample += [(lens, kind) for lens in lenses[::stride][:per_kind]]
    return sample


SAMPLE = _db_sample()


def test_the_sample_covers_every_model_of_the_database() -> None:
    kinds = {k for _, k in SAMPLE}
    assert {"distortion-poly3", "distortion-poly5", "distortion-ptlens"} <= kinds
    assert {"tca-linear", "tca-poly3", "vignetting-pa"} <= kinds


def _profile(lens, crop: float, focal: float, aperture: float) -> LensProfile:
    """Our profile of a database entry, as find_profile builds it."""
    from imgform_rs.lens import _aspect_ratios, _crop_key, _model, _name

    vig = lens.interpolate_vignetting(focal, aperture, 10.0)
    return LensProfile(
        lens=_name(lens),
        camera="test",
        crop_factor=crop,
        calibration_crop=lens.crop_factor,
        aspect_ratio=_aspect_ratios()[(lens.maker, lens.model, _crop_key(lens.crop_factor))],
        center=(lens.center_x, lens.center_y),
        focal_length=focal,
        aperture=aperture,
        distance=10.0,
        distortion=_model(lens.interpolate_distortion(focal)),
        tca=_model(lens.interpolate_tca(focal)),
        vignetting=tuple(vig.terms[:3]) if vig is not None else None,
    )


def _setting(i: int, lens) -> tuple[int, int, float, float, float]:
    """Size, crop factor, focal length and aperture varied over the sample:
    landscape, portrait, odd sizes; the camera's crop factor equal to or
    larger than the calibration's (lensfun's rule, see imgform_rs.lens)."""
    w, h = [(97, 64), (64, 97), (120, 90), (81, 81)][i % 4]
    crop = lens.crop_factor * [1.0, 1.3, 0.97][i % 3]
    span = (lens.max_focal or lens.min_focal) - lens.min_focal
    focal = lens.min_focal + span * ((i * 0.37) % 1.0)
    aperture = (lens.min_aperture or 2.8) * 1.4
    return w, h, crop, focal, aperture


def _modifier(lens, crop, w, h, focal, aperture):
    mod = lf.Modifier(lens, crop, w, h)
    mod.initialize(focal, aperture, 10.0, scale=1.0, pixel_format=np.float32, flags=FLAGS)
    return mod


@pytest.mark.parametrize(
    ("i", "entry"),
    [(i, e) for i, e in enumerate(SAMPLE) if e[1].startswith(("distortion", "tca"))],
    ids=lambda v: str(v)[:40],
)
def test_positions_equal_lensfunpy_to_a_hundredth_of_a_pixel(i, entry) -> None:
    lens, _ = entry
    w, h, crop, focal, aperture = _setting(i, lens)
    mod = _modifier(lens, crop, w, h, focal, aperture)
    # One column per call: lensfun's scalar code. Whole rows take its SSE
    # path, whose square roots are 12-bit approximations (see below).
    ref = np.concatenate(
        [mod.apply_subpixel_geometry_distortion(u, 0, 1, h) for u in range(w)], axis=1
    )
    ours = _profile(lens, crop, focal, aperture).positions(w, h)
    assert ours.shape == ref.shape == (h, w, 3, 2)
    assert np.abs(ours - ref).max() < 0.01


def test_lensfuns_sse_rows_differ_only_by_its_square_root_approximation() -> None:
    """Whole-row calls: lensfun's SSE ptlens uses rcp(rsqrt(r²)), good to
    about 3e-4 relative; ours stays within that of the radius."""
    lens = next(lens for lens, k in SAMPLE if k == "distortion-ptlens")
    w, h, crop, focal, aperture = 300, 200, lens.crop_factor, lens.min_focal, 4.0
    ref = _modifier(lens, crop, w, h, focal, aperture).apply_subpixel_geometry_distortion()
    ours = _profile(lens, crop, focal, aperture).positions(w, h)
    radius = np.hypot(ours[..., 0] - (w - 1) / 2, ours[..., 1] - (h - 1) / 2)
    assert np.all(np.abs(ours - ref).max(axis=-1) <= 1e-3 * radius + 1e-3)


@pytest.mark.parametrize(
    ("i", "entry"), [(i, e) for i, e in enumerate(SAMPLE) if e[1] == "vignetting-pa"]
)
def test_vignetting_gains_equal_lensfunpy_to_1e_4(i, entry) -> None:
    lens, _ = entry
    w, h, crop, focal, aperture = _setting(i, lens)
    mod = _modifier(lens, crop, w, h, focal, aperture)
    ref = np.ones((h, w, 3), np.float32)
    assert mod.apply_color_modification(ref)
    ours = _profile(lens, crop, focal, aperture).correct(
        np.ones((h, w, 3), np.float32), geometry=False
    )
    np.testing.assert_allclose(ours, ref, rtol=1e-4)


def _synthetic(**kw) -> LensProfile:
    base = dict(
        lens="test / lens",
        camera="test / camera",
        crop_factor=1.5,
        calibration_crop=1.5,
        aspect_ratio=1.5,
        center=(0.0, 0.0),
        focal_length=20.0,
        aperture=4.0,
        distance=1000.0,
        distortion=None,
        tca=None,
        vignetting=None,
    )
    return LensProfile(**{**base, **kw})


@settings(max_examples=30, deadline=None)
@given(
    k1=st.floats(-0.1, 0.1),
    kr=st.floats(0.995, 1.005),
    w=st.integers(2, 40),
    h=st.integers(2, 40),
)
def test_positions_are_point_symmetric_about_the_centre(k1, kr, w, h) -> None:
    """Radial models about a centred axis: the mirrored pixel reads the
    mirrored position. Up to the interpolation between the exact grid points
    (each position within 0.002 px, see ``positions``): the grid starts at
    pixel 0, so it is not itself symmetric (found by Hypothesis: w=2, h=18,
    k1=2**-9 gave 4.4e-5 px with the 1e-9 this test had)."""
    p = _synthetic(distortion=("poly3", (k1,)), tca=("linear", (kr, 2 - kr)))
    pos = p.positions(w, h)
    mirrored = pos[::-1, ::-1]
    np.testing.assert_allclose(pos[..., 0] + mirrored[..., 0], w - 1, atol=0.004)
    np.testing.assert_allclose(pos[..., 1] + mirrored[..., 1], h - 1, atol=0.004)


def test_a_profile_without_models_changes_nothing() -> None:
    img = np.random.default_rng(1).integers(0, 65535, (30, 40, 3), dtype=np.uint16)
    assert np.array_equal(_synthetic().correct(img), img)
    # Nothing to correct still gives a new array of a checked image: it gave
    # the caller's own array back, strided views and float64 included.
    shaded = _synthetic(distortion=("poly3", (-0.05,)), vignetting=(-0.3, 0.0, 0.0))
    for profile, kwargs in ((_synthetic(), {}), (shaded, dict(geometry=False, vignetting=False))):
        view = img[:, ::2]
        out = profile.correct(view, **kwargs)
        assert out.flags.c_contiguous and not np.shares_memory(out, view)
        np.testing.assert_array_equal(out, view)
        with pytest.raises(TypeError, match="uint8, uint16 or float32"):
            profile.correct(img.astype(np.float64), **kwargs)
    pos = _synthetic().positions(40, 30)
    np.testing.assert_allclose(pos[5, 7, 2], [7, 5], atol=1e-9)


@pytest.mark.parametrize("dtype", [np.float32, np.uint16, np.uint8])
def test_correct_devignettes_in_the_resampling_pass(dtype) -> None:
    """One pass multiplies each sample by the gain at its source position;
    two passes (devignette, then resample) interpolate gained taps. They
    differ by the gain's change across a pixel times the local contrast,
    and integers by one extra rounding."""
    p = _synthetic(
        distortion=("ptlens", (0.0064, -0.0125, -0.0348)),
        tca=("poly3", (1.001, 0.9995, 0.0, 0.0, -0.0003, 0.0003)),
        vignetting=(-0.316, 0.0175, 0.0074),
    )
    h, w = 200, 300
    rng = np.random.default_rng(3)
    full = 1.0 if dtype == np.float32 else np.iinfo(dtype).max
    img = (rng.random((h, w, 3)) * full * 0.6).astype(dtype)
    native = p.native(w, h)
    one = p.correct(img).astype(np.float64)
    two = native.correct_geometry(native.devignette(img, np.zeros((1, 1)))).astype(np.float64)
    gain = p.correct(np.ones((h, w, 3), np.float32), geometry=False)
    step = max(np.abs(np.diff(gain, axis=0)).max(), np.abs(np.diff(gain, axis=1)).max())
    rounding = 0.0 if dtype == np.float32 else 1.0
    assert np.abs(one - two).max() <= 2 * step * full * 0.6 + rounding
    # Not the uncorrected vignetting: the corners do brighten.
    plain = p.correct(img, vignetting=False).astype(np.float64)
    assert one[:20, :20].mean() > 1.2 * plain[:20, :20].mean()


@pytest.mark.parametrize("geometry", [True, False])
def test_correct_writes_into_a_given_output(geometry) -> None:
    p = _synthetic(distortion=("poly3", (-0.02,)), vignetting=(-0.3, 0.0, 0.0))
    img = np.random.default_rng(4).random((30, 40, 3), dtype=np.float32)
    out = np.full_like(img, np.nan)
    got = p.correct(img, geometry=geometry, out=out)
    assert got is out
    np.testing.assert_array_equal(out, p.correct(img, geometry=geometry))
    with pytest.raises(ValueError, match="shape"):
        p.correct(img, geometry=geometry, out=np.empty((30, 41, 3), np.float32))
    with pytest.raises(TypeError, match="dtype"):
        p.correct(img, geometry=geometry, out=np.empty((30, 40, 3), np.uint16))
    with pytest.raises(ValueError, match="C-contiguous"):
        p.correct(img, geometry=geometry, out=np.empty((40, 30, 3), np.float32).transpose(1, 0, 2))


def test_equal_profiles_share_one_native_correction_and_its_grids() -> None:
    """The grids of positions are built once per profile and size; a
    profile with unhashable (list) terms gets a fresh correction, and all
    give the same bits."""
    p = _synthetic(distortion=("poly3", (-0.02,)), vignetting=(-0.3, 0.0, 0.0))
    twin = replace(p)
    assert twin is not p and p.native(40, 30) is twin.native(40, 30)
    assert p.native(41, 30) is not p.native(40, 30)
    listed = replace(p, distortion=("poly3", [-0.02]))
    assert listed.native(40, 30) is not listed.native(40, 30)
    img = np.random.default_rng(5).random((30, 40, 3), dtype=np.float32)
    first = p.correct(img)
    for profile in (p, twin, listed):
        np.testing.assert_array_equal(profile.correct(img), first)
        np.testing.assert_array_equal(
            profile.correct(img, vignetting=False), p.correct(img, vignetting=False)
        )


def test_bad_profiles_and_images_raise_clear_errors() -> None:
    with pytest.raises(ValueError, match="unknown distortion model"):
        _synthetic(distortion=("poly9", (0.1,))).positions(10, 10)
    with pytest.raises(ValueError, match="needs 6 terms"):
        _synthetic(tca=("poly3", (1.0, 1.0))).positions(10, 10)
    with pytest.raises(ValueError, match="crop factor"):
        _synthetic(crop_factor=0.0).positions(10, 10)
    with pytest.raises(ValueError, match=">= 1, got -5 x 10"):
        _synthetic().positions(-5, 10)
    with pytest.raises(MemoryError):  # 447 GiB of positions, not a panic
        _synthetic().positions(100_000, 100_000)
    native = _synthetic(distortion=("poly3", (0.01,))).native(10, 10)
    with pytest.raises(ValueError, match="10x10x3"):
        native.correct_geometry(np.zeros((10, 11, 3), np.uint8))
    with pytest.raises(TypeError, match="uint8, uint16 or float32"):
        native.correct_geometry(np.zeros((10, 10, 3), np.int32))
    for size in [(3.7, 5), (True, 5), (0, 5)]:  # 3.7 was truncated to 3
        with pytest.raises(ValueError, match="width and height must be ints >= 1"):
            _synthetic().native(*size)


# --- matching -----------------------------------------------------------------


def test_a_known_camera_and_lens_match_with_the_candidates_reported() -> None:
    m = find_profile(
        "EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 550D"), focal_length=18, aperture=5.6
    )
    assert m.profile is not None
    assert m.profile.lens == "Canon / Canon EF-S 18-55mm f/3.5-5.6 IS"
    assert m.candidates[0] == m.profile.lens and len(m.candidates) > 1
    assert m.profile.distortion is not None and m.profile.vignetting is not None
    assert "Canon EF-S 18-55mm f/3.5-5.6 IS on Canon / Canon EOS 550D at 18 mm f/5.6" in m.report()


@pytest.mark.parametrize(
    ("lens", "camera", "focal", "why"),
    [
        ("nonexistent lens", "Canon EOS 550D", 18, "not in lensfun; a loose search finds several"),
        (
            "EF-S 18-55mm f/3.5-5.6 IS",
            "Nonexistent X1",
            18,
            "camera 'Canon Nonexistent X1' is not in",
        ),
        ("EF-S 18-55mm f/3.5-5.6 IS", "Canon EOS 5D Mark III", 18, "not in the lensfun database"),
        ("EF-S 18-55mm f/3.5-5.6 IS", "Canon EOS 550D", 300, "outside"),
        ("EF-S 18-55mm f/3.5-5.6 IS", "Canon EOS 550D", 0, "focal length unknown"),
        ("EF-S 18-55mm f/3.5-5.6 IS", "Canon EOS 550D", float("nan"), "focal length unknown"),
        ("EF-S 18-55mm f/3.5-5.6 IS", "No Such Camera 3000", 18, "not in the lensfun database"),
    ],
)
def test_bad_metadata_gives_no_profile_and_says_why(lens, camera, focal, why) -> None:
    m = find_profile(lens, ("Canon", camera), focal_length=focal, aperture=5.6)
    assert m.profile is None
    assert why in m.reason and why in m.report()


def test_the_full_frame_rule_keeps_aps_c_profiles_off_full_frame_cameras() -> None:
    """lensfun's crop-factor rule: the 5D's frame is larger than the EF-S
    lens's calibration sensor."""
    m = find_profile(
        "EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 5D Mark III"), focal_length=18
    )
    assert m.profile is None


def test_a_camera_is_a_name_or_a_maker_and_model_pair() -> None:
    lens, pair = "EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 550D")
    want = find_profile(lens, pair, focal_length=24)
    # A list was read as its repr and matched only loosely.
    assert find_profile(lens, list(pair), focal_length=24) == want
    for bad in [("Canon", "Canon EOS 550D", "x"), ("Canon", 550), 550]:
        with pytest.raises(TypeError, match="camera must be a model's name or a"):
            find_profile(lens, bad, focal_length=24)


def test_without_aperture_vignetting_is_skipped_and_reported() -> None:
    m = find_profile("EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 550D"), focal_length=24)
    assert m.profile is not None and m.profile.vignetting is None
    assert "aperture unknown" in m.report()


@pytest.mark.parametrize(
    ("setting", "why"),
    [
        (dict(aperture=1.0), "does not reach f/1$"),
        (dict(aperture=8.0, distance=0.01), "does not reach f/8 focused at 0.01 m$"),
    ],
)
def test_a_setting_beyond_the_vignetting_calibration_is_reported(setting, why) -> None:
    """It used to drop the vignetting correction without a word."""
    lens, camera = "EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 550D")
    m = find_profile(lens, camera, focal_length=35, **setting)
    assert m.profile is not None and m.profile.vignetting is None
    assert re.search("vignetting skipped: its calibration " + why, m.reason)
    assert find_profile(lens, camera, focal_length=35, aperture=8.0).profile.vignetting


def test_matching_is_deterministic() -> None:
    runs = {
        find_profile("18-55mm", ("Canon", "Canon EOS 550D"), focal_length=30, aperture=8).report()
        for _ in range(3)
    }
    assert len(runs) == 1


# --- develop and the command line ---------------------------------------------

# A Canon EOS 550D with its kit lens at 18 mm f/5.6: lensfun's profile has
# barrel distortion (ptlens), TCA (poly3) and vignetting (pa).
KIT = dict(
    make="Canon",
    model="Canon EOS 550D",
    lens="EF-S 18-55mm f/3.5-5.6 IS",
    focal_length=18.0,
    f_number=8.0,  # exact in float32, as LibRaw reports it
)


def test_a_synthetic_dng_carries_its_camera_and_lens_to_libraw(tmp_path) -> None:
    path = tmp_path / "kit.dng"
    cfa = (900 + np.arange(32 * 48) % 50).astype(np.uint16).reshape(32, 48)
    write_dng(path, cfa, "RGGB", white_level=4095, **KIT)
    raw = load_raw(path)
    assert (raw.make, raw.model, raw.shot.lens) == (KIT["make"], KIT["model"], KIT["lens"])
    assert raw.shot.focal_length == 18 and raw.shot.f_number == 8
    for bad, match in [
        ({"focal_length": -18.0}, "focal_length must be a positive number or 0"),
        ({"f_number": float("nan")}, "f_number must be"),
        ({"lens": "Objectif 18–55"}, "lens must be an ASCII str"),
    ]:
        with pytest.raises(ValueError, match=match):
            write_dng(
                tmp_path / "bad.dng", np.zeros((32, 48), np.uint16), "RGGB", white_level=4095, **bad
            )
    assert not (tmp_path / "bad.dng").exists()


@pytest.fixture(scope="module")
def dng(tmp_path_factory) -> Path:
    """A smooth synthetic mosaic from the Canon EOS 550D (in lensfun)."""
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:96, 0:144]
    cfa = (1200 + 800 * np.sin(x / 9.0) * np.cos(y / 7.0) + rng.normal(0, 4, x.shape)).astype(
        np.uint16
    )
    path = tmp_path_factory.mktemp("lens") / "a.dng"
    write_dng(path, cfa, "RGGB", white_level=4095, black_level=100, model="Canon EOS 550D")
    return path


def _kit(raw, camera: str | None = "Canon EOS 550D") -> LensMatch:
    return match_lens(
        raw, lens="EF-S 18-55mm f/3.5-5.6 IS", camera=camera, focal_length=18, aperture=5.6
    )


def test_develop_applies_geometry_after_the_pipeline_and_vignetting_before(dng) -> None:
    raw = load_raw(dng)
    match = _kit(raw)
    assert match.profile is not None, match.report()
    opts = dict(demosaic="bilinear", tone="linear", bps="float", orientation="none")
    plain = develop(raw, **opts)
    geometry_only = LensProfile(**{**match.profile.__dict__, "vignetting": None})
    # Geometry: exactly our correction of the uncorrected development.
    np.testing.assert_array_equal(
        develop(raw, lens_correction=geometry_only, **opts),
        geometry_only.correct(plain, vignetting=False),
    )
    # Vignetting on the photosites: the corners brighten by the lens's gain.
    vig_only = LensProfile(**{**match.profile.__dict__, "distortion": None, "tca": None})
    out = develop(raw, lens_correction=vig_only, **opts)
    gain = vig_only.correct(np.ones(plain.shape, np.float32))
    inner = (slice(4, -4), slice(4, -4))
    np.testing.assert_allclose(out[inner], np.minimum(plain * gain, 1)[inner], rtol=0.02, atol=2e-3)
    assert gain[0, 0, 0] > gain[48, 72, 0] == pytest.approx(1, abs=1e-3)


def test_a_corrected_develop_does_not_depend_on_the_working_array_kept(dng) -> None:
    # The working array is kept from call to call (per size and sample
    # type) and taken out while a call runs: other sizes, other types and
    # concurrent calls must all find their development, not another's.
    raw = load_raw(dng)
    profile = _kit(raw).profile
    narrow = replace(raw, cfa=np.ascontiguousarray(raw.cfa[:, :100]))
    first = develop(raw, lens_correction=profile)
    cut = develop(narrow, lens_correction=profile)
    assert cut.shape == (96, 100, 3)
    floats = develop(raw, lens_correction=profile, bps="float")
    for _ in range(2):
        np.testing.assert_array_equal(develop(raw, lens_correction=profile), first)
    cases = [(raw, 8, first), (narrow, 8, cut), (raw, "float", floats), (raw, 8, first)] * 2
    with ThreadPoolExecutor(2) as pool:
        runs = [pool.submit(develop, s, lens_correction=profile, bps=b) for s, b, _ in cases]
        for run, (_, _, want) in zip(runs, cases, strict=True):
            np.testing.assert_array_equal(run.result(), want)


def test_develop_auto_without_a_lens_is_uncorrected(dng) -> None:
    raw = load_raw(dng)
    assert match_lens(raw).profile is None
    np.testing.assert_array_equal(develop(raw, lens_correction="auto"), develop(raw))


def test_develop_rejects_bad_lens_options(dng) -> None:
    with pytest.raises(ValueError, match='"auto", "off"'):
        develop(dng, lens_correction="on")
    with pytest.raises(TypeError, match="LensProfile"):
        develop(dng, lens_correction=3)


def test_cli_reports_the_lens_per_file(dng, tmp_path) -> None:
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "imgform_rs.cli",
            "develop",
            str(dng),
            "-o",
            str(tmp_path),
            "--lens",
            "auto",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    # The synthetic file's Make is "imgform-rs": no such camera in lensfun.
    assert "-> " in run.stdout and "; lens correction: none (camera " in run.stdout
    assert "is not in the lensfun database)" in run.stdout
    assert (tmp_path / "a.png").exists()


@pytest.mark.skipif(not KISS_X4.exists(), reason="shared raw data not present")
def test_real_raw_matches_its_camera_and_an_overridden_lens() -> None:
    raw = load_raw(KISS_X4)
    auto = match_lens(raw)
    assert auto.profile is None and "no lens" in auto.reason
    m = _kit(raw, camera=None)
    assert m.profile is not None and m.profile.camera == "Canon / Canon EOS Kiss X4"
    out = develop(raw, lens_correction=m, demosaic="bilinear")
    assert out.shape == develop(raw, demosaic="bilinear").shape


def test_non_square_photosites_are_left_alone_or_refused(tmp_path) -> None:
    cfa = (1500 + np.arange(48 * 64) % 300).astype(np.uint16).reshape(48, 64)
    path = tmp_path / "wide.dng"
    write_dng(path, cfa, "RGGB", white_level=4095, pixel_aspect=2.0, model="Canon EOS 550D")
    raw = load_raw(path)
    assert raw.pixel_aspect != 1
    np.testing.assert_array_equal(develop(raw, lens_correction="auto"), develop(raw))
    profile = _kit(raw).profile
    assert profile is not None
    with pytest.raises(ValueError, match="square photosites"):
        develop(raw, lens_correction=profile)


def test_the_cli_leaves_non_square_photosites_uncorrected_and_says_so(tmp_path, capsys) -> None:
    """A file whose camera and lens lensfun knows, on a sensor with 2:1
    photosites: --lens auto develops it uncorrected (it raised before)."""
    from imgform_rs.cli import main

    cfa = (1500 + np.arange(48 * 64) % 300).astype(np.uint16).reshape(48, 64)
    path = tmp_path / "wide.dng"
    write_dng(path, cfa, "RGGB", white_level=4095, pixel_aspect=2.0, **KIT)
    assert match_lens(load_raw(path)).profile is not None
    assert main(["develop", str(path), "-o", str(tmp_path / "out"), "--lens", "auto"]) == 0
    assert (
        capsys.readouterr().out.rstrip().endswith("; lens correction: none (non-square photosites)")
    )


# --- straight lines: a chessboard captured through a real profile -------------

BOARD_W, BOARD_H, SQUARE = 600, 400, 36
INNER = (13, 9)  # inner corners per row, per column: 14 x 10 squares
DARK, LIGHT = 0.12, 0.72
SUPERSAMPLE = 3  # per axis: each photosite averages 9 points of the scene (2: 0.07 px)


def _board(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The scene: a chessboard centred in the frame on a light surround, in
    corrected (undistorted) pixel coordinates."""
    du, dv = u - (BOARD_W - 1) / 2, v - (BOARD_H - 1) / 2
    on = (np.abs(du) < (INNER[0] + 1) * SQUARE / 2) & (np.abs(dv) < (INNER[1] + 1) * SQUARE / 2)
    dark = (np.floor(du / SQUARE) + np.floor(dv / SQUARE)) % 2 == 0
    return np.where(on & dark, DARK, LIGHT)


def _true_corners() -> np.ndarray:
    """The board's inner corners, (rows * cols, 2) as (x, y) pixels."""
    xs = (BOARD_W - 1) / 2 + SQUARE * (np.arange(INNER[0]) - (INNER[0] - 1) / 2)
    ys = (BOARD_H - 1) / 2 + SQUARE * (np.arange(INNER[1]) - (INNER[1] - 1) / 2)
    return np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)


def _undistort(pos: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The scene a capture point (x, y) sees: where in the corrected frame it
    came from, the inverse of ``pos`` (corrected pixel -> capture position,
    one channel), by fixed-point iteration on its bilinear interpolation,
    which is how the correction samples between pixels too. Barrel
    correction reads inwards, so the capture's outer points come from
    beyond the corrected frame, where ``pos`` is not known: there the
    iteration stalls at the border, and the scene is the surround."""
    from scipy.ndimage import map_coordinates

    u, v = x.copy(), y.copy()
    for _ in range(20):  # the error shrinks ~20x a step: lensfun's slopes are near 1
        pu = map_coordinates(pos[..., 0], [v, u], order=1, mode="nearest")
        pv = map_coordinates(pos[..., 1], [v, u], order=1, mode="nearest")
        error = np.maximum(np.abs(x - pu), np.abs(y - pv))
        u, v = u + (x - pu), v + (y - pv)
        if np.percentile(error, 90) < 1e-6:
            break
    found = error < 1e-4
    h, w = pos.shape[:2]
    beyond = (u < 0) | (u > w - 1) | (v < 0) | (v > h - 1)
    assert np.all(found | beyond)  # converged wherever the frame reaches
    return np.where(found, _board(u, v), LIGHT)


def _capture(profile: LensProfile) -> np.ndarray:
    """The RGGB mosaic the lens makes of the board: each photosite sees the
    scene through its own channel's distortion and TCA, dimmed by the
    vignetting, averaged over its area."""
    pos = profile.positions(BOARD_W, BOARD_H)
    vignetting = profile.correct(np.ones((BOARD_H, BOARD_W, 3), np.float32), geometry=False)
    channel = np.tile(np.array([[0, 1], [1, 2]]), (BOARD_H // 2, BOARD_W // 2))
    rows, cols = np.mgrid[0:BOARD_H, 0:BOARD_W].astype(np.float64)
    light = np.zeros((BOARD_H, BOARD_W))
    offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
    for c in range(3):
        at = channel == c
        for dy in offsets:
            for dx in offsets:
                light[at] += _undistort(pos[..., c, :], cols[at] + dx, rows[at] + dy)
    light /= SUPERSAMPLE**2 * vignetting[..., 0]
    black, white = 256, 4095
    return np.round(black + light * (white - black)).astype(np.uint16)


@pytest.fixture(scope="module")
def chessboard(tmp_path_factory) -> tuple[Path, LensProfile]:
    """A synthetic DNG of the board as the kit lens captures it, with the
    lens, focal length and aperture in its EXIF."""
    match = find_profile(
        KIT["lens"],
        (KIT["make"], KIT["model"]),
        focal_length=KIT["focal_length"],
        aperture=KIT["f_number"],
    )
    assert match.profile is not None and match.profile.distortion is not None, match.report()
    path = tmp_path_factory.mktemp("chess") / "board.dng"
    write_dng(path, _capture(match.profile), "RGGB", white_level=4095, black_level=256, **KIT)
    return path, match.profile


def _corners(rgb: np.ndarray) -> np.ndarray:
    """OpenCV's sub-pixel chessboard corners of a developed picture, as
    (rows, cols, 2) (x, y) pixels."""
    cv2 = pytest.importorskip("cv2")
    grey = np.round(np.clip(rgb.mean(axis=2) / LIGHT, 0, 1) * 255).astype(np.uint8)
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, corners = cv2.findChessboardCornersSB(grey, INNER, flags=flags)
    assert found, "OpenCV found no chessboard"
    return corners.reshape(INNER[1], INNER[0], 2).astype(np.float64)


def _line_residual(corners: np.ndarray) -> float:
    """RMS distance of the corners to the straight line fitted (total least
    squares) through each row and each column of them."""
    squares = []
    for line in [*corners, *corners.transpose(1, 0, 2)]:
        centred = line - line.mean(axis=0)
        squares.append(np.linalg.svd(centred, compute_uv=False)[-1] ** 2)
    return float(np.sqrt(np.sum(squares) / (2 * corners.shape[0] * corners.shape[1])))


def _rms_to_truth(corners: np.ndarray) -> float:
    """RMS distance of the corners to the nearest of the board's true corners."""
    truth = _true_corners()
    off = np.linalg.norm(corners.reshape(-1, 1, 2) - truth[None], axis=-1).min(axis=1)
    return float(np.sqrt(np.mean(off**2)))


def test_the_corrected_chessboards_lines_are_straight(chessboard) -> None:
    path, profile = chessboard
    raw = load_raw(path)
    match = match_lens(raw)
    assert match.profile == profile, match.report()  # the file's EXIF finds its own lens
    opts = dict(tone="linear", bps="float")
    bent = _corners(develop(raw, **opts))
    straight = _corners(develop(raw, lens_correction="auto", **opts))
    # Measured: 0.04 px corrected, 0.72 px as captured (OpenCV's corners of
    # the ideal board alone: 0.006 px).
    assert _line_residual(straight) < 0.1
    assert _line_residual(bent) > 0.5
    # Not only straight: the corners are back where the scene has them
    # (measured: 0.06 px RMS, 0.14 px at worst; as captured 1.6 and 3.1 px).
    assert _rms_to_truth(straight) < 0.1
    assert _rms_to_truth(bent) > 1.0
