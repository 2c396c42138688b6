"""Spectral image formation: grids, data, integration, the sensor, photon transfer."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs.spectral as sp
from conftest import output_with_threads

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    colour = pytest.importorskip("colour")


# --- grids and light -------------------------------------------------------------------


def test_grids_are_checked_with_a_clear_message():
    assert sp.check_wavelengths([380, 385.5, 700]).dtype == np.float64
    for bad, msg in [
        ([500.0], "at least 2"),
        ([500.0, np.nan], "finite"),
        ([500.0, 400.0], "strictly increasing"),
        ([[400.0, 500.0]], "1-D"),
    ]:
        with pytest.raises(ValueError, match=msg):
            sp.check_wavelengths(bad)
    with pytest.raises(ValueError, match="uniform grid"):
        sp.quadrature_weights([400, 410, 415], "riemann")
    with pytest.raises(ValueError, match="quadrature must be"):
        sp.quadrature_weights([400, 410], "simpson")  # type: ignore[arg-type]


@given(st.lists(st.floats(1.0, 50.0), min_size=1, max_size=30), st.floats(200.0, 900.0))
def test_trapezoid_weights_sum_to_the_span_on_any_grid(steps, start):
    wl = start + np.concatenate([[0.0], np.cumsum(steps)])
    w = sp.quadrature_weights(wl)
    assert w.sum() == pytest.approx(wl[-1] - wl[0], rel=1e-12)
    assert (w > 0).all()


def test_blackbody_matches_colour_science_planck_law():
    wl = sp.wavelengths(300, 1000, 5)
    for t in (1000.0, 2856.0, 6504.0, 20000.0):
        ours = sp.blackbody(wl, t)
        # colour takes metres, c1 = 2 pi h c^2 (exitance) and returns
        # W m^-2 sr^-1 m^-1; the same constants.
        theirs = colour.colorimetry.planck_law(
            wl * 1e-9, t, c1=np.pi * 1.191042972e-16, c2=1.438776877e-2
        )
        np.testing.assert_allclose(ours, theirs * 1e-9, rtol=1e-12)
    with pytest.raises(ValueError, match="temperature"):
        sp.blackbody(wl, -5.0)


def test_data_sets_come_from_colour_science_on_any_grid():
    wl = np.array([400.0, 433.3, 560.0, 700.0])
    d65 = sp.illuminant("D65", wl)
    assert d65[2] == pytest.approx(100.0)
    names, refl = sp.colorchecker(wl)
    assert len(names) == 24 and refl.shape == (24, 4)
    sd = colour.SDS_COLOURCHECKERS[sp.COLORCHECKER][names[5]]
    assert refl[5, 1] == pytest.approx(np.interp(433.3, sd.wavelengths, sd.values))
    assert sp.camera_sensitivities(wl=wl).shape == (4, 3)
    with pytest.raises(ValueError, match="unknown illuminant 'D66'"):
        sp.illuminant("D66")
    with pytest.raises(ValueError, match="reaches outside"):
        sp.colorchecker([300.0, 400.0])


# --- integration ------------------------------------------------------------------------


def _chart_radiance(wl):
    _, refl = sp.colorchecker(wl)
    return (refl * sp.illuminant("D65", wl)).astype(np.float32).reshape(4, 6, -1)


def test_integration_equals_colour_science_on_the_colorchecker():
    """colour-science's ``sd_to_XYZ`` ("Integration" method, 5 nm, D65, CIE 1931)
    and ours on the same float32 radiance: equal to 1e-6 relative."""
    shape = colour.SpectralShape(380, 780, 5)
    wl = shape.wavelengths
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    radiance = _chart_radiance(wl)
    k = 100.0 / np.sum(cmfs.values[:, 1] * d65.values * 5.0)
    ours = sp.integrate(radiance, wl, cmfs.values * k, rule="riemann")
    for i, r in enumerate(radiance.reshape(24, -1)):
        # The reflectance whose product with D65 is exactly our float32 radiance.
        sd = colour.SpectralDistribution(r.astype(np.float64) / d65.values, wl)
        theirs = colour.sd_to_XYZ(sd, cmfs, d65, method="Integration", k=k)
        # colour-science 0.4.7 returns k Σ R S x̄ Δλ / 100 when given k (its
        # [0, 1] range); the sum itself is what we compare.
        np.testing.assert_allclose(ours.reshape(24, 3)[i], 100 * theirs, rtol=1e-6, atol=1e-9)


def test_integration_is_exact_against_float64_numpy_and_refuses_bad_input():
    rng = np.random.default_rng(3)
    wl = sp.wavelengths(400, 700, 7.5)
    cube = rng.random((13, 11, len(wl)), dtype=np.float32)
    sens = rng.random((len(wl), 4))
    weighted = sens * sp.quadrature_weights(wl)[:, None]
    want = np.einsum("hwl,lc->hwc", cube.astype(np.float64), weighted)
    np.testing.assert_allclose(sp.integrate(cube, wl, sens), want, rtol=1e-6)
    assert sp.integrate(cube[0], wl, sens).shape == (11, 4)
    assert sp.integrate(cube[0, 0], wl, sens).shape == (4,)
    bad = cube.copy()
    bad[5, 7, 3] = -1.0
    with pytest.raises(ValueError, match=r"row 5, column 7"):
        sp.integrate(bad, wl, sens)
    bad[5, 7, 3] = np.nan
    with pytest.raises(ValueError, match=r"finite and >= 0"):
        sp.integrate(bad, wl, sens)
    with pytest.raises(ValueError, match="grid has 81"):
        sp.integrate(cube, sp.wavelengths(380, 780, 5), np.ones((81, 4)))
    with pytest.raises(ValueError, match=r"sensitivities must have shape \(L, C\)"):
        sp.integrate(cube, wl, sens.T)
    with pytest.raises(ValueError, match="spectral response must be finite"):
        sp.integrate(cube, wl, -sens)
    with pytest.raises(TypeError, match="real numbers"):
        sp.integrate(cube.astype(complex), wl, sens)


def test_integrals_and_rates_beyond_float32_are_refused_not_made_inf():
    wl = sp.wavelengths(400, 700, 100)
    cube = np.ones((2, 3, 4), np.float32)
    cube[1, 2, 1] = 3e38  # finite, but its integral over 100 nm is not
    with pytest.raises(ValueError, match=r"index \(1, 2\) integrates beyond float32"):
        sp.integrate(cube, wl, np.ones((4, 2)))
    with pytest.raises(
        ValueError, match=r"spectra \(float64\) holds 1e\+300.*beyond float32's range"
    ):
        sp.integrate(np.full(4, 1e300), wl, np.ones((4, 2)))
    with pytest.raises(ValueError, match=r"rates \(float64\) holds .*beyond float32's range"):
        _ideal().capture_rates(np.full((2, 2), 1e200), exposure_time=1.0)


# --- sensor -----------------------------------------------------------------------------


def _ideal(**kw):
    base = dict(read_noise=0.0, dark_current=0.0, black_level=0, bit_depth=16, electrons_per_dn=1.0)
    base.update(kw)
    return sp.Sensor(full_well=1e9, **base)


@pytest.mark.parametrize("mean", [0.3, 1.0, 7.0, 10.0, 60.0, 1e3, 1e4, 1e5])
def test_poisson_counts_are_exact_at_every_mean(mean):
    """var/mean = 1 within 2 % (2e5 samples: >= 2.5 standard errors)."""
    per_dn = 2.0 if mean > 3e4 else 1.0
    s = _ideal(electrons_per_dn=per_dn)
    raw = s.capture_rates(np.full((200, 1000), mean, np.float32), exposure_time=1.0, seed=7)
    e = raw.astype(np.float64) * per_dn
    assert e.mean() == pytest.approx(mean, rel=0.01)
    assert e.var(ddof=1) / e.mean() == pytest.approx(1.0, abs=0.02)


def test_frames_do_not_depend_on_the_thread_count():
    code = """
        import sys, numpy as np, imgform_rs.spectral as sp
        s = sp.Sensor(prnu=0.01, dsnu=1.5, column_noise=0.7, pattern_seed=3)
        rates = np.linspace(0, 5e5, 301 * 257, dtype=np.float32).reshape(301, 257)
        sys.stdout.buffer.write(s.capture_rates(rates, exposure_time=0.02, seed=11).tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


def test_sensor_parameters_are_checked_by_name():
    for kw, msg in [
        (dict(full_well=0.0), "full_well must be"),
        (dict(prnu=1.0), "prnu must be"),
        (dict(bit_depth=17), "bit_depth must be"),
        (dict(black_level=20_000), "black_level must be below"),
        (dict(read_noise=np.nan), "read_noise must be"),
    ]:
        with pytest.raises(ValueError, match=msg):
            sp.Sensor(**kw)
    with pytest.raises(ValueError, match="exposure_time"):
        sp.Sensor().capture_rates(np.ones((2, 2), np.float32), exposure_time=0.0)
    # The rate and its value are named, not a spectrum "at every wavelength".
    with pytest.raises(
        ValueError, match=r"rates must be .* \(e-/s\); pixel \(row 1, column 0\) is -3"
    ):
        sp.Sensor().capture_rates(np.array([[1.0, 2.0], [-3.0, 4.0]]), exposure_time=1.0)
    with pytest.raises(ValueError, match=r"rates must .*pixel \(row 0, column 1\) is NaN"):
        sp.Sensor().capture_rates(np.array([[1.0, np.nan]]), exposure_time=1.0)
    with pytest.raises(ValueError, match=r"shape \(H, W\)"):
        sp.Sensor().capture_rates(np.ones(4, np.float32), exposure_time=1.0)


def test_the_default_sensor_records_its_whole_full_well():
    """The ADC spans the documented 20 000 e- well: a pixel past it reads the
    well's level, 20 000 / 1.28 = 15 625 DN above the black level, below the
    white level 16 383 (at 1.25 e-/DN the ADC clipped at 19 839 e-)."""
    s = sp.Sensor(read_noise=0.0, dark_current=0.0)
    assert s.saturation == s.full_well == 20_000.0
    raw = s.capture_rates(np.full((3, 4), 1e6, np.float32), exposure_time=1.0)
    assert (raw == 512 + 15_625).all() and raw.max() < s.white_level


# --- photon transfer --------------------------------------------------------------------


def _ptc_frames(sensor, rate, times, shape=(256, 256)):
    flats, darks = [], []
    ones = np.full(shape, rate, np.float32)
    zeros = np.zeros(shape, np.float32)
    for i, t in enumerate(times):
        flats.append([sensor.capture_rates(ones, exposure_time=t, seed=4 * i + k) for k in (0, 1)])
        darks.append([sensor.capture_rates(zeros, exposure_time=t, seed=4 * i + k) for k in (2, 3)])
    return flats, darks


# The photon-transfer camera: K = 1.25 DN/e-, 4 e- read noise, 12 000 e- full
# well, 3 e- DSNU, 1 % PRNU, no dark current; lit at 1e4 e-/s.
PTC_SENSOR = sp.Sensor(
    full_well=12_000.0,
    read_noise=4.0,
    electrons_per_dn=0.8,
    bit_depth=16,
    black_level=1000,
    dark_current=0.0,
    dsnu=3.0,
    prnu=0.01,
    pattern_seed=5,
)
PTC_RATE = 1e4
# Geometric steps up to the linear range's end, then dense ones across the knee.
PTC_TIMES = np.concatenate([np.geomspace(1e-4, 0.9, 16), np.linspace(1.0, 1.4, 17)])


@pytest.fixture(scope="module")
def ptc_frames():
    return _ptc_frames(PTC_SENSOR, PTC_RATE, PTC_TIMES)


def test_photon_transfer_recovers_gain_read_noise_and_full_well(ptc_frames):
    ptc = sp.photon_transfer(*ptc_frames)
    assert ptc.conversion_gain == pytest.approx(1 / 0.8, rel=0.01)
    assert ptc.read_noise == pytest.approx(4.0, rel=0.03)
    assert ptc.full_well == pytest.approx(12_000.0, rel=0.05)
    assert ptc.dsnu == pytest.approx(3.0, rel=0.1)
    assert ptc.prnu == pytest.approx(0.01, rel=0.1)


def test_photon_transfer_reads_the_read_noise_off_the_shortest_exposure_in_any_order():
    """With dark current, each dark pair's noise grows with its exposure:
    the read noise comes from the shortest one, wherever it is listed
    (3 e- read noise and 50 e-/s x 0.1 s of dark shot noise: sqrt(14) e-)."""
    s = sp.Sensor(read_noise=3.0, dark_current=50.0, electrons_per_dn=1.0, full_well=12_000)
    times = np.linspace(0.1, 14.0, 12)
    flats, darks = _ptc_frames(s, 1000.0, times, shape=(128, 128))
    forward = sp.photon_transfer(flats, darks)
    backward = sp.photon_transfer(flats[::-1], darks[::-1])
    assert forward.read_noise == pytest.approx(np.sqrt(9.0 + 50.0 * 0.1), rel=0.05)
    assert backward.read_noise == pytest.approx(forward.read_noise, rel=1e-12)
    assert backward.dsnu == pytest.approx(forward.dsnu, rel=1e-12)


def test_photon_transfer_refuses_frames_without_photon_noise():
    """No light, or light without shot noise, gives no gain to fit: a
    ValueError saying so, not NaN results."""
    s = sp.Sensor(read_noise=2.0, dark_current=0.0)
    flats, darks = _ptc_frames(s, 0.0, [0.1, 0.2, 0.3], shape=(32, 32))
    with pytest.raises(ValueError, match="no light reached the sensor"):
        sp.photon_transfer(flats, darks)
    # Flats that are the darks lifted by a constant: signal, but no shot
    # noise. Lifted in the order of the darks' variance, the variance peaks
    # at the brightest, so four exposures lie below 70 % of it, all with a
    # variance equal to their darks': K = 0.
    _, darks = _ptc_frames(s, 0.0, np.linspace(0.1, 0.6, 6), shape=(32, 32))
    darks.sort(key=lambda pair: sp.flat_pair_stats(*pair)[1])
    lifted = [tuple(f + np.uint16(100 * (i + 1)) for f in pair) for i, pair in enumerate(darks)]
    with pytest.raises(ValueError, match=r"variance that grows with the signal.*K = 0"):
        sp.photon_transfer(lifted, darks)


def _emva1288_results(frames, tmp_path):
    """emva1288's own loader, reduction and results on our frames, saved as
    .npy files and described as its descriptor parser would: at every
    exposure a dark pair (0 photons) and a bright pair (photons = e-, QE 1);
    the spatial measurement at the exposure our PRNU uses, the brightest
    below 70 % of saturation.

    The series stops once the well is full (5 % past it). emva1288 looks for
    the variance's peak walking back from the brightest exposure and stops
    at the first local maximum; past saturation the variance is flat (read
    noise only) and its noise has local maxima, one of which it would take
    (13 500 e- here, for a 12 000 e- well). EMVA 1288's series, too, ends
    where saturation is reached.
    """
    from emva1288.process import Data1288, LoadImageData, Results1288

    flats, darks = frames
    ptc = sp.photon_transfer(flats, darks)
    spatial = int(np.flatnonzero(ptc.fitted)[np.argmax(ptc.mean[ptc.fitted])])
    images = {"temporal": {}, "spatial": {}}
    through_saturation = PTC_RATE * PTC_TIMES <= 1.05 * PTC_SENSOR.full_well
    for i, t in enumerate(PTC_TIMES[through_saturation]):
        names = {}
        for photons, pair in ((0.0, darks[i]), (float(PTC_RATE * t), flats[i])):
            names[photons] = [f"{i}_{photons}_{k}.npy" for k in range(2)]
            for name, frame in zip(names[photons], pair, strict=True):
                np.save(tmp_path / name, frame)
        images["temporal"][float(t)] = names
        if i == spatial:
            images["spatial"][float(t)] = names
    loaded = LoadImageData(images, path=str(tmp_path), fload=np.load)
    return Results1288(Data1288(loaded.data).data), ptc


def test_emva1288_measures_our_camera_as_photon_transfer_does(ptc_frames, tmp_path, monkeypatch):
    """The EMVA 1288 reference implementation (the emva1288 package) and
    photon_transfer agree within 3 % on the same frames: system gain K,
    temporal dark noise, saturation capacity, DSNU and PRNU."""
    pytest.importorskip("emva1288")
    # emva1288 1.0.2 (the latest release) calls np.asfarray, which NumPy 2
    # removed; this test alone gets the one-line equivalent back, and
    # monkeypatch deletes it again afterwards.
    monkeypatch.setattr(
        np, "asfarray", lambda a, dtype=np.float64: np.asarray(a, dtype=dtype), raising=False
    )
    emva, ptc = _emva1288_results(ptc_frames, tmp_path)
    assert emva.K == pytest.approx(ptc.conversion_gain, rel=0.03)
    assert emva.sigma_d == pytest.approx(ptc.read_noise, rel=0.03)
    assert emva.u_e_sat == pytest.approx(ptc.full_well, rel=0.03)
    assert emva.DSNU1288 == pytest.approx(ptc.dsnu, rel=0.03)
    assert emva.PRNU1288 / 100 == pytest.approx(ptc.prnu, rel=0.03)


# --- RGB -> spectrum ----------------------------------------------------------------------


@given(
    st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
    st.sampled_from([5.0, 10.0]),
)
def test_rgb_round_trips_through_a_reflectance_in_0_1(rgb, step):
    wl = sp.wavelengths(380, 780, step)
    refl = sp.rgb_to_reflectance(rgb, wl)
    assert refl.min() >= 0.0 and refl.max() <= 1.001
    back = sp.reflectance_to_rgb(refl, wl)
    m = sp.XYZ_TO_SRGB
    white = np.linalg.solve(m, np.ones(3))
    de = sp.delta_e2000(np.linalg.solve(m, back), np.linalg.solve(m, np.array(rgb)), white)
    assert de < 1e-3


@pytest.mark.parametrize("wl", [[400.0, 410.0], [380.0, 780.0], sp.wavelengths(380, 780, 25)])
def test_a_grid_that_cannot_carry_srgb_is_refused_by_name(wl):
    with pytest.raises(ValueError, match="too coarse or too narrow to carry sRGB"):
        sp.upsampling_basis(np.asarray(wl))


def test_out_of_gamut_rgb_is_clipped_not_blown_up():
    refl = sp.rgb_to_reflectance([[-0.5, 0.2, 1.0], [0.0, 0.2, 1.0]])
    np.testing.assert_array_equal(refl[0], refl[1])
    with pytest.raises(ValueError, match="finite"):
        sp.rgb_to_reflectance([np.nan, 0, 0])
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\)"):
        sp.rgb_to_reflectance([0.1, 0.2])


def test_fused_rgb_capture_sees_what_the_materialised_spectra_give():
    cam = sp.SpectralCamera()
    wl = cam.wavelengths
    light = sp.luminance_scale(sp.illuminant("D65", wl), wl, 200.0)
    rgb = np.random.default_rng(1).random((5, 7, 3)).astype(np.float32)
    spectra = sp.rgb_to_reflectance(rgb, wl) * light
    np.testing.assert_allclose(
        rgb.astype(np.float64) @ cam.rgb_matrix(light).T, cam.camera_rates(spectra), rtol=2e-6
    )
    raw = cam.capture_rgb(rgb, illuminant_radiance=light, exposure_time=0.01)
    assert raw.shape == (5, 7) and raw.dtype == np.uint16
    with pytest.raises(TypeError, match="float32"):
        cam.capture_rgb(rgb.astype(np.float64), illuminant_radiance=light, exposure_time=0.01)


# --- characterisation and the end-to-end chain --------------------------------------------


def test_the_colour_matrix_fit_is_reported_and_the_de2000_variant_improves_it():
    cam = sp.SpectralCamera()
    ls = sp.characterise(cam)
    de = sp.characterise(cam, method="de2000")
    assert ls.delta_e.shape == (24,)
    assert de.mean_delta_e < ls.mean_delta_e
    assert ls.mean_delta_e < 3.0


@pytest.mark.parametrize("method", ["least_squares", "de2000"])
def test_the_fit_keeps_the_cameras_white_on_the_white_and_greys_neutral(method):
    # Before, the free fit left every grey 0.4-1.1 CIEDE2000 off neutral, and
    # AsShotNeutral through it was 0.7 % off the camera's own white.
    cam = sp.SpectralCamera()
    wl = cam.wavelengths
    spd = sp.illuminant("D65", wl)
    white = sp.xyz_weights(wl, spd, cam.rule).sum(axis=0)
    camera_white = cam.camera_rates(spd[None])[0].astype(np.float64)
    fit = sp.characterise(cam, method=method)
    np.testing.assert_allclose(fit.matrix @ camera_white, white, rtol=1e-12)
    _, neutral = sp.dng_color_tags(fit, white)
    np.testing.assert_allclose(neutral, camera_white / camera_white.max(), rtol=1e-9)
    assert fit.delta_e[19:].max() < 0.2  # the five greys below the white
    free = sp.characterise(cam, method=method, preserve_white=False)
    assert free.delta_e[19:].min() > 0.4
    # Not at the chart's expense: the mean is lower, the worst patch (cyan) worse.
    assert fit.mean_delta_e < free.mean_delta_e


def test_a_white_to_preserve_must_be_a_camera_white():
    rgb, xyz = np.eye(3) + 0.1, np.eye(3)
    for bad in ([1.0, 0.0, 1.0], [1.0, np.nan, 1.0], [1.0, 1.0]):
        with pytest.raises(ValueError, match="white_rgb must be the camera's 3 finite values > 0"):
            sp.fit_color_matrix(rgb, xyz, [1.0, 1.0, 1.0], white_rgb=bad)
    with pytest.raises(TypeError, match="preserve_white must be a bool"):
        sp.characterise(sp.SpectralCamera(), preserve_white="no")


def test_colorchecker_scene_to_dng_to_develop_gives_the_chart_colours(tmp_path):
    """Scene -> lens -> sensor -> DNG -> develop: the mean CIEDE2000 of the
    patches against the chart's own (sRGB-clipped) colours stays within the
    matrix fit's own error plus 0.5 for noise, demosaicing and clipping."""
    from imgform_rs import develop

    cam = sp.SpectralCamera(sensor=sp.Sensor(prnu=0.005, dsnu=1.0, pattern_seed=2))
    wl = cam.wavelengths
    spd = sp.illuminant("D65", wl)
    light = sp.luminance_scale(spd, wl, 300.0)
    scene, boxes = sp.colorchecker_scene(wl, light)
    fit = sp.characterise(cam)
    # Auto-exposure: the white patch's brightest channel at 60 % of the full well.
    white_rate = cam.camera_rates(light).max()
    t = 0.6 * cam.sensor.full_well / float(white_rate)
    raw = cam.capture(scene, exposure_time=t, seed=3)
    weights = sp.xyz_weights(wl, spd)
    path = tmp_path / "chart.dng"
    sp.write_dng(path, raw, cam, fit)
    rgb = develop(path, tone="linear", bps="float", demosaic="bilinear")
    got = np.array([rgb[ys, xs][6:-6, 6:-6].reshape(-1, 3).mean(0) for ys, xs in boxes])
    _, refl = sp.colorchecker(wl)
    want = np.clip((refl @ weights) @ sp.XYZ_TO_SRGB.T, 0.0, 1.0)
    got *= want[18, 1] / got[18, 1]  # exposure: the white patch's green
    to_xyz = np.linalg.inv(sp.XYZ_TO_SRGB)
    white = weights.sum(axis=0)
    de = sp.delta_e2000(got @ to_xyz.T, want @ to_xyz.T, white)
    assert de.mean() < fit.mean_delta_e + 0.5, (de.mean(), fit.mean_delta_e)


def test_cos4_falloff_is_the_fourth_power_of_the_chief_ray_cosine():
    falloff = sp.cos4_falloff(9, 13, focal_length=10.0, pixel_pitch=900.0, center=(3.0, 5.0))
    rows, cols = np.mgrid[0:9, 0:13]
    theta = np.arctan(np.hypot(cols - 3.0, rows - 5.0) * 0.9 / 10.0)
    assert falloff.dtype == np.float32 and falloff[5, 3] == 1.0
    np.testing.assert_allclose(falloff, np.cos(theta) ** 4, rtol=1e-6)
    with pytest.raises(ValueError, match="focal_length must be"):
        sp.cos4_falloff(2, 2, focal_length=0.0, pixel_pitch=4.0)
    with pytest.raises(ValueError, match="height and width"):
        sp.cos4_falloff(0, 2, focal_length=50.0, pixel_pitch=4.0)


def test_a_focal_length_applies_the_cos4_falloff_inside_the_capture():
    """The fused falloff reads the frame that the falloff image gives:
    the same seeds, means equal to float32 rounding, so the frames match
    except where that rounding moves a Poisson draw (rare)."""
    wl = sp.wavelengths()
    cam = sp.SpectralCamera(wl, focal_length=0.15)
    flat = sp.SpectralCamera(wl)
    light = sp.luminance_scale(sp.illuminant("D65", wl), wl, 300.0)
    rgb = np.random.default_rng(4).random((40, 56, 3), dtype=np.float32)
    falloff = sp.cos4_falloff(40, 56, focal_length=0.15, pixel_pitch=4.0)
    assert falloff.min() < 0.35
    cube = (sp.rgb_to_reflectance(rgb, wl) * light).astype(np.float32)
    for fused, reference in [
        (
            cam.capture(cube, exposure_time=0.01, seed=5),
            flat.capture(cube * falloff[..., None], exposure_time=0.01, seed=5),
        ),
        (
            cam.capture_rgb(rgb, illuminant_radiance=light, exposure_time=0.01, seed=5),
            flat.sensor.capture_rates(
                _mosaic(flat.rgb_matrix(light), rgb) * falloff, exposure_time=0.01, seed=5
            ),
        ),
    ]:
        assert np.mean(fused != reference) < 0.01
        undimmed = flat.capture(cube, exposure_time=0.01, seed=5).mean() - 512
        assert fused.mean() - 512 < 0.8 * undimmed
    with pytest.raises(ValueError, match="focal_length must be None or"):
        sp.SpectralCamera(focal_length=0.0)


def _mosaic(matrix, rgb):
    """Mean rates (e-/s) of an RGGB mosaic of ``rgb`` seen through ``matrix``."""
    rates = np.clip(rgb, 0, None).astype(np.float64) @ matrix.T
    channel = np.zeros(rgb.shape[:2], np.intp)
    channel[0::2, 1::2] = channel[1::2, 0::2] = 1
    channel[1::2, 1::2] = 2
    return np.take_along_axis(rates, channel[..., None], -1)[..., 0].astype(np.float32)


@pytest.mark.parametrize("pattern", ["GBRG", "XTRANS"])
def test_the_cube_capture_reads_each_pixel_through_its_own_filter(pattern):
    """Every pixel of an (H, W, L) capture is a Poisson count of its own CFA
    channel's mean, for a Bayer phase and X-Trans alike, on a width that is
    no multiple of the kernels' eight lanes; the neighbouring channel's mean
    would miss most pixels, so a wrong channel cannot pass."""
    from imgform_rs.cfa import pattern_cells

    wl = sp.wavelengths()
    cam = sp.SpectralCamera(wl, pattern=pattern, sensor=_ideal())
    rgb = np.random.default_rng(6).random((29, 37, 3), dtype=np.float32)
    cube = (sp.rgb_to_reflectance(rgb, wl) * sp.illuminant("D65", wl)).astype(np.float32)
    rates = cam.camera_rates(cube).astype(np.float64)
    t = 3e4 / rates.max()
    tile = pattern_cells(pattern).astype(np.intp)
    channel = np.tile(tile, (15, 19))[:29, :37]
    raw = cam.capture(cube, exposure_time=t, seed=9).astype(np.float64)

    def within_5_sigma(c):
        mean = np.take_along_axis(rates, c[..., None], -1)[..., 0] * t
        return np.abs(raw - mean) < 5 * np.sqrt(mean) + 1

    assert within_5_sigma(channel).all()
    assert within_5_sigma((channel + 1) % 3).mean() < 0.2


def test_auto_exposure_meters_the_mean_or_a_percentile_and_brackets_in_stops():
    sensor = sp.Sensor(read_noise=0.0, dark_current=0.0, full_well=16_000.0, bit_depth=16)
    rates = np.random.default_rng(3).gamma(2.0, 5_000.0, (200, 300)).astype(np.float32)
    # 16 bits at 1.28 e-/DN reach further than the well: the well saturates.
    assert sensor.saturation == 16_000.0
    assert sp.Sensor(bit_depth=12).saturation == (4095 - 512) * 1.28
    t = sp.auto_exposure(rates, sensor, target=0.18)
    electrons = (sensor.capture_rates(rates, exposure_time=t) - 512.0) * 1.28
    assert electrons.mean() == pytest.approx(0.18 * 16_000, rel=0.01)
    t = sp.auto_exposure(rates, sensor, target=0.9, percentile=99.0)
    electrons = (sensor.capture_rates(rates, exposure_time=t) - 512.0) * 1.28
    assert np.percentile(electrons, 99.0) == pytest.approx(0.9 * 16_000, rel=0.01)
    times = sp.exposure_bracket(t, (-2, 0, 1.5))
    np.testing.assert_allclose(np.array(times) / t, [0.25, 1.0, 2**1.5])
    with pytest.raises(ValueError, match="black"):
        sp.auto_exposure(np.zeros((2, 2)), sensor)
    with pytest.raises(ValueError, match="target"):
        sp.auto_exposure(rates, sensor, target=1.5)
    with pytest.raises(ValueError, match="percentile"):
        sp.auto_exposure(rates, sensor, percentile=101)
    with pytest.raises(ValueError, match="finite values >= 0"):
        sp.auto_exposure(-rates, sensor)
    with pytest.raises(ValueError, match="exposure_time"):
        sp.exposure_bracket(0.0)


def test_the_forward_matrix_takes_balanced_white_to_d50_and_is_written(tmp_path):
    from imgform_rs._tiff import first_tag, tiff_ifds

    cam = sp.SpectralCamera()
    wl = cam.wavelengths
    fit = sp.characterise(cam)
    white = sp.xyz_weights(wl, sp.illuminant("D65", wl)).sum(axis=0)
    forward = sp.dng_forward_matrix(fit, white)
    np.testing.assert_allclose(forward @ np.ones(3), sp.D50_XYZ, rtol=1e-12)
    # Colours other than white: balanced camera RGB -> XYZ (D65) -> Bradford
    # to D50 gives what the forward matrix gives directly.
    _, neutral = sp.dng_color_tags(fit, white)
    _, refl = sp.colorchecker(wl)
    rgb = cam.camera_rates(refl * sp.illuminant("D65", wl))
    balanced = rgb / (np.linalg.inv(fit.matrix) @ white)
    bradford = colour.adaptation.chromatic_adaptation_VonKries(
        rgb @ fit.matrix.T, white, sp.D50_XYZ, transform="Bradford"
    )
    np.testing.assert_allclose(balanced @ forward.T, bradford, rtol=1e-9, atol=1e-12)
    raw = cam.capture(np.zeros((24, 24, len(wl)), np.float32), exposure_time=0.01)
    sp.write_dng(tmp_path / "f.dng", raw, cam, fit)
    written = first_tag(tiff_ifds((tmp_path / "f.dng").read_bytes()), 50964)
    np.testing.assert_allclose(np.reshape(written, (3, 3)), forward, atol=1e-6)
    assert neutral.max() == 1.0


# The Nikon's three peaks are all 1: colour-science scales the light by the
# first of them (red), ours by the channel that responds most (red under A).
# Red's peak lowered, colour-science takes green, as ours does under D55.
@pytest.mark.parametrize(("light", "peaks"), [("A", (1, 1, 1)), ("D55", (0.98, 1, 1))])
def test_the_idt_matrix_reproduces_colour_science_matrix_idt(light, peaks):
    wl = sp.wavelengths(380, 780, 5)
    sens = sp.camera_sensitivities("Nikon 5100 (NPL)", wl) * peaks
    spd = sp.illuminant(light, wl)
    matrix, balance = sp.idt_matrix(wl, sens, spd)
    want, want_balance = colour.matrix_idt(
        colour.characterisation.RGB_CameraSensitivities(sens, wl),
        colour.SpectralDistribution(spd, wl),
    )
    np.testing.assert_allclose(matrix, want, atol=1e-3)
    # Trapezoid sums against colour-science's plain ones: the ends differ.
    np.testing.assert_allclose(balance, want_balance, rtol=1e-4)
    np.testing.assert_allclose(matrix.sum(axis=1), 1.0, atol=1e-12)
    with pytest.raises(ValueError, match="sensitivities must have shape"):
        sp.idt_matrix(wl, sens[:, :2], spd)


def test_the_idt_matrix_does_not_turn_on_the_grid():
    # Before, the light's scale went by the highest sampled peak: the
    # Nikon's tie at 1 flipped between channels, and the first row was
    # (0.56, 0.34, 0.09) on 5 nm and (0.76, 0.21, 0.03) on 10 nm.
    uneven = np.r_[np.arange(380, 600, 5), np.arange(600, 781, 20)].astype(float)
    fits = []
    for wl in (sp.wavelengths(380, 780, 5), sp.wavelengths(), uneven):
        fits.append(sp.idt_matrix(wl, sp.camera_sensitivities(wl=wl), sp.illuminant("D65", wl)))
    for matrix, balance in fits[1:]:
        np.testing.assert_allclose(matrix, fits[0][0], atol=5e-3)
        np.testing.assert_allclose(balance, fits[0][1], rtol=1e-2)


def test_the_idt_matrix_refuses_what_has_no_response():
    wl = sp.wavelengths()
    sens, spd = sp.camera_sensitivities(wl=wl), sp.illuminant("D65", wl)
    blind = sens.copy()
    blind[:, 2] = 0
    # Before: the identity and a white balance of inf, or NaN.
    with pytest.raises(ValueError, match=r"each channel a response > 0, got \[.*, 0\.0\]"):
        sp.idt_matrix(wl, blind, spd)
    with pytest.raises(ValueError, match="each channel a response > 0"):
        sp.idt_matrix(wl, sens, np.zeros(len(wl)))
    with pytest.raises(ValueError, match="sensitivities"):
        sp.idt_matrix(wl, sens * np.nan, spd)
    with pytest.raises(ValueError, match="sensitivities"):
        sp.idt_matrix(wl, -sens, spd)


def test_degenerate_whites_and_patches_are_refused_not_turned_into_nan(tmp_path):
    cam = sp.SpectralCamera()
    wl = cam.wavelengths
    fit = sp.characterise(cam)
    with pytest.raises(ValueError, match=r"illuminant_spd has no luminance"):
        sp.xyz_weights(wl, np.zeros(len(wl)))
    for white in ([np.nan, 1.0, 1.09], [0.95, 0.0, 1.09], [1.0, 1.0]):
        for call in (sp.dng_color_tags, sp.dng_forward_matrix):
            with pytest.raises(ValueError, match="white_xyz must"):
                call(fit, white)
    raw = np.zeros((4, 4), np.uint16)
    with pytest.raises(ValueError, match="white_xyz must be 3 finite values"):
        sp.write_dng(tmp_path / "x.dng", raw, cam, fit, white_xyz=[np.nan, 1.0, 1.09])
    # A white the matrix takes to a negative camera channel has no DNG neutral.
    with pytest.raises(ValueError, match="not > 0 in every channel"):
        sp.dng_color_tags(sp.ColorFit(np.diag([1.0, 1.0, -1.0]), np.zeros(3)), [1, 1, 1])
    xyz = np.random.default_rng(2).uniform(0.05, 0.9, (24, 3))
    grey = np.outer(np.linspace(0.1, 1.0, 24), [1.0, 2.0, 3.0])
    two = np.column_stack([xyz[:, 0], xyz[:, 1], xyz[:, 0] + xyz[:, 1]])
    for rgb, rank in ((np.zeros((24, 3)), 0), (grey, 1), (two, 2)):
        with pytest.raises(ValueError, match=f"camera_rgb has rank {rank}: .*no 3x3 matrix"):
            sp.fit_color_matrix(rgb, xyz, [0.95, 1.0, 1.09])


# --- bad input ----------------------------------------------------------------------------

_WL = sp.wavelengths()
_L = len(_WL)
_CUBE = np.ones((4, 5, _L), np.float32)
_FRAME = np.zeros((2, 2), np.uint16)

BAD_INPUT = {
    "step 0": (lambda: sp.wavelengths(380, 780, 0), "step > 0"),
    "NaN start": (lambda: sp.wavelengths(np.nan, 780, 10), "finite"),
    "a grid other than the camera's": (
        lambda: sp.SpectralCamera().capture(_CUBE[..., :-1], exposure_time=0.01),
        r"one sample per wavelength of the camera's grid \(41, 380-780 nm\)",
    ),
    "rates of another grid": (
        lambda: sp.SpectralCamera().camera_rates(_CUBE[..., :-1]),
        "camera's grid",
    ),
    "negative radiance": (
        lambda: sp.SpectralCamera().camera_rates(-_CUBE),
        r"finite and >= 0 at every wavelength; pixel \(row 0, column 0\)",
    ),
    "sensitivities of zeros": (
        lambda: sp.SpectralCamera(sensitivities=np.zeros((_L, 3))),
        "channel of zeros",
    ),
    "sensitivities one row per channel": (
        lambda: sp.SpectralCamera(sensitivities=np.ones((3, _L))),
        r"sensitivities must have shape \(L, 3\) = \(41, 3\).*got shape \(3, 41\)",
    ),
    "unknown CFA pattern": (lambda: sp.SpectralCamera(pattern="RGBX"), "unknown CFA pattern"),
    "unknown quadrature": (lambda: sp.SpectralCamera(rule="simpson"), "quadrature must be"),
    "NaN luminance": (
        lambda: sp.luminance_scale(np.ones(_L), _WL, np.nan),
        r"luminance must be a finite number >= 0",
    ),
    "negative luminance": (lambda: sp.luminance_scale(np.ones(_L), _WL, -5.0), "luminance"),
    "NaN patches": (
        lambda: sp.fit_color_matrix(np.full((24, 3), np.nan), np.ones((24, 3)), [1, 1, 1]),
        "must be finite",
    ),
    "a white of two values": (
        lambda: sp.fit_color_matrix(np.eye(3), np.eye(3), [1.0, 1.0]),
        "white_xyz must be 3 finite values",
    ),
    "a white without luminance": (
        lambda: sp.delta_e2000([0.2, 0.2, 0.2], [0.2, 0.2, 0.2], [1.0, 0.0, 1.0]),
        "luminance Y > 0",
    ),
    "a white without Z": (  # before: b* = -inf and a difference of NaN
        lambda: sp.xyz_to_lab([0.2, 0.2, 0.2], [1.0, 1.0, 0.0]),
        r"X, Y, Z > 0 .*got \[1\.0, 1\.0, 0\.0\]",
    ),
    "a stack of frames for one": (
        lambda: sp.flat_pair_stats(np.ones((1, 3, 4), np.uint16), np.ones((1, 3, 4), np.uint16)),
        r"frame a must be one frame \(H, W\), got shape \(1, 3, 4\)",
    ),
    "a bracket beyond any time": (  # before: [inf] and [0.0]
        lambda: sp.exposure_bracket(0.01, [0.0, 1100.0]),
        "beyond a finite time > 0",
    ),
    "colours of different shapes": (
        lambda: sp.delta_e2000(np.ones((3, 3)), np.ones((4, 3)), [1, 1, 1]),
        "one shape",
    ),
    "a chart of empty patches": (
        lambda: sp.colorchecker_scene(_WL, np.ones(_L), patch=0),
        "patch must be an int >= 1",
    ),
    "a negative gap": (
        lambda: sp.colorchecker_scene(_WL, np.ones(_L), gap=-1),
        "gap must be an int >= 0",
    ),
    "frames of two sizes": (
        lambda: sp.photon_transfer(
            [(_FRAME, _FRAME)] * 3, [(np.zeros((3, 3), np.uint16),) * 2] * 3
        ),
        r"one shape, got shapes \[\(2, 2\), \(3, 3\)\]",
    ),
    "single frames, not pairs": (
        lambda: sp.photon_transfer([_FRAME] * 3, [_FRAME] * 3),
        "must be a pair",
    ),
    "a NaN optical centre": (
        lambda: sp.cos4_falloff(4, 4, focal_length=50.0, pixel_pitch=4.0, center=(np.nan, 1)),
        "two finite numbers",
    ),
    "a fractional height": (
        lambda: sp.cos4_falloff(4.5, 4, focal_length=50.0, pixel_pitch=4.0),
        "ints > 0",
    ),
    "a fractional bit depth": (lambda: sp.Sensor(bit_depth=14.5), "bit_depth must be an int"),
}


@pytest.mark.parametrize("case", BAD_INPUT)
def test_bad_input_gets_a_clear_error(case):
    call, message = BAD_INPUT[case]
    with pytest.raises(ValueError, match=message):
        call()
