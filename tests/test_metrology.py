import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from metrology_scene import (
    UP,
    Pose,
    algebraic_vanishing_point,
    measure,
    pole_scene,
    random_scenes,
    vp_angle,
)

import imgform_rs as ig
from conftest import output_with_threads

poses = st.builds(
    Pose,
    eye_height=st.floats(0.5, 20.0),
    pitch=st.floats(0.08, 0.7),
    yaw=st.floats(-np.pi, np.pi),
    roll=st.floats(-0.4, 0.4),
    hfov=st.floats(np.deg2rad(35.0), np.deg2rad(100.0)),
)
seeds = st.integers(0, 2**32 - 1)


def scene_for(pose: Pose, seed: int):
    scene = pole_scene(pose, seed)
    assume(scene is not None)
    return scene


@given(poses, seeds)
def test_heights_are_exact_without_noise(pose, seed):
    m = measure(scene_for(pose, seed))
    assert np.all(m.height_errors < 1e-6), m.height_errors
    assert m.camera_height_error < 1e-6
    assert np.all(m.vp_errors < 1e-8), m.vp_errors


@given(poses, seeds)
def test_fitted_horizon_is_the_cameras_vanishing_line(pose, seed):
    scene = scene_for(pose, seed)
    m = measure(scene)
    expected = ig.vanishing_line(scene.camera, UP)
    # Same line, same sign and scale (|roll| < 90 deg, so image up is skywards).
    np.testing.assert_allclose(m.horizon[:2], expected[:2], atol=1e-9)
    np.testing.assert_allclose(m.horizon[2], expected[2], rtol=1e-9, atol=1e-6)


@given(poses, seeds, st.floats(-0.5, 0.5), st.floats(-0.5, 0.5))
def test_an_object_reaching_the_horizon_is_as_tall_as_the_camera_is_high(pose, seed, dx, dz):
    scene = scene_for(pose, seed)
    cam, h = scene.camera, scene.eye_height
    base_w = cam.center * [1.0, 0.0, 1.0] + h * np.array([dx, 0.0, dz]) + 8 * h * _forward(cam)
    top_w = base_w + h * UP
    assume(((top_w @ cam.R.T) + cam.t)[2] > 1e-3)
    base, top = cam.project(base_w), cam.project(top_w)
    horizon = ig.vanishing_line(cam, UP)
    vertical = ig.vanishing_point(cam, UP)
    assert abs(horizon @ [*top, 1.0]) < 1e-6 * (1 + np.abs(top).max())
    ref = (scene.poles[0, :2], scene.poles[0, 2:], scene.heights[0])
    measured = ig.relative_height(horizon, base, top, *ref, vertical_vp=vertical)
    assert measured == pytest.approx(h, rel=1e-6)
    assert ig.camera_height(horizon, *ref, vertical_vp=vertical) == pytest.approx(h, rel=1e-6)


def _forward(cam: ig.Camera) -> np.ndarray:
    """The camera's viewing direction projected on the ground, unit length."""
    f = cam.R[2] * [1.0, 0.0, 1.0]
    return f / np.linalg.norm(f)


def _error_curve(sigmas, n_scenes=12):
    """Median relative height error and median vanishing-point angle per sigma,
    over fixed scenes and noise draws (deterministic)."""
    scenes = random_scenes(n_scenes, seed=2024)
    curve = []
    for sigma in sigmas:
        ms = [measure(s, sigma, seed=i) for i, s in enumerate(scenes)]
        curve.append(
            (
                np.median(np.concatenate([m.height_errors for m in ms])),
                np.median(np.concatenate([m.vp_errors for m in ms])),
            )
        )
    return np.array(curve)


def test_noise_degrades_heights_and_vanishing_points_smoothly():
    curve = _error_curve([0.0, 0.25, 0.5, 1.0])
    heights, angles = curve[:, 0], curve[:, 1]
    assert heights[0] < 1e-9 and angles[0] < 1e-9
    # Monotone in sigma and close to linear (first-order error propagation):
    # doubling the noise roughly doubles the errors.
    assert np.all(np.diff(heights) > 0) and np.all(np.diff(angles) > 0)
    for errors in (heights, angles):
        assert 1.3 < errors[2] / errors[1] < 3.0
        assert 1.3 < errors[3] / errors[2] < 3.0
    # Half a pixel of noise on every end point costs about a percent.
    assert heights[2] < 0.03, heights
    assert angles[2] < np.deg2rad(0.5), angles


def test_end_point_residual_beats_the_algebraic_fit():
    """With end-point noise, the end-point distance (ours) weighs segments
    as the noise does; the algebraic fit of the lines does not. Over 40
    scenes its median angular error is ~3x ours."""
    rng = np.random.default_rng(0)
    ours, peer = [], []
    for scene in random_scenes(20, seed=11):
        for segs, d in zip(scene.ground, scene.directions, strict=True):
            noisy = segs + rng.normal(0.0, 1.0, segs.shape)
            truth = ig.vanishing_point(scene.camera, d).homogeneous
            fit = ig.fit_vanishing_point(noisy, threshold=10.0)
            ours.append(vp_angle(scene.camera, fit.homogeneous, truth))
            peer.append(vp_angle(scene.camera, algebraic_vanishing_point(noisy), truth))
    assert np.median(ours) < 0.6 * np.median(peer), (np.median(ours), np.median(peer))


def _towards(vp, starts, length=80.0):
    starts = np.asarray(starts, dtype=float)
    d = np.asarray(vp) - starts
    ends = starts + length * d / np.linalg.norm(d, axis=1, keepdims=True)
    return np.hstack([starts, ends])


@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.4))
def test_outliers_are_rejected(seed, outlier_fraction):
    rng = np.random.default_rng(seed)
    vp = rng.uniform(-2000, 2000, 2)
    inliers = _towards(vp, rng.uniform(0, 640, (30, 2)))
    n_out = int(outlier_fraction * 30 / (1 - outlier_fraction))
    outliers = rng.uniform(0, 640, (n_out, 4))
    segs = np.vstack([inliers, outliers])
    # Exact inliers: a tight threshold, so no outlier passes near by chance.
    fit = ig.fit_vanishing_point(segs, threshold=1e-3)
    assert fit.point == pytest.approx(vp, rel=1e-7, abs=1e-6)
    assert fit.inliers[:30].all() and not fit.inliers[30:].any()


def test_many_segments_use_sampled_hypotheses_reproducibly():
    rng = np.random.default_rng(5)
    segs = np.vstack(
        [_towards([900.0, -300.0], rng.uniform(0, 640, (150, 2))), rng.uniform(0, 640, (60, 4))]
    )
    segs[:150] += rng.normal(0, 0.3, (150, 4))
    a = ig.fit_vanishing_point(segs, seed=1)
    b = ig.fit_vanishing_point(segs, seed=1)
    assert a.point.tobytes() == b.point.tobytes()
    assert a.point == pytest.approx([900.0, -300.0], abs=5.0)
    assert a.residual == pytest.approx(0.3, rel=0.3)


def test_results_do_not_depend_on_the_thread_count():
    code = """
        import sys, numpy as np, imgform_rs as ig
        rng = np.random.default_rng(1)
        starts = rng.uniform(0, 640, (300, 2))
        d = np.array([700.0, -200.0]) - starts
        ends = starts + 50 * d / np.linalg.norm(d, axis=1, keepdims=True)
        segs = np.vstack([np.hstack([starts, ends]) + rng.normal(0, 0.5, (300, 4)),
                          rng.uniform(0, 640, (100, 4))])
        fit = ig.fit_vanishing_point(segs, seed=3)
        sys.stdout.buffer.write(fit.homogeneous.tobytes() + fit.inliers.tobytes())
        base = rng.uniform(0, 640, (100_000, 2)) + [0, 300]
        top = base - rng.uniform(1, 100, (100_000, 1)) * [0, 1]
        h = ig.relative_height([0.01, -1, 240], base, top, [300, 400], [300, 350],
                               vertical_vp=[20, 5000])
        sys.stdout.buffer.write(h.tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


def test_parallel_lines_at_infinity():
    segs = [[0, 0, 10, 20], [5, 0, 15, 20], [9, 1, 19, 21]]
    with pytest.raises(ValueError, match=r"parallel in the image.*allow_infinite=True"):
        ig.fit_vanishing_point(segs)
    fit = ig.fit_vanishing_point(segs, allow_infinite=True)
    assert fit.at_infinity and np.isnan(fit.point).all()
    np.testing.assert_allclose(fit.homogeneous, np.array([1.0, 2.0, 0.0]) / np.sqrt(5))
    # A level camera: verticals stay parallel, and heights still work (affine case).
    ref = ([300.0, 315.0], [300.0, 215.0], 2.0)
    h = ig.relative_height([0, -1, 240], [100, 427.5], [100, 340], *ref, vertical_vp=[0, 1, 0])
    assert h == pytest.approx(0.7, rel=1e-12)


@pytest.mark.parametrize("size", [1.0, 1e3, 1e9])
def test_lines_at_infinity_is_a_matter_of_angle_not_of_pixels(size):
    """Two lines of an image ``size`` wide meeting at 1e-8 rad meet at a point
    5e7 widths away; the test was made on pixel coordinates, so at 1000 px
    that point counted as at infinity, and a scaled image changed the answer."""
    for angle, far in ((1e-8, False), (1e-12, True)):
        segs = np.array([[0, 0.4, 1, 0.4], [0, 0.6, 1, 0.6 - np.tan(angle)]]) * size
        fit = ig.fit_vanishing_point(segs, allow_infinite=True)
        assert fit.at_infinity == far
        if not far:
            np.testing.assert_allclose(fit.point / size, [0.2 / angle, 0.4], rtol=1e-6)


def test_vectorised_heights_match_one_by_one():
    rng = np.random.default_rng(0)
    base = rng.uniform(0, 640, (20, 2)) + [0, 300]
    top = base - [0, 40]
    ref = ([300.0, 400.0], [302.0, 350.0], 1.7)
    kw = {"vertical_vp": [320.0, 5000.0]}
    many = ig.relative_height([0.01, -1, 240], base, top, *ref, **kw)
    one = [
        ig.relative_height([0.01, -1, 240], b, t, *ref, **kw)
        for b, t in zip(base, top, strict=True)
    ]
    assert many.shape == (20,) and isinstance(one[0], float)
    np.testing.assert_array_equal(many, one)
    # The scale and sign of the horizon and the vanishing point do not matter.
    again = ig.relative_height([-0.03, 3, -720], base, top, *ref, vertical_vp=[-32.0, -500.0, -0.1])
    np.testing.assert_allclose(again, many, rtol=1e-12)


H = [0.0, -1.0, 240.0]
REF = ([300.0, 315.0], [300.0, 215.0])
UPV = {"vertical_vp": [0, 1, 0]}


@pytest.mark.parametrize(
    ("call", "exc", "match"),
    [
        (lambda: ig.fit_vanishing_point([[0, 0, 1, 1]]), ValueError, "at least 2 segments, got 1"),
        (lambda: ig.fit_vanishing_point(np.zeros((0, 4))), ValueError, "at least 2"),
        (lambda: ig.fit_vanishing_point(np.ones((3, 3))), ValueError, r"\(N, 4\)"),
        (lambda: ig.fit_vanishing_point([["a"] * 4] * 2), TypeError, "real numbers"),
        (
            lambda: ig.fit_vanishing_point([[0, 0, 1, 1], [0, np.nan, 1, 2]]),
            ValueError,
            "finite, segment 1",
        ),
        (
            lambda: ig.fit_vanishing_point([[0, 0, 1, 1], [3, 3, 3, 3]]),
            ValueError,
            "segment 1 has zero length",
        ),
        (
            lambda: ig.fit_vanishing_point([[0, 0, 1, 1], [2, 2, 3, 3]]),
            ValueError,
            "one image line",
        ),
        (
            lambda: ig.fit_vanishing_point([[0, 0, 1, 1], [0, 1, 1, 0]], threshold=0),
            ValueError,
            "threshold must be a finite number > 0",
        ),
        (
            lambda: ig.fit_vanishing_point([[0, 0, 1, 1], [0, 1, 1, 0]], seed=-1),
            ValueError,
            "seed",
        ),
        (lambda: ig.fit_horizon([1, 2], [2, 4, 2]), ValueError, "same point"),
        (lambda: ig.fit_horizon([1, 2, 3, 4], [2, 4]), ValueError, r"pixel \(2,\)"),
        (lambda: ig.fit_horizon([np.inf, 2], [2, 4]), ValueError, "finite"),
        (lambda: ig.fit_horizon([0, 0, 0], [2, 4]), ValueError, "non-zero"),
        (
            lambda: ig.relative_height(H, [5, 240], [5, 200], *REF, **UPV),
            ValueError,
            "object 0 has its base .* on the horizon",
        ),
        (
            lambda: ig.relative_height(
                H, [5, 300], [5, 200], [3, 240], REF[1], vertical_vp=[0, 1, 0]
            ),
            ValueError,
            "the reference has its base .* on the horizon",
        ),
        (
            lambda: ig.relative_height(H, [5, 300], [5, 200], *REF, vertical_vp=[320, 240]),
            ValueError,
            "lies on the horizon",
        ),
        (
            lambda: ig.relative_height(H, [5, 300], [20, 900], *REF, vertical_vp=[20, 900]),
            ValueError,
            "object 0 has its top .* at the vertical vanishing point",
        ),
        (
            lambda: ig.relative_height(
                H, [5, 300], [5, 200], REF[0], REF[0], vertical_vp=[0, 1, 0]
            ),
            ValueError,
            "no vertical extent",
        ),
        (
            lambda: ig.relative_height(H, [5, 300], [5, 200], *REF, 0.0, **UPV),
            ValueError,
            "ref_height must be a finite number > 0",
        ),
        (
            lambda: ig.relative_height(H, [[5, 300]], [5, 200], *REF, **UPV),
            ValueError,
            "same shape",
        ),
        (
            lambda: ig.relative_height(
                H, [[5, 300, 1]], [[5, 200, 1]], *REF, vertical_vp=[0, 1, 0]
            ),
            ValueError,
            r"base must have shape \(N, 2\)",
        ),
        (
            lambda: ig.relative_height(H, [[5, np.nan]], [[5, 200]], *REF, **UPV),
            ValueError,
            "object 0 must have finite coordinates",
        ),
        (
            lambda: ig.relative_height([0, 0], [5, 300], [5, 200], *REF, **UPV),
            ValueError,
            r"horizon must have shape \(3,\)",
        ),
        (
            lambda: ig.camera_height([0, 0, 0], *REF, **UPV),
            ValueError,
            "horizon must be a non-zero",
        ),
        (
            lambda: ig.camera_height(H, *REF, vertical_vp=[np.nan, 1, 0]),
            ValueError,
            "vertical_vp must contain only finite",
        ),
        (lambda: ig.camera_height(H, *REF), TypeError, "vertical_vp"),
    ],
)
def test_bad_input_is_refused_clearly(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


def test_a_horizon_through_points_given_at_any_scale_is_the_same_line():
    a, b = np.array([300.0, 200.0, 1.0]), np.array([900.0, 260.0, 1.0])
    expected = ig.fit_horizon(a, b)
    np.testing.assert_allclose(ig.fit_horizon(a * 1e300, b * 1e300), expected, atol=1e-12)


@pytest.mark.parametrize("scale", [1e160, 1e-200])
def test_a_horizon_of_any_scale_gives_the_same_height(scale):
    # Before: 301.5 m at 1e160 (the horizon normalised to a zero vector) and
    # NaN at 1e-200, where the camera stands 1.5 m high.
    cam = ig.Camera.from_intrinsics(800, 800, 320, 240).look_at([0, 1.5, -10], [0, 0.5, 10])
    horizon = ig.vanishing_line(cam, [0, 1, 0])
    up = ig.vanishing_point(cam, [0, 1, 0])
    base, top = cam.project([2, 0, 5]), cam.project([2, 2, 5])
    want = ig.camera_height(horizon, base, top, 2.0, vertical_vp=up)
    assert want == pytest.approx(1.5)
    got = ig.camera_height(horizon * scale, base, top, 2.0, vertical_vp=up)
    assert got == pytest.approx(want, rel=1e-12)
