import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs as ig

K = np.array([[1200.0, 0.8, 640.0], [0.0, 1180.0, 360.0], [0.0, 0.0, 1.0]])

lenses = st.tuples(
    st.floats(-0.4, 0.4),  # k1
    st.floats(-0.2, 0.2),  # k2
    st.floats(-2e-3, 2e-3),  # p1
    st.floats(-2e-3, 2e-3),  # p2
    st.floats(-0.05, 0.05),  # k3
)
# Within radius 0.6 of the axis every lens above is one-to-one (d r_d / d r > 0.4).
in_field = st.tuples(st.floats(-0.42, 0.42), st.floats(-0.42, 0.42))


@given(lens=lenses, p=in_field)
def test_undistort_inverts_distort_within_1e_6_px(lens, p):
    pix = np.array(K[:2, :2] @ p + K[:2, 2])
    distorted = ig.distort_points(pix, lens, K=K)
    back, ok = ig.undistort_points(distorted, lens, K=K, return_converged=True)
    assert ok.all()
    np.testing.assert_allclose(back, pix, atol=1e-6, rtol=0)


@given(lam=st.floats(-0.5, 0.5), p=in_field)
def test_division_model_round_trip(lam, p):
    back = ig.undistort_points(
        ig.distort_points(p, [lam], model="division"), [lam], model="division"
    )
    np.testing.assert_allclose(back, p, atol=1e-12)


def test_brown_conrady_forward_matches_opencv():
    cv2 = pytest.importorskip("cv2")
    k0 = K.copy()
    k0[0, 1] = 0.0  # cv2.projectPoints ignores skew
    rng = np.random.default_rng(1)
    lens = np.array([-0.3, 0.09, 1e-3, -2e-3, -0.02, 0.01, 0.002, 0.001])
    pts = rng.uniform(-0.5, 0.5, (200, 2))
    obj = np.hstack([pts, np.ones((200, 1))])
    ref, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), k0, lens)
    pix = pts @ k0[:2, :2].T + k0[:2, 2]
    np.testing.assert_allclose(ig.distort_points(pix, lens, K=k0), ref[:, 0], atol=1e-9)


def test_far_points_of_a_barrel_division_lens_land_at_its_fold_not_its_centre():
    # Past x ~ 1e154 the squares overflowed and the points went to (0, 0): the
    # principal point for a ray all but parallel to the image plane.
    fold = 1 / np.sqrt(0.2)
    far = ig.distort_points([[1e100, 0.0], [0.0, -1e200]], [-0.2], model="division")
    np.testing.assert_allclose(far, [[fold, 0.0], [0.0, -fold]], rtol=1e-15)
    cam = ig.Camera([[800, 0, 320], [0, 800, 240], [0, 0, 1.0]], dist=[-0.2], model="division")
    u = cam.project([[1.0, 0.0, 1e-10], [1.0, 0.0, 1e-160]])[:, 0]
    np.testing.assert_allclose(u, 320 + 800 * fold, rtol=1e-9)


def test_points_beyond_the_fold_are_reported_not_invented():
    strong_barrel = [-0.5, 0.0, 0.0, 0.0]
    out, ok = ig.undistort_points([[0.5, 0.0], [0.6, 0.0]], strong_barrel, return_converged=True)
    assert ok.tolist() == [True, False]
    assert np.isnan(out[1]).all()
    # Forward, r (1 - 0.5 r²) turns back at r = 0.816: past it a point is
    # not put on the wrong side of the axis (as cv2.projectPoints does).
    far = ig.distort_points([[0.8, 0.0], [0.9, 0.0], [3.0, 0.0]], strong_barrel)
    assert not np.isnan(far[0]).any() and np.isnan(far[1:]).all()


@pytest.mark.parametrize(
    ("dist", "model", "match"),
    [
        ([0.1, 0.2, 0.3], "brown_conrady", r"4, 5 or 8 coefficients .* got 3"),
        ([0.1, 0.2], "division", "1 coefficient"),
        ([0.1, np.nan, 0, 0], "brown_conrady", "finite"),
        ([0.1], "fisheye", "unknown distortion model"),
    ],
)
def test_bad_coefficients(dist, model, match):
    with pytest.raises(ValueError, match=match):
        ig.distort_points([0.1, 0.1], dist, model=model)


def test_singular_k_is_refused():
    with pytest.raises(ValueError, match="singular"):
        ig.distort_points([1.0, 1.0], [0.1, 0, 0, 0], K=np.diag([0.0, 1.0, 1.0]))
