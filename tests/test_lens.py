"""Lens corrections from the lensfun database (imgform_rs.lens): our Rust
maps and gains against lensfunpy's, matching, and develop / CLI integration."""

from __future__ import annotations

import subprocess
import sys
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
    mirrored position."""
    p = _synthetic(distortion=("poly3", (k1,)), tca=("linear", (kr, 2 - kr)))
    pos = p.positions(w, h)
    mirrored = pos[::-1, ::-1]
    np.testing.assert_allclose(pos[..., 0] + mirrored[..., 0], w - 1, atol=1e-9)
    np.testing.assert_allclose(pos[..., 1] + mirrored[..., 1], h - 1, atol=1e-9)


def test_a_profile_without_models_changes_nothing() -> None:
    img = np.random.default_rng(1).integers(0, 65535, (30, 40, 3), dtype=np.uint16)
    assert np.array_equal(_synthetic().correct(img), img)
    pos = _synthetic().positions(40, 30)
    np.testing.assert_allclose(pos[5, 7, 2], [7, 5], atol=1e-9)


def test_bad_profiles_and_images_raise_clear_errors() -> None:
    with pytest.raises(ValueError, match="unknown distortion model"):
        _synthetic(distortion=("poly9", (0.1,))).positions(10, 10)
    with pytest.raises(ValueError, match="needs 6 terms"):
        _synthetic(tca=("poly3", (1.0, 1.0))).positions(10, 10)
    with pytest.raises(ValueError, match="crop factor"):
        _synthetic(crop_factor=0.0).positions(10, 10)
    native = _synthetic(distortion=("poly3", (0.01,))).native(10, 10)
    with pytest.raises(ValueError, match="10x10x3"):
        native.correct_geometry(np.zeros((10, 11, 3), np.uint8))
    with pytest.raises(TypeError, match="uint8, uint16 or float32"):
        native.correct_geometry(np.zeros((10, 10, 3), np.int32))


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
        ("nonexistent lens", "Canon EOS 550D", 18, "ambiguous"),
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


def test_without_aperture_vignetting_is_skipped_and_reported() -> None:
    m = find_profile("EF-S 18-55mm f/3.5-5.6 IS", ("Canon", "Canon EOS 550D"), focal_length=24)
    assert m.profile is not None and m.profile.vignetting is None
    assert "aperture unknown" in m.report()


def test_matching_is_deterministic() -> None:
    runs = {
        find_profile("18-55mm", ("Canon", "Canon EOS 550D"), focal_length=30, aperture=8).report()
        for _ in range(3)
    }
    assert len(runs) == 1


# --- develop and the command line ---------------------------------------------


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
