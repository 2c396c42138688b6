"""Spherical aberration: PSFs against the Airy pattern and Marechal, spot
diagrams against the 2/3 rule, convolution against the definition and cv2."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads

WAVELENGTH, N = 0.5e-3, 4.0
LAMBDA_N = WAVELENGTH * N
# Pixels of lambda N / 16: the Airy ring is 19.5 px out, where the parabola
# through the three samples around its minimum is within ~0.4 % of the zero
# (at lambda N / 8 that estimate alone is 1.5 % off, even on the exact pattern).
FINE = {"pixel_pitch": LAMBDA_N / 16, "f_number": N, "wavelength": WAVELENGTH}
# Pixels of lambda N / 4 over 65 px: the crop holds ~99 % of the light even of
# the aberrated PSFs, so normalising each to its crop leaves peak ratios fair.
WIDE = {"n_pixels": 65, "pixel_pitch": LAMBDA_N / 4, "f_number": N, "wavelength": WAVELENGTH}


def first_minimum(profile: np.ndarray) -> float:
    """Sub-pixel position of the first local minimum of a 1-D profile, from
    the parabola through it and its two neighbours."""
    i = next(k for k in range(1, len(profile) - 1) if profile[k] <= profile[k + 1])
    a, b, c = profile[i - 1 : i + 2]
    return i + 0.5 * (a - c) / (a - 2 * b + c)


def rms_wavefront(w020: float, w040: float) -> float:
    """RMS of W020 rho^2 + W040 rho^4 over the unit disc, from the disc means
    <rho^(2k)> = 1 / (k + 1)."""
    mean = w020 / 2 + w040 / 3
    mean_sq = w020**2 / 3 + w020 * w040 / 2 + w040**2 / 5
    return float(np.sqrt(mean_sq - mean**2))


def test_perfect_lens_gives_the_airy_pattern() -> None:
    psf = ig.pupil_psf(n_pixels=49, **FINE)
    ring = first_minimum(psf[24, 24:]) * FINE["pixel_pitch"]
    assert ring == pytest.approx(1.22 * LAMBDA_N, rel=0.02)
    special = pytest.importorskip("scipy.special")
    r = np.arange(1, 25) * FINE["pixel_pitch"]
    v = np.pi * r / LAMBDA_N
    airy = (2 * special.j1(v) / v) ** 2
    np.testing.assert_allclose(psf[24, 25:] / psf[24, 24], airy, atol=0.005)


@settings(max_examples=15)
@given(
    n=st.integers(1, 40),
    pitch_ratio=st.floats(0.05, 3.0),
    defocus=st.floats(-3.0, 3.0),
    spherical=st.floats(-3.0, 3.0),
)
def test_psf_sums_to_one_and_is_centred(
    n: int, pitch_ratio: float, defocus: float, spherical: float
) -> None:
    psf = ig.pupil_psf(
        n_pixels=n,
        pixel_pitch=pitch_ratio * LAMBDA_N,
        f_number=N,
        wavelength=WAVELENGTH,
        defocus=defocus,
        spherical=spherical,
    )
    assert psf.shape == (n, n) and psf.dtype == np.float64
    assert psf.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(psf >= 0)
    # A radially symmetric wavefront gives a PSF symmetric about the centre.
    np.testing.assert_allclose(psf, psf[::-1, ::-1], atol=1e-12)
    np.testing.assert_allclose(psf, psf.T, atol=1e-12)


@pytest.mark.parametrize(
    ("w020", "w040"),
    [(0.0, 0.05), (0.0, 0.1), (0.0, 0.15), (0.05, 0.0), (-0.2, 0.2), (0.03, 0.08)],
)
def test_strehl_follows_marechal_for_small_errors(w020: float, w040: float) -> None:
    reference = ig.pupil_psf(**WIDE)
    psf = ig.pupil_psf(defocus=w020, spherical=w040, **WIDE)
    sigma = rms_wavefront(w020, w040)
    marechal = np.exp(-((2 * np.pi * sigma) ** 2))
    assert ig.strehl_ratio(psf, reference) == pytest.approx(marechal, rel=0.05)


def test_spherical_aberration_makes_focus_asymmetric() -> None:
    def peak(w020: float, w040: float) -> float:
        return float(ig.pupil_psf(defocus=w020, spherical=w040, **WIDE).max())

    # Without spherical aberration, +d and -d defocus blur alike.
    assert peak(0.6, 0.0) == pytest.approx(peak(-0.6, 0.0), rel=1e-9)
    # With it, the side towards the marginal focus (W020 < 0 balancing
    # W040 > 0) is far sharper than the other.
    near, far = peak(-0.6, 0.6), peak(0.6, 0.6)
    assert near > 1.5 * far
    # The sharpest plane is the balanced one, W020 = -W040.
    scan = {d: peak(d, 0.6) for d in (-1.0, -0.8, -0.6, -0.4, -0.2, 0.0)}
    assert max(scan, key=scan.__getitem__) == -0.6


def test_marginal_ray_focus_matches_the_requested_lsa() -> None:
    f, lsa = 50.0, 0.4
    lens = {"f": f, "f_number": 2.0, "spherical_lsa": lsa, "n_rays": 301}
    a = ig.spot_diagram(image_plane=49.0, **lens)
    b = ig.spot_diagram(image_plane=51.0, **lens)
    # Each ray is a straight line: where does it cross the axis?
    x_a, x_b = a.hits[1:, 0], b.hits[1:, 0]
    crossing = 49.0 + 2.0 * x_a / (x_a - x_b)
    u2 = (np.hypot(*a.pupil[1:].T) / (f / 4.0)) ** 2
    np.testing.assert_allclose(crossing, f - lsa * u2, atol=1e-9)
    assert crossing[-1] == pytest.approx(f - lsa, abs=1e-9)
    at_marginal = ig.spot_diagram(image_plane=f - lsa, **lens)
    np.testing.assert_allclose(at_marginal.hits[-1], 0.0, atol=1e-12)


@given(
    f=st.floats(10.0, 200.0),
    n=st.floats(1.0, 16.0),
    lsa_fraction=st.floats(-0.005, 0.005).filter(lambda v: abs(v) > 1e-4),
)
def test_least_rms_plane_is_two_thirds_of_the_lsa(f: float, n: float, lsa_fraction: float) -> None:
    lsa = lsa_fraction * f
    z = ig.best_focus(f=f, f_number=n, spherical_lsa=lsa)
    # Small-angle theory: the RMS spread is least at 2/3 of the LSA; the exact
    # ray geometry moves it by O(LSA / f).
    assert (f - z) / lsa == pytest.approx(2 / 3, abs=0.01)
    lens = {"f": f, "f_number": n, "spherical_lsa": lsa, "n_rays": 4096}
    best = ig.spot_diagram(image_plane=z, **lens).rms_radius
    for dz in (-0.05 * lsa, 0.05 * lsa):
        assert ig.spot_diagram(image_plane=z + dz, **lens).rms_radius > best


def delta(kh: int, kw: int) -> np.ndarray:
    psf = np.zeros((kh, kw))
    psf[kh // 2, kw // 2] = 1.0
    return psf


IMAGES = {
    np.uint8: lambda rng, s: rng.integers(0, 256, s, dtype=np.uint8),
    np.uint16: lambda rng, s: rng.integers(0, 65536, s, dtype=np.uint16),
    np.float32: lambda rng, s: rng.random(s, dtype=np.float32),
}


@pytest.mark.parametrize("dtype", list(IMAGES))
@pytest.mark.parametrize("shape", [(37, 53), (40, 61, 3)])
@pytest.mark.parametrize("ksize", [(1, 1), (5, 7), (65, 65)])
def test_delta_psf_returns_the_image(dtype: type, shape: tuple, ksize: tuple) -> None:
    img = IMAGES[dtype](np.random.default_rng(0), shape)
    out = ig.render_aberrated(img, delta(*ksize))
    assert out.dtype == img.dtype and out.shape == img.shape
    if dtype is np.float32 and ksize == (65, 65):
        # Through the FFT tiles float samples come back to float32 round-off.
        np.testing.assert_allclose(out, img, atol=2e-6)
    else:
        np.testing.assert_array_equal(out, img)


@pytest.mark.parametrize("ksize", [(7, 7), (4, 6), (31, 31), (20, 33)])
@pytest.mark.parametrize("shape", [(120, 97), (64, 150, 3)])
def test_convolution_matches_cv2(ksize: tuple, shape: tuple) -> None:
    cv2 = pytest.importorskip("cv2")
    rng = np.random.default_rng(1)
    img = rng.random(shape, dtype=np.float32)
    psf = rng.random(ksize)
    psf /= psf.sum()
    kh, kw = ksize
    # filter2D correlates: flip the kernel and mirror the anchor.
    anchor = (kw - 1 - kw // 2, kh - 1 - kh // 2)
    want = cv2.filter2D(
        img,
        -1,
        psf[::-1, ::-1].astype(np.float32),
        anchor=anchor,
        borderType=cv2.BORDER_REFLECT_101,
    )
    np.testing.assert_allclose(ig.render_aberrated(img, psf), want, atol=2e-5)
    img8 = (img * 255).astype(np.uint8)
    want8 = cv2.filter2D(
        img8, -1, psf[::-1, ::-1], anchor=anchor, borderType=cv2.BORDER_REFLECT_101
    )
    assert np.abs(ig.render_aberrated(img8, psf).astype(int) - want8).max() <= 1


def test_pupil_psf_blur_keeps_flat_images_flat_and_spreads_points() -> None:
    psf = ig.pupil_psf(spherical=1.0, **WIDE)
    flat = np.full((90, 140, 3), 37, np.uint16)
    np.testing.assert_array_equal(ig.render_aberrated(flat, psf), flat)
    point = np.zeros((101, 101), np.float32)
    point[50, 50] = 1.0
    np.testing.assert_allclose(ig.render_aberrated(point, psf)[18:83, 18:83], psf, atol=1e-6)


def test_non_contiguous_images_are_accepted() -> None:
    img = np.random.default_rng(2).integers(0, 256, (60, 80, 4), dtype=np.uint8)
    view = img[::2, ::-1, :3]
    psf = np.ones((3, 5)) / 15
    np.testing.assert_array_equal(
        ig.render_aberrated(view, psf), ig.render_aberrated(np.ascontiguousarray(view), psf)
    )


def test_results_do_not_depend_on_the_thread_count() -> None:
    code = """
        import sys
        import numpy as np
        import imgform_rs as ig
        psf = ig.pupil_psf(n_pixels=65, pixel_pitch=1e-3, f_number=4, wavelength=0.5e-3,
                           defocus=0.3, spherical=1.5)
        sys.stdout.buffer.write(psf.tobytes())
        rng = np.random.default_rng(3)
        for img in (rng.integers(0, 256, (700, 300, 3), dtype=np.uint8),
                    rng.random((500, 450), dtype=np.float32)):
            for k in (psf, psf[30:35, 30:35]):  # FFT tiles, direct sum
                sys.stdout.buffer.write(ig.render_aberrated(img, k).tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


def test_bad_input_is_refused_clearly() -> None:
    with pytest.raises(ValueError, match="n_pixels must be >= 1"):
        ig.pupil_psf(n_pixels=0, **FINE)
    with pytest.raises(TypeError, match="n_pixels must be an integer"):
        ig.pupil_psf(n_pixels=2.5, **FINE)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="pixel_pitch must be a finite number > 0"):
        ig.pupil_psf(n_pixels=5, pixel_pitch=-1.0, f_number=N, wavelength=WAVELENGTH)
    with pytest.raises(ValueError, match="aliases"):
        ig.pupil_psf(
            n_pixels=5, pixel_pitch=LAMBDA_N, f_number=N, wavelength=WAVELENGTH, oversample=1
        )
    with pytest.raises(ValueError, match="FFT of"):
        ig.pupil_psf(n_pixels=5, spherical=1e4, **FINE)
    with pytest.raises(ValueError, match="spherical_lsa must be smaller than f"):
        ig.spot_diagram(f=50.0, f_number=2.0, spherical_lsa=60.0, n_rays=10, image_plane=50.0)
    with pytest.raises(ValueError, match="n_rays must be in 2"):
        ig.best_focus(f=50.0, f_number=2.0, spherical_lsa=0.1, n_rays=1)
    with pytest.raises(TypeError, match="uint8, uint16 or float32"):
        ig.render_aberrated(np.zeros((4, 4)), delta(1, 1))
    with pytest.raises(ValueError, match="2-D"):
        ig.render_aberrated(np.zeros((4, 4), np.uint8), np.ones((2, 2, 2)))
    with pytest.raises(ValueError, match="psf must contain only finite"):
        ig.render_aberrated(np.zeros((4, 4), np.uint8), [[np.nan]])
    # Finite, but inf in the float32 kernel: the output was all NaN.
    with pytest.raises(ValueError, match="within float32's range, got one of 1e"):
        ig.render_aberrated(np.zeros((3, 3), np.float32), [[1e39]])
    with pytest.raises(TypeError, match="real numbers"):
        ig.render_aberrated(np.zeros((4, 4), np.uint8), [["a"]])
    # Whatever the PSF's size: the FFT tiles would spread it over a tile.
    holed = np.ones((64, 64), np.float32)
    holed[5, 7] = np.inf
    for side in (3, 9):
        with pytest.raises(ValueError, match=r"finite numbers, got inf at index \(5, 7\)"):
            ig.render_aberrated(holed, np.full((side, side), 1 / side**2))
    with pytest.raises(ValueError, match="same shape"):
        ig.strehl_ratio(np.ones((3, 3)), np.ones((3, 4)))
    with pytest.raises(ValueError, match="non-negative"):
        ig.strehl_ratio(-np.ones((3, 3)), np.ones((3, 3)))
