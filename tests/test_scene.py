"""The demo scene's ground texture, averaged over each pixel's footprint."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from imgform_rs import demo, scene, vanishing_line

# Brute-force box means: the antiderivatives' closed forms against the mean
# of many point samples across [t - r, t + r].
SAMPLES = 50_001


@given(st.floats(-60.0, 60.0), st.floats(1e-3, 4.0))
def test_box_means_of_the_checker_profiles_are_their_sampled_means(t, r):
    xs = np.linspace(t - r, t + r, SAMPLES)
    zero = np.zeros_like(xs)
    point_g = scene._interior(xs, zero)
    point_gs = scene._signed_interior(xs, zero)
    # A grid line's edges fall between samples: the sampled mean is off by
    # at most one sample's share per edge crossed (two edges per metre).
    tol = (2 * (2 * r + 1) + 4) / SAMPLES + 1e-6
    assert scene._interior(np.array([t]), np.array([r]))[0] == pytest.approx(
        point_g.mean(), abs=tol
    )
    assert scene._signed_interior(np.array([t]), np.array([r]))[0] == pytest.approx(
        point_gs.mean(), abs=tol
    )


def test_point_samples_are_the_checkerboard_and_its_lines():
    # (x, z): a light cell, a dark one, a line, a crossing of lines.
    pts = np.array([[0.5, 1.5], [0.5, 0.5], [3.01, 7.5], [-2.0, 4.0]])
    pts = np.insert(pts, 1, 0.0, axis=1)
    want = [scene.LIGHT_CELL, scene.DARK_CELL, scene.LINE_COLOUR, scene.LINE_COLOUR]
    np.testing.assert_allclose(scene._checker(pts), want, atol=1e-6)


def test_a_footprint_many_cells_wide_averages_to_the_textures_mean():
    pts = np.array([[0.3, 0.0, 0.7], [17.2, 0.0, -40.1]])
    mean = scene._checker(pts, np.full((2, 2), 500.0))
    line_share = 1 - (1 - 2 * scene.LINE_HALF) ** 2
    want = (
        line_share * scene.LINE_COLOUR + (1 - line_share) * (scene.LIGHT_CELL + scene.DARK_CELL) / 2
    )
    np.testing.assert_allclose(mean, [want, want], atol=2e-3)


def _horizon_band(camera, rows: int = 24) -> np.ndarray:
    """Pixel centres (N, 2) of the ``rows`` rows just below the horizon, where
    the checkerboard's cells shrink below a pixel."""
    a, b, c = vanishing_line(camera, (0.0, 1.0, 0.0))
    w = camera.image_size[1]
    top = int(np.ceil(max(-(a * u + c) / b for u in (0.0, w - 1.0)))) + 2
    v, u = np.mgrid[top : top + rows, 0:w]
    return np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)


def _point_sampled(camera, pixels: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Mean colour over the given sub-pixel offsets (K, 2), one ray each, no footprint."""
    colours = [scene.shade(camera.center, camera.rays(pixels + o))[0] for o in offsets]
    return np.mean(colours, axis=0)


def test_the_horizon_matches_a_heavily_supersampled_reference():
    """The demo's camera, one ray per pixel with its footprint, against
    32 x 32 jittered rays per pixel (every 16th column of the 24 rows below
    the horizon): the texture keeps its contrast where the cells are still
    resolved and fades to their mean beyond, without the coloured noise that
    2 x 2 point samples per pixel (the demo's earlier rendering) leave."""
    camera = demo._camera()
    pixels = _horizon_band(camera)
    pixels = pixels[pixels[:, 0] % 16 == 0]
    rng = np.random.default_rng(0)
    n = 32
    grid = (np.stack(np.meshgrid(np.arange(n), np.arange(n)), -1).reshape(-1, 2) + 0.5) / n - 0.5
    reference = _point_sampled(camera, pixels, grid + rng.uniform(-0.5 / n, 0.5 / n, grid.shape))
    ours, _ = scene.render(camera, pixels)
    quarters = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])
    two_by_two = _point_sampled(camera, pixels, quarters)
    err_ours = np.sqrt(np.mean((ours - reference) ** 2))
    err_2x2 = np.sqrt(np.mean((two_by_two - reference) ** 2))
    # The reference's own sampling noise is ~0.01 (its 16 x 16 version
    # differs from it by 0.014).
    assert err_ours < 0.02, err_ours
    assert err_ours < 0.15 * err_2x2, (err_ours, err_2x2)


def test_the_ground_is_met_only_ahead_of_a_ray():
    """From below the ground, a ray going down used to hit it at a negative
    distance, and render gave negative depths."""
    import imgform_rs as ig

    down = np.array([[0.0, -0.5, np.sqrt(0.75)]])
    colour, distance = scene.shade(np.array([0.0, -1.0, 0.0]), down)
    assert distance[0] == np.inf
    np.testing.assert_allclose(colour[0], (0.55 - 0.45 * 0.5) * np.array([0.55, 0.75, 1.0]))
    cam = ig.Camera.from_fov(0.8, (12, 16)).look_at([0, -1.0, -3.0], [0, -2, 9.0])
    px = np.stack(np.meshgrid(np.arange(16.0), np.arange(12.0)), -1).reshape(-1, 2)
    colours, depths = scene.render(cam, px)
    assert (depths > 0).all()
    one = scene.render(cam, px[20])  # one pixel, as the point sets take it
    assert one[0].shape == (3,) and one[1] == depths[20]
    np.testing.assert_array_equal(one[0], colours[20])
