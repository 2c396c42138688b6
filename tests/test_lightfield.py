"""Light fields: rendering sub-aperture views and shift-and-add refocusing."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads
from imgform_rs import _native, scene

# A camera at the world origin looking along +z (world frame = camera frame),
# and three fronto-parallel textured planes: a near strip, a middle strip and
# a background filling the rest, at disparities 2, 1.25 and 0.5 px per view.
H, W, F = 64, 160, 100.0
BASELINE = 0.02
GRID = (5, 5)
DISPARITY = {"near": 2.0, "middle": 1.25, "far": 0.5}
DEPTH = {k: BASELINE * F / d for k, d in DISPARITY.items()}
STRIPS = {"near": (16, 56), "middle": (80, 120), "far": (-1e9, 1e9)}
# Texture period in pixels on every plane: long enough that bilinear
# interpolation at half a pixel loses < 2 % of the contrast.
PERIOD_PX = 16.0


def camera() -> ig.Camera:
    return ig.Camera.from_intrinsics(F, F, (W - 1) / 2, (H - 1) / 2, image_size=(H, W))


def texture(points: np.ndarray, z: float) -> np.ndarray:
    """Smooth RGB texture whose period is PERIOD_PX pixels at depth z."""
    k = 2 * np.pi * F / (PERIOD_PX * z)
    x, y = points[:, 0] * k, points[:, 1] * k
    rgb = [np.sin(x) * np.cos(0.7 * y), np.cos(0.8 * x + y), np.sin(0.6 * x - 0.9 * y)]
    return 0.5 + 0.35 * np.stack(rgb, axis=1)


def shade(origin: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ray caster of the three planes, nearest first."""
    best = np.full(len(dirs), np.inf)
    colour = np.zeros((len(dirs), 3))
    cx = (W - 1) / 2
    for name in ("near", "middle", "far"):
        z, (c0, c1) = DEPTH[name], STRIPS[name]
        t = (z - origin[2]) / dirs[:, 2]
        p = origin + t[:, None] * dirs
        x_lo, x_hi = (c0 - cx) * z / F, (c1 - cx) * z / F
        hit = (p[:, 0] >= x_lo) & (p[:, 0] <= x_hi) & (t < best)
        best[hit] = t[hit]
        colour[hit] = texture(p[hit], z)
    return colour, best


@pytest.fixture(scope="module")
def planes() -> np.ndarray:
    return ig.render_light_field(shade, camera=camera(), baseline=BASELINE, grid=GRID)


def erode(mask: np.ndarray, m: int) -> np.ndarray:
    """``mask`` shrunk by ``m`` pixels, the image border counting as outside."""
    padded = np.pad(mask, m, constant_values=False)
    out = np.ones_like(mask)
    for dy in range(2 * m + 1):
        for dx in range(2 * m + 1):
            out &= padded[dy : dy + mask.shape[0], dx : dx + mask.shape[1]]
    return out


def plane_mask(name: str, margin: int) -> np.ndarray:
    """Pixels where the central view sees plane ``name``, ``margin`` pixels
    away from any other plane and from the border."""
    cam = camera()
    v, u = np.mgrid[0:H, 0:W]
    rays = cam.rays(np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
    _, dist = shade(cam.center, rays)
    z = (dist * rays[:, 2]).reshape(H, W)
    return erode(np.isclose(z, DEPTH[name]), margin)


def psnr(reference: np.ndarray, estimate: np.ndarray, mask: np.ndarray) -> float:
    err = reference[mask].astype(np.float64) - estimate[mask]
    return float(10 * np.log10(255.0**2 / max(np.mean(err**2), 1e-12)))


# Largest disparity difference (2 - 0.5) times the largest view offset (2),
# plus the bilinear tap: every view sees the masked pixels on the same plane.
MARGIN = 5


@pytest.mark.parametrize("name", ["near", "middle", "far"])
def test_refocusing_at_a_planes_disparity_makes_it_as_sharp_as_one_view(planes, name):
    sharp = ig.refocus(planes, DISPARITY[name])
    mask = plane_mask(name, MARGIN)
    assert mask.sum() > 500
    assert psnr(planes[2, 2], sharp, mask) >= 40.0


def test_views_move_by_the_documented_disparity(planes):
    # The middle plane at 1.25 px per view: view (4, 0) is 2 rows below and
    # 2 columns left of the centre, so it sees the plane moved by (-2.5, +2.5)
    # pixels; half-pixel shifts of a smooth texture are close to the mean of
    # the two neighbouring integer shifts.
    centre = planes[2, 2].astype(np.float64)
    shifted = sum(np.roll(centre, (-dy, dx), (0, 1)) for dy in (2, 3) for dx in (2, 3)) / 4
    mask = plane_mask("middle", MARGIN)
    assert psnr(shifted, planes[4, 0], mask) > 35.0
    assert np.isclose(float(ig.view_disparity(camera(), BASELINE, DEPTH["middle"])), 1.25)


def test_blur_grows_with_the_disparity_difference(planes):
    mask = plane_mask("far", 7)
    scores = [
        psnr(planes[2, 2], ig.refocus(planes, DISPARITY["far"] + delta), mask)
        for delta in (0.0, 0.25, 0.5, 1.0, 1.5)
    ]
    assert all(a > b for a, b in itertools.pairwise(scores)), scores
    assert scores[-1] < 25.0


def test_blur_shrinks_with_the_aperture(planes):
    # Focused on the near strip, the background blurs less and less as the
    # synthetic aperture closes; one view alone is the central picture.
    mask = plane_mask("far", 7)
    alpha = DISPARITY["near"]
    scores = [
        psnr(planes[2, 2], ig.refocus(planes, alpha, aperture=r), mask) for r in (None, 2.0, 1.0)
    ]
    assert scores[0] < scores[1] < scores[2], scores
    np.testing.assert_array_equal(ig.refocus(planes, alpha, aperture=0.0), planes[2, 2])


def test_aperture_mask_and_radius_agree(planes):
    mask = np.zeros(GRID, bool)
    mask[1:4, 2] = mask[2, 1:4] = True
    np.testing.assert_array_equal(
        ig.refocus(planes, 0.7, aperture=mask), ig.refocus(planes, 0.7, aperture=1)
    )


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_alpha_zero_is_the_mean_of_the_views(dtype):
    rng = np.random.default_rng(3)
    top = 1.0 if dtype == np.float32 else np.iinfo(dtype).max
    lf = (rng.random((3, 4, 9, 11, 3)) * top).astype(dtype)
    out = ig.refocus(lf, 0.0)
    assert out.dtype == dtype and out.shape == (9, 11, 3)
    mean = lf.astype(np.float64).mean(axis=(0, 1))
    tol = 1e-5 if dtype == np.float32 else 0.5 + 1e-3 * top / 255
    assert np.abs(out - mean).max() <= tol


def test_focal_stack_is_refocus_per_alpha(planes):
    alphas = [0.5, 1.25, 2.0]
    stack = ig.focal_stack(planes, alphas, aperture=1.5)
    assert stack.shape == (3, H, W, 3) and stack.dtype == np.uint8
    for frame, alpha in zip(stack, alphas, strict=True):
        np.testing.assert_array_equal(frame, ig.refocus(planes, alpha, aperture=1.5))


@given(
    grid=st.tuples(st.integers(1, 4), st.integers(1, 4)),
    size=st.tuples(st.integers(1, 9), st.integers(1, 9)),
    alpha=st.floats(-3.0, 3.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_matches_scipy_bilinear_shift_and_add(grid, size, alpha, seed):
    # Peer: scipy.ndimage.shift, order 1, mode "mirror" (d c b | a b c d |
    # c b a, the same mirror), of each view by alpha * its offset, averaged
    # over a random non-empty aperture; gray views (U, V, H, W).
    ndimage = pytest.importorskip("scipy.ndimage")
    rng = np.random.default_rng(seed)
    lf = rng.random((*grid, *size), dtype=np.float32)
    mask = rng.random(grid) < 0.6
    mask.flat[rng.integers(mask.size)] = True
    uc, vc = (grid[0] - 1) / 2, (grid[1] - 1) / 2
    views = [
        ndimage.shift(
            lf[u, v].astype(np.float64),
            (alpha * (u - uc), alpha * (v - vc)),
            order=1,
            mode="mirror",
        )
        for u, v in zip(*np.nonzero(mask), strict=True)
    ]
    got = ig.refocus(lf, alpha, aperture=mask)
    assert got.shape == size
    np.testing.assert_allclose(got, np.mean(views, axis=0), atol=2e-5)


def test_noncontiguous_input_is_accepted(planes):
    flipped = planes[:, :, :, ::-1]
    np.testing.assert_array_equal(
        ig.refocus(flipped, 1.0), ig.refocus(np.ascontiguousarray(flipped), 1.0)
    )


def test_big_endian_input_is_its_values():
    # Before: "must be a uint8, uint16 or float32 array, got dtype >u2".
    views = np.random.default_rng(4).integers(0, 60000, (3, 3, 8, 8)).astype(">u2")
    np.testing.assert_array_equal(ig.refocus(views, 0.5), ig.refocus(views.astype("<u2"), 0.5))


def test_same_bits_for_any_thread_count():
    code = """
        import sys
        import numpy as np
        import imgform_rs as ig
        rng = np.random.default_rng(5)
        lf = rng.integers(0, 256, (5, 5, 70, 90, 3), dtype=np.uint8)
        out = ig.focal_stack(lf, [-0.7, 1.3], aperture=1.6)
        sys.stdout.buffer.write(out.tobytes())
    """
    assert output_with_threads(code, 1) == output_with_threads(code, 2)


def test_render_light_field_of_the_sample_scene():
    cam = ig.Camera.from_fov(0.8, (12, 16)).look_at([4.5, 1.6, -3.0], [-0.5, 0.9, 9.0])
    lf = ig.render_light_field(
        scene, camera=cam, baseline=0.05, grid=(2, 3), supersample=2, dtype=np.float32
    )
    assert lf.shape == (2, 3, 12, 16, 3) and lf.dtype == np.float32
    assert 0.0 <= lf.min() and lf.max() <= 1.0
    # Different positions see different things, but not wholly different.
    assert 0 < np.abs(lf[0, 0] - lf[1, 2]).mean() < 0.2


@pytest.mark.parametrize(
    ("light_field", "kwargs", "error", "match"),
    [
        (np.zeros((4, 4, 3), np.uint8), {}, ValueError, "shape"),
        (np.zeros((2, 2, 4, 4, 3, 1), np.uint8), {}, ValueError, "shape"),
        (np.zeros((2, 2, 4, 4), np.float64), {}, TypeError, "float64"),
        (np.zeros((2, 2, 0, 4), np.uint8), {}, ValueError, "empty"),
        (np.zeros((2, 2, 4, 4), np.uint8), {"alpha": np.nan}, ValueError, "finite"),
        (np.zeros((2, 2, 4, 4), np.uint8), {"alpha": np.inf}, ValueError, "finite"),
        (np.zeros((3, 3, 4, 4), np.uint8), {"aperture": -1.0}, ValueError, ">= 0"),
        (
            np.zeros((3, 3, 4, 4), np.uint8),
            {"aperture": np.zeros((3, 3), bool)},
            ValueError,
            "no view",
        ),
        (np.zeros((2, 2, 4, 4), np.uint8), {"aperture": 0.0}, ValueError, "no view"),
        (np.zeros((3, 3, 4, 4), np.uint8), {"aperture": np.ones((3, 2), bool)}, ValueError, "grid"),
        (np.zeros((3, 3, 4, 4), np.uint8), {"aperture": "all"}, TypeError, "aperture"),
        # Refocused at the first alpha alone before.
        (np.zeros((2, 2, 4, 4), np.uint8), {"alpha": [1.0]}, ValueError, r"shape \(1,\)"),
        # Read as 1.0 before.
        (np.zeros((2, 2, 4, 4), np.uint8), {"alpha": "1"}, TypeError, "must be numbers"),
    ],
)
def test_bad_input_is_refused(light_field, kwargs, error, match):
    alpha = kwargs.pop("alpha", 1.0)
    with pytest.raises(error, match=match):
        ig.refocus(light_field, alpha, **kwargs)


def test_bad_alphas_and_native_shapes_are_refused():
    lf = np.zeros((3, 3, 4, 5), np.uint8)
    with pytest.raises(ValueError, match="at least one"):
        ig.focal_stack(lf, [])
    with pytest.raises(ValueError, match="finite"):
        ig.focal_stack(lf, [0.0, np.nan])
    # A 2-D array of disparities was flattened into frames.
    with pytest.raises(ValueError, match=r"1-D sequence of disparities, got shape \(2, 2\)"):
        ig.focal_stack(lf, [[0, 1], [2, 3]])
    views = np.zeros((3 * 3 * 4 + 1, 5, 1), np.uint8)
    with pytest.raises(ValueError, match="views of equal height"):
        _native.focal_stack(views, (3, 3), [0.0], [True] * 9)
    with pytest.raises(ValueError, match="one flag per view"):
        _native.focal_stack(views[:-1], (3, 3), [0.0], [True] * 8)
    with pytest.raises(TypeError, match="int64"):
        _native.focal_stack(views[:-1].astype(np.int64), (3, 3), [0.0], [True] * 9)


def test_one_depths_disparity_refocuses_and_several_make_a_focal_stack(planes):
    # The guide's calls: one depth's disparity is a scalar refocus takes.
    alpha = ig.view_disparity(camera(), BASELINE, DEPTH["near"])
    assert np.ndim(alpha) == 0
    np.testing.assert_array_equal(ig.refocus(planes, alpha), ig.refocus(planes, 2.0))
    alphas = ig.view_disparity(camera(), BASELINE, list(DEPTH.values()))
    np.testing.assert_array_equal(ig.focal_stack(planes, alphas)[0], ig.refocus(planes, 2.0))
    with pytest.raises(ValueError, match=r"got shape \(3,\); for several, call focal_stack"):
        ig.refocus(planes, alphas)


@pytest.mark.parametrize(
    ("args", "error", "match"),
    [
        # Before: negative disparities and NaN silently.
        ((BASELINE, 0.0), ValueError, r"depth must be > 0 \(inf for the far distance\), got 0\.0"),
        ((BASELINE, -2.0), ValueError, r"depth must be > 0 .*, got -2\.0"),
        ((BASELINE, [1.0, np.nan]), ValueError, "depth must be > 0 .*, got nan"),
        ((BASELINE, -np.inf), ValueError, "depth must be > 0 .*, got -inf"),
        ((BASELINE, "far"), TypeError, "depth must be real numbers"),
        ((-BASELINE, 2.0), ValueError, r"baseline must be a finite number > 0, got -0\.02"),
        ((np.nan, 2.0), ValueError, "baseline must be a finite number > 0"),
        (([BASELINE], 2.0), TypeError, "baseline must be a real number"),
    ],
)
def test_view_disparity_refuses_what_has_no_disparity(args, error, match):
    with pytest.raises(error, match=match):
        ig.view_disparity(camera(), *args)


def test_the_far_distance_has_disparity_zero_and_refocuses_to_the_plain_mean(planes):
    alphas = ig.view_disparity(camera(), BASELINE, [np.inf, DEPTH["near"]])
    assert alphas[0] == 0.0 and alphas[1] > 0
    np.testing.assert_array_equal(ig.refocus(planes, alphas[0]), ig.refocus(planes, 0.0))


def test_view_disparity_needs_a_camera():
    # Before: AttributeError: 'str' object has no attribute 'K'.
    with pytest.raises(TypeError, match=r"camera must be an imgform_rs\.Camera, got str"):
        ig.view_disparity("pinhole", BASELINE, 2.0)


def test_render_light_field_takes_a_grid_of_numpy_ints():
    """The error said a NumPy pair was not "a pair (U, V) of integers"."""
    args = {"camera": camera(), "baseline": 0.02}
    np.testing.assert_array_equal(
        ig.render_light_field(scene, grid=np.array([2, 2]), **args),
        ig.render_light_field(scene, grid=(2, 2), **args),
    )


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"grid": (0, 3)}, ValueError, "grid"),
        ({"grid": 3}, ValueError, "grid"),
        ({"baseline": 0.0}, ValueError, "baseline"),
        ({"baseline": np.nan}, ValueError, "baseline"),
        ({"baseline": "0.02"}, TypeError, "baseline must be a real number"),
        ({"supersample": 0}, ValueError, "supersample"),
        ({"dtype": np.uint16}, TypeError, "dtype"),
        ({"camera": "pinhole"}, TypeError, "Camera"),
        ({"camera": ig.Camera.from_intrinsics(10.0, 10.0, 4.0, 4.0)}, ValueError, "image_size"),
        # A lens whose fold lies inside the image: "shade's colours must be finite".
        (
            {"camera": ig.Camera.from_fov(0.8, (24, 32), dist=[-0.6, 0, 0, 0])},
            ValueError,
            r"the camera's lens sees no ray at \d+ of 768 sample positions",
        ),
        ({"scene": 42}, TypeError, "shade"),
        # A shade whose colours come as (3, N) once scrambled the views.
        ({"scene": lambda o, d: (scene.shade(o, d)[0].T, None)}, ValueError, r"\(\d+, 3\)"),
        ({"scene": lambda o, d: (scene.shade(o, d)[0] * np.nan, None)}, ValueError, "finite"),
        ({"scene": lambda o, d: (scene.shade(o, d)[0] + 0j, None)}, TypeError, "real numbers"),
        ({"scene": lambda o, d: scene.shade(o, d)[0]}, TypeError, r"\(colour, distance\)"),
    ],
)
def test_render_light_field_refuses_bad_input(kwargs, error, match):
    args = {"scene": scene, "camera": camera(), "baseline": 0.02, "grid": (2, 2)}
    args.update(kwargs)
    target = args.pop("scene")
    with pytest.raises(error, match=match):
        ig.render_light_field(target, **args)
