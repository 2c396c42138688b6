import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads

unit = st.floats(-1.0, 1.0)
quaternions = st.tuples(unit, unit, unit, unit).filter(lambda q: np.linalg.norm(q) > 0.1)
translations = st.tuples(*[st.floats(-5.0, 5.0)] * 3)
intrinsics = st.tuples(
    st.floats(200.0, 3000.0),  # fx
    st.floats(0.8, 1.25),  # fy / fx
    st.floats(0.0, 2000.0),  # cx
    st.floats(0.0, 1500.0),  # cy
    st.floats(-5.0, 5.0),  # skew
)
# Mild lenses: one-to-one (d r_d / d r > 0.4) within normalised radius 0.6.
lenses = st.one_of(
    st.just(None),
    st.tuples(
        st.floats(-0.4, 0.4),
        st.floats(-0.2, 0.2),
        st.floats(-2e-3, 2e-3),
        st.floats(-2e-3, 2e-3),
        st.floats(-0.05, 0.05),
    ),
)
in_field = st.tuples(st.floats(-0.42, 0.42), st.floats(-0.42, 0.42))


def rotation(q) -> np.ndarray:
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def make_camera(k, q, t, dist=None) -> ig.Camera:
    fx, ratio, cx, cy, skew = k
    return ig.Camera.from_intrinsics(fx, fx * ratio, cx, cy, skew, rotation(q), t, dist)


def world_point(cam: ig.Camera, xy, z) -> np.ndarray:
    """The world points at normalised image positions ``xy`` (..., 2) and camera
    depths ``z`` (...)."""
    z = np.asarray(z, dtype=float)[..., None]
    return (np.concatenate([np.asarray(xy) * z, z], axis=-1) - cam.t) @ cam.R


def cross2(a, b) -> float:
    return a[0] * b[1] - a[1] * b[0]


def line_through(a, b) -> np.ndarray:
    return np.cross([*a, 1.0], [*b, 1.0])


@given(k=intrinsics, q=quaternions, t=translations, lens=lenses, xy=in_field, z=st.floats(0.1, 50))
def test_points_along_one_ray_project_to_one_image_point(k, q, t, lens, xy, z):
    cam = make_camera(k, q, t, lens)
    x = world_point(cam, xy, z)
    along = cam.center + np.outer([0.5, 1.0, 3.0, 40.0], x - cam.center)
    uv = cam.project(along)
    np.testing.assert_allclose(uv, np.broadcast_to(uv[1], uv.shape), rtol=0, atol=1e-7)


@given(
    k=intrinsics,
    q=quaternions,
    t=translations,
    d_cam=st.tuples(unit, unit, st.floats(0.2, 1.0)),
    a=st.tuples(unit, unit),
    b=st.tuples(unit, unit),
)
def test_images_of_parallel_lines_meet_at_the_vanishing_point(k, q, t, d_cam, a, b):
    cam = make_camera(k, q, t)
    # The lines recede from the camera (z > 0 in its frame): the VP is finite.
    d = cam.R.T @ np.asarray(d_cam)
    # Two lines through points in front of the camera, followed into the scene.
    starts = [world_point(cam, 0.3 * np.asarray(p), 2.0) for p in (a, b)]
    segments = [cam.project([s + 1.0 * d, s + 9.0 * d]) for s in starts]
    # A line through (or near) the camera centre images to a point, not a line.
    assume(all(np.linalg.norm(p1 - p0) > 1.0 for p0, p1 in segments))
    lines = [line_through(*seg) for seg in segments]
    meet = np.cross(*lines)
    # Distinct, well-separated image lines only: nearly equal ones meet anywhere.
    norms = np.linalg.norm(lines[0][:2]) * np.linalg.norm(lines[1][:2])
    assume(abs(cross2(lines[0], lines[1])) > 0.05 * norms)
    vp = ig.vanishing_point(cam, d)
    assert not vp.at_infinity
    np.testing.assert_allclose(vp.homogeneous, [*vp.point, 1.0])
    scale = 1.0 + np.abs(vp.point).max()
    np.testing.assert_allclose(meet[:2] / meet[2], vp.point, rtol=0, atol=1e-6 * scale)


@given(k=intrinsics, q=quaternions, t=translations, up=st.tuples(unit, unit, unit), s=unit)
def test_horizon_passes_through_the_vanishing_points_of_horizontal_directions(k, q, t, up, s):
    cam = make_camera(k, q, t)
    up = np.asarray(up)
    assume(np.linalg.norm(up) > 0.1)
    a, b, c = ig.vanishing_line(cam, up)
    # Two horizontal directions spanning the ground plane, and a mix of them.
    e1 = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 * np.linalg.norm(up) else [0, 1, 0])
    e2 = np.cross(up, e1)
    d = e1 / np.linalg.norm(e1) + s * e2 / np.linalg.norm(e2)
    vp = ig.vanishing_point(cam, d)
    m = cam.R @ up
    if np.hypot(m[0], m[1]) <= 1e-12 * np.linalg.norm(m):
        # Looking straight up or down: the ground vanishes at the line at infinity.
        assert (a, b, c) == (0.0, 0.0, 1.0)
        assert vp.at_infinity
        return
    # Within 1e-6 rad of that, the horizon's orientation is set by rounding noise.
    assume(np.hypot(m[0], m[1]) > 1e-6 * np.linalg.norm(m))
    assert a * a + b * b == pytest.approx(1.0)
    if vp.at_infinity:  # the point at infinity (du, dv, 0) lies on the line too
        assert abs(a * vp.homogeneous[0] + b * vp.homogeneous[1]) < 1e-9
    else:
        u, v = vp.point
        assert abs(a * u + b * v + c) <= 1e-9 * (1.0 + abs(u) + abs(v))


@given(
    k=intrinsics,
    q=quaternions,
    t=translations,
    lens=lenses,
    xy=st.lists(in_field, min_size=1, max_size=20),
    z=st.floats(0.05, 1e3),
)
def test_unproject_inverts_project(k, q, t, lens, xy, z):
    cam = make_camera(k, q, t, lens)
    depth = z * np.linspace(1.0, 2.0, len(xy))
    world = world_point(cam, xy, depth)
    back = cam.unproject(cam.project(world), depth)
    scale = 1.0 + np.abs(world).max() + np.abs(cam.t).max()
    np.testing.assert_allclose(back, world, rtol=0, atol=1e-9 * scale)


@given(k=intrinsics, q=quaternions, t=translations, lens=lenses, xy=in_field)
def test_rays_are_unit_and_project_back(k, q, t, lens, xy):
    cam = make_camera(k, q, t, lens)
    pixel = cam.project(world_point(cam, xy, 3.0))
    ray = cam.rays(pixel)
    assert np.linalg.norm(ray) == pytest.approx(1.0, abs=1e-12)
    assert (cam.R @ ray)[2] > 0, "rays point into the scene"
    for s in (0.5, 7.0, 300.0):
        np.testing.assert_allclose(cam.project(cam.center + s * ray), pixel, atol=1e-6)


@pytest.mark.parametrize("n_coeffs", [0, 4, 5, 8])
def test_project_agrees_with_opencv(n_coeffs):
    cv2 = pytest.importorskip("cv2")
    rng = np.random.default_rng(n_coeffs)
    for _ in range(25):
        fx = rng.uniform(300.0, 3000.0)
        K = np.array(
            [
                [fx, 0.0, rng.uniform(0, 2000)],  # cv2.projectPoints ignores skew
                [0.0, fx * rng.uniform(0.8, 1.25), rng.uniform(0, 1500)],
                [0.0, 0.0, 1.0],
            ]
        )
        rvec = rng.uniform(-np.pi, np.pi, 3) / np.sqrt(3)
        tvec = rng.uniform(-3.0, 3.0, 3)
        lens = np.array([-0.3, 0.1, 1e-3, -1e-3, -0.02, 0.05, 0.01, 0.002])[:n_coeffs]
        lens = lens * rng.uniform(0.0, 1.0, n_coeffs)
        R = cv2.Rodrigues(rvec)[0]
        cam = ig.Camera(K, R, tvec, lens if n_coeffs else None)
        xy = rng.uniform(-0.5, 0.5, (200, 2))
        world = world_point(cam, xy, rng.uniform(0.1, 80.0, 200))
        ref, _ = cv2.projectPoints(world, rvec, tvec, K, lens if n_coeffs else None)
        np.testing.assert_allclose(cam.project(world), ref[:, 0], rtol=0, atol=1e-6)


@pytest.mark.parametrize(("axis", "index"), [("horizontal", 0), ("vertical", 1), ("diagonal", 2)])
@given(fov=st.floats(0.01, 3.1), h=st.integers(1, 5000), w=st.integers(1, 8000))
def test_fov_of_from_fov_round_trips(axis, index, fov, h, w):
    cam = ig.Camera.from_fov(fov, (h, w), axis=axis)
    assert cam.image_size == (h, w)
    assert cam.fov[index] == pytest.approx(fov, rel=1e-12)
    horizontal, vertical, diagonal = cam.fov
    assert np.tan(diagonal / 2) ** 2 == pytest.approx(
        np.tan(horizontal / 2) ** 2 + np.tan(vertical / 2) ** 2, rel=1e-9
    )


def test_a_lens_changes_the_field_it_sees():
    pinhole = ig.Camera.from_fov(np.deg2rad(60.0), (480, 640))
    barrel = ig.Camera(pinhole.K, dist=[-0.2, 0.0, 0.0, 0.0], image_size=(480, 640))
    assert all(b > p for b, p in zip(barrel.fov, pinhole.fov, strict=True))


def test_points_at_or_behind_the_camera_have_no_image():
    cam = ig.Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0, t=[0.0, 0.0, 1.0])
    uv = cam.project([[0.0, 0.0, -1.0], [1.0, 1.0, -3.0], [0.0, 0.0, 1.0]])
    assert np.isnan(uv[:2]).all()
    np.testing.assert_array_equal(uv[2], [320.0, 240.0])
    pts = cam.unproject([[320.0, 240.0]] * 3, [0.0, -2.0, 2.0])
    assert np.isnan(pts[:2]).all()
    np.testing.assert_array_equal(pts[2], [0.0, 0.0, 1.0])


def test_division_lens_beyond_its_fold_gives_nan():
    cam = ig.Camera(np.diag([100.0, 100.0, 1.0]), dist=[0.5], model="division")
    uv = cam.project([[0.1, 0.0, 1.0], [2.0, 0.0, 1.0]])
    assert np.isfinite(uv[0]).all() and np.isnan(uv[1]).all()


def test_single_point_in_single_point_out():
    cam = ig.Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0)
    assert cam.project([0.0, 0.0, 1.0]).shape == (2,)
    assert cam.unproject([1.0, 2.0], 3.0).shape == (3,)
    assert cam.rays([1.0, 2.0]).shape == (3,)
    assert cam.project(np.zeros((0, 3))).shape == (0, 2)


def test_vanishing_point_at_infinity_is_said_so():
    cam = ig.Camera.from_intrinsics(500.0, 400.0, 320.0, 240.0, skew=10.0)
    vp = ig.vanishing_point(cam, [1.0, 1.0, 0.0])
    assert vp.at_infinity
    assert np.isnan(vp.point).all()
    assert vp.homogeneous[2] == 0.0
    # The image lines are parallel, along (du, dv): check with two projected lines.
    d = np.array([1.0, 1.0, 0.0])
    for start in ([0.0, 0.0, 5.0], [-1.0, 2.0, 9.0]):
        a, b = cam.project([start, np.add(start, d)])
        step = (b - a) / np.linalg.norm(b - a)
        assert abs(cross2(step, vp.homogeneous)) < 1e-12


def test_directions_and_normals_of_any_length_give_the_same_answers():
    cam = ig.Camera.from_fov(np.deg2rad(60), image_size=(480, 640))
    for v in ([1.0, 1.0, 1.0], [2.0, -1.0, 3.0]):
        big, small = np.multiply(v, 1e308 / 3), np.multiply(v, 1e-300)
        expected = ig.vanishing_point(cam, v).point
        for scaled in (big, small):
            np.testing.assert_allclose(ig.vanishing_point(cam, scaled).point, expected)
            np.testing.assert_allclose(
                ig.vanishing_line(cam, scaled), ig.vanishing_line(cam, v), atol=1e-12
            )


def test_vanishing_point_through_a_lens_is_the_distorted_ideal_one():
    K = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
    lens = [-0.25, 0.05, 0.0, 0.0]
    vp = ig.vanishing_point(ig.Camera(K, dist=lens), [0.3, -0.2, 1.0])
    np.testing.assert_allclose(vp.homogeneous, [560.0, 80.0, 1.0])
    np.testing.assert_allclose(vp.point, ig.distort_points(vp.homogeneous[:2], lens, K=K))


def test_vanishing_line_of_a_fronto_parallel_plane_is_the_line_at_infinity():
    cam = ig.Camera.from_intrinsics(500.0, 500.0, 320.0, 240.0)
    np.testing.assert_array_equal(ig.vanishing_line(cam, [0.0, 0.0, -3.0]), [0.0, 0.0, 1.0])


@pytest.mark.parametrize("depth", [1e-200, 1e200])
def test_look_at_is_the_same_rotation_at_any_distance(depth):
    # Before: NaN at 1e-200, and "up must not be parallel" at 1e200.
    R, _ = ig.look_at([0.0, 0.0, 0.0], [0.0, 0.3 * depth, depth])
    want, _ = ig.look_at([0.0, 0.0, 0.0], [0.0, 0.3, 1.0])
    np.testing.assert_allclose(R, want, atol=1e-15)
    # An up vector of any length too.
    R, _ = ig.look_at([0.0, 0.0, 0.0], [0.0, 0.3, 1.0], up=[0.0, depth, 0.0])
    np.testing.assert_allclose(R, want, atol=1e-15)


def test_look_at_aims_the_optical_axis_and_keeps_up_upward():
    cam = ig.Camera.from_fov(1.0, (480, 640)).look_at([3.0, 2.0, -4.0], [0.0, 1.0, 5.0])
    np.testing.assert_allclose(cam.center, [3.0, 2.0, -4.0], atol=1e-12)
    np.testing.assert_allclose(cam.project([0.0, 1.0, 5.0]), [319.5, 239.5], atol=1e-9)
    assert cam.project([0.0, 2.0, 5.0])[1] < 239.5, "+y (up) appears above the centre"
    np.testing.assert_allclose(np.linalg.det(cam.R), 1.0)
    with pytest.raises(ValueError, match="parallel"):
        ig.look_at([0.0, 0.0, 0.0], [0.0, 5.0, 0.0])
    with pytest.raises(ValueError, match="must differ"):
        ig.look_at([1.0, 1.0, 1.0], [1.0, 1.0, 1.0])


def test_opencv_shaped_parameters_are_accepted():
    cam = ig.Camera(np.eye(3), t=np.array([[1.0], [2.0], [3.0]]), dist=np.zeros((1, 5)))
    np.testing.assert_array_equal(cam.t, [1.0, 2.0, 3.0])
    assert cam.dist.shape == (5,)
    with pytest.raises(ValueError, match="read-only"):
        cam.K[0, 0] = 2.0


def test_camera_pickles_and_reprs():
    import pickle

    cam = ig.Camera.from_fov(1.2, (480, 640), dist=[0.5], model="division").look_at(
        [1.0, 2.0, 3.0], [0.0, 0.0, 9.0]
    )
    back = pickle.loads(pickle.dumps(cam))
    for name in ("K", "R", "t", "dist"):
        np.testing.assert_array_equal(getattr(back, name), getattr(cam, name))
    assert (back.model, back.image_size) == ("division", (480, 640))
    np.testing.assert_array_equal(back.project([0.0, 0.0, 9.0]), cam.project([0.0, 0.0, 9.0]))
    assert repr(cam).startswith("Camera(fx=") and "model='division'" in repr(cam)


def test_results_do_not_depend_on_the_thread_count():
    code = """
        import sys
        import numpy as np
        import imgform_rs as ig
        rng = np.random.default_rng(3)
        pts = rng.uniform(-2.0, 2.0, (70_000, 3))
        pts[:, 2] += 4.0
        R = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
        cam = ig.Camera([[700, 1, 300], [0, 720, 200], [0, 0, 1]], R, [0.1, 0.2, 5.0],
                        [-0.2, 0.05, 1e-3, -1e-3, 0.01])
        uv = cam.project(pts)
        for a in (uv, cam.unproject(uv, pts[:, 2]), cam.rays(uv)):
            sys.stdout.buffer.write(a.tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


K_GOOD = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"K": np.eye(2)}, ValueError, r"K must have shape \(3, 3\)"),
        ({"K": np.diag([0.0, 1.0, 1.0])}, ValueError, "singular"),
        ({"K": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}, ValueError, "upper triangular"),
        ({"K": [["a"] * 3] * 3}, TypeError, "real numbers"),
        ({"K": None}, TypeError, "got None"),
        ({"R": np.diag([2.0, 1.0, 1.0])}, ValueError, "rotation matrix .*orthonormal"),
        ({"R": np.diag([-1.0, 1.0, 1.0])}, ValueError, r"det \+1\), got det -1"),
        ({"R": np.full((3, 3), np.nan)}, ValueError, "finite"),
        ({"t": [1.0, 2.0]}, ValueError, r"t must have shape \(3,\)"),
        ({"dist": [0.1, 0.2, 0.3]}, ValueError, r"4, 5 or 8 coefficients .* got 3"),
        ({"dist": [0.1, 0.2], "model": "division"}, ValueError, "1 coefficient"),
        ({"dist": [0.1], "model": "fisheye"}, ValueError, "unknown distortion model"),
        ({"image_size": (480,)}, ValueError, r"image_size must be two positive integers"),
        ({"image_size": (0, 640)}, ValueError, r"image_size must be two positive integers"),
        # Before: (1, 1) and (480, 640).
        ({"image_size": (True, True)}, ValueError, r"two positive integers .*\(True, True\)"),
        ({"image_size": (480.0, 640.0)}, ValueError, r"two positive integers"),
        # Before: "argument 'model_name': 'NoneType' object cannot be converted".
        ({"model": None}, TypeError, r"model must be a distortion model's name .*None"),
    ],
)
def test_bad_camera_parameters(kwargs, exc, match):
    args = {"K": K_GOOD, **kwargs}
    with pytest.raises(exc, match=match):
        ig.Camera(**args)


@pytest.mark.parametrize(
    ("call", "exc", "match"),
    [
        (lambda c: c.project([[1.0, 2.0]]), ValueError, r"shape \(N, 3\) or \(3,\)"),
        (lambda c: c.project([[np.nan, 0.0, 1.0]]), ValueError, "point 0 contains NaN"),
        (lambda c: c.project([["x", "y", "z"]]), TypeError, "real numbers"),
        (lambda c: c.unproject([[1.0, 2.0]], [1.0, 2.0]), ValueError, r"depth must be .*\(1,\)"),
        (lambda c: c.unproject([[1.0, 2.0]], [np.inf]), ValueError, "depth must be finite"),
        (lambda c: c.unproject([[np.nan, 2.0]], [1.0]), ValueError, "pixels must be finite"),
        (lambda c: c.rays([1.0, 2.0, 3.0]), ValueError, r"shape \(N, 2\)"),
        (lambda c: c.fov, ValueError, "image_size=\\(height, width\\)"),
        (lambda c: ig.vanishing_point(c, [0.0, 0.0, 0.0]), ValueError, "non-zero"),
        (lambda c: ig.vanishing_line(c, [0.0, np.nan, 1.0]), ValueError, "finite"),
        (lambda c: ig.vanishing_point(c, [1.0, 0.0]), ValueError, r"shape \(3,\)"),
    ],
)
def test_bad_call_arguments(call, exc, match):
    with pytest.raises(exc, match=match):
        call(ig.Camera(K_GOOD))


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        ((0.0, (480, 640)), {}, r"fov must be an angle in radians in \(0, pi\)"),
        ((4.0, (480, 640)), {}, r"fov must be"),
        ((1.0, None), {}, "needs image_size"),
        ((1.0, (480, 640)), {"axis": "width"}, "axis must be"),
    ],
)
def test_bad_from_fov(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        ig.Camera.from_fov(*args, **kwargs)


def test_native_layer_checks_too():
    from imgform_rs import _native

    cam = _native.NativeCamera(K_GOOD, np.eye(3), np.zeros(3), [], "brown_conrady")
    with pytest.raises(TypeError, match="float64 array of shape"):
        cam.project(np.zeros((2, 3), np.float32))
    with pytest.raises(TypeError, match="depth must be a float64 array"):
        cam.unproject(np.zeros((2, 2)), [1.0, 2.0])
    with pytest.raises(ValueError, match="one value per pixel"):
        cam.unproject(np.zeros((2, 2)), np.ones(3))
    with pytest.raises(TypeError, match="R must be a float64 array"):
        _native.NativeCamera(K_GOOD, np.eye(3, dtype=np.float32), np.zeros(3), [], "division")
