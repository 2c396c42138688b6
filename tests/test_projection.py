import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs as ig

coord = st.floats(-1e3, 1e3, allow_nan=False)
depth = st.floats(1e-2, 1e4)
focal = st.floats(1e-2, 1e3)


def test_pinhole_is_exactly_equations_1_and_2():
    pts = np.array([[1.0, 2.0, 4.0], [-3.0, 0.5, 0.25]])
    got = ig.project_pinhole(pts, 2.0)
    np.testing.assert_array_equal(got, -2.0 * pts[:, :2] / pts[:, 2:])
    np.testing.assert_array_equal(ig.project_pinhole(pts, 2.0, invert=False), -got)


def test_points_at_or_behind_the_pinhole_have_no_image():
    got = ig.project_pinhole([[1.0, 1.0, 0.0], [1.0, 1.0, -2.0], [0.0, 0.0, 1.0]], 1.0)
    assert np.isnan(got[:2]).all()
    np.testing.assert_array_equal(got[2], [0.0, 0.0])


def test_single_point_in_single_point_out():
    assert ig.project_pinhole([2.0, 4.0, 2.0], 1.0).shape == (2,)


@given(x=coord, y=coord, z=depth, f=focal, k=st.floats(0.1, 100.0))
def test_points_along_one_ray_project_to_one_image_point(x, y, z, f, k):
    a, b = ig.project_pinhole([[x, y, z], [k * x, k * y, k * z]], f)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


@given(
    p=st.tuples(coord, coord, depth),
    d=st.tuples(coord, coord, st.floats(0.0, 1e3)),
    ts=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
    f=focal,
)
def test_collinear_points_stay_collinear(p, d, ts, f):
    pts = np.array(p) + np.outer(ts, d)
    uv = ig.project_pinhole(pts, f)
    (a, b, c) = uv
    cross = (b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0]
    scale = max(1.0, np.abs(uv).max()) ** 2
    assert abs(cross) <= 1e-9 * scale


@given(x=coord, y=coord, s=st.floats(0.01, 10.0))
def test_orthographic_is_the_limit_of_perspective(x, y, s):
    z_far = 1e9
    persp = ig.project_pinhole([x, y, z_far], s * z_far, invert=False)
    np.testing.assert_allclose(persp, ig.project_orthographic([x, y, z_far], scale=s), atol=1e-6)


@pytest.mark.parametrize(
    ("points", "f", "exc", "match"),
    [
        ([[1.0, 2.0]], 1.0, ValueError, r"shape \(N, 3\)"),
        ([[1.0, 2.0, 3.0]], 0.0, ValueError, "f must be a finite number > 0, got 0"),
        ([[1.0, 2.0, 3.0]], float("nan"), ValueError, "f must be"),
        ([[np.nan, 2.0, 3.0]], 1.0, ValueError, "point 0 contains NaN"),
        ([["a", "b", "c"]], 1.0, TypeError, "real numbers"),
        (None, 1.0, TypeError, "got None"),
    ],
)
def test_bad_input_says_what_was_given(points, f, exc, match):
    with pytest.raises(exc, match=match):
        ig.project_pinhole(points, f)


def test_native_layer_checks_too():
    from imgform_rs import _native

    with pytest.raises(TypeError, match="float64 array of shape"):
        _native.project_pinhole(np.zeros((2, 3), np.float32), 1.0)
