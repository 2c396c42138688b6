import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import imgform_rs as ig
from conftest import output_with_threads

K = np.array([[300.0, 0.0, 159.5], [0.0, 310.0, 119.5], [0.0, 0.0, 1.0]])
LENS = np.array([-0.25, 0.08, 1e-3, -8e-4, -0.01])
H, W = 240, 320


def smooth(h=H, w=W, channels=3, dtype=np.uint8, seed=0):
    """A band-limited test card (sums of long-wavelength sinusoids)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    planes = []
    for _ in range(channels):
        fx, fy, ph = rng.uniform(0.01, 0.05, 2).tolist() + [rng.uniform(0, 6)]
        planes.append(0.5 + 0.4 * np.sin(fx * x + ph) * np.cos(fy * y - ph))
    img = np.stack(planes, axis=-1)
    if dtype == np.float32:
        img = img.astype(np.float32)
    else:
        img = np.round(img * np.iinfo(dtype).max).astype(dtype)
    return img if channels > 1 else img[..., 0]


def identity_map(h, w):
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    return x, y


def interior(a, margin=20):
    return a[margin:-margin, margin:-margin]


@pytest.mark.parametrize("interpolation", ["bilinear", "bicubic"])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("channels", [1, 3, 4, 5])
def test_identity_map_returns_the_image_exactly(interpolation, dtype, channels):
    rng = np.random.default_rng(channels)
    shape = (17, 23) if channels == 1 else (17, 23, channels)
    if dtype == np.float32:
        img = rng.standard_normal(shape).astype(np.float32)
    else:
        img = rng.integers(0, np.iinfo(dtype).max, shape, endpoint=True).astype(dtype)
    out = ig.remap(img, identity_map(17, 23), interpolation=interpolation)
    assert out.dtype == img.dtype and out.shape == img.shape
    np.testing.assert_array_equal(out, img)


def test_output_takes_the_map_shape_and_non_contiguous_input_works():
    img = smooth(channels=3)[::2, ::2]  # non-contiguous view
    x, y = identity_map(50, 70)
    out = ig.remap(img, (x * 1.5, y * 1.5))
    assert out.shape == (50, 70, 3) and out.flags.c_contiguous
    np.testing.assert_array_equal(out[::2, ::2], img[:75:3, :105:3])


@pytest.mark.parametrize("dtype", [">u2", ">f4"])
def test_big_endian_images_give_what_their_native_copies_give(dtype):
    """Data read from a big-endian file as it is holds the same values."""
    rng = np.random.default_rng(4)
    native = (rng.random((24, 32, 3)) * 1000).astype(np.dtype(dtype).newbyteorder("="))
    big = native.astype(dtype)
    assert not big.dtype.isnative
    my, mx = np.mgrid[0:24, 0:32].astype(np.float32) * 0.9
    mono = native[..., 0].astype(np.float32)
    calls = [
        lambda im: ig.remap(im, (mx, my)),
        lambda im: ig.add_lateral_ca(im, 1.001, 0.999),
        lambda im: ig.render_aberrated(im[..., 0], np.full((3, 3), 1 / 9)),
    ]
    for call in calls:
        np.testing.assert_array_equal(call(big), call(native))
    np.testing.assert_array_equal(
        ig.similarity(mono.astype(">f4"), mono[::-1].astype(">f4")),
        ig.similarity(mono, mono[::-1]),
    )


@pytest.mark.parametrize("dtype", [bool, np.complex64, object])
def test_maps_of_anything_but_real_numbers_are_refused(dtype):
    # A cast to float32 would read True as 1, drop an imaginary part, parse strings.
    x = np.zeros((2, 2), dtype)
    y = np.zeros((2, 2), np.float32)
    with pytest.raises(TypeError, match="map_x must be an array of real numbers"):
        ig.remap(np.ones((4, 4), np.float32), (x, y))


def test_undistort_map_matches_opencv_map():
    cv2 = pytest.importorskip("cv2")
    mx, my = cv2.initUndistortRectifyMap(K, LENS, None, K, (W, H), cv2.CV_32FC1)
    ours = ig.undistort_map(K, LENS, (H, W))
    px, py = ours.planes()
    assert ours.shape == (H, W)
    # Stored to 1/256 px; OpenCV computes in float64 and rounds to float32.
    np.testing.assert_allclose(px, mx, atol=1 / 512 + 1e-4)
    np.testing.assert_allclose(py, my, atol=1 / 512 + 1e-4)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_undistort_image_agrees_with_opencv_bilinear(dtype):
    cv2 = pytest.importorskip("cv2")
    img = smooth(dtype=dtype)
    mx, my = cv2.initUndistortRectifyMap(K, LENS, None, K, (W, H), cv2.CV_32FC1)
    ref = cv2.remap(img, mx, my, cv2.INTER_LINEAR)
    ours = ig.undistort_image(img, K, LENS)
    # OpenCV rounds positions to 1/32 px (ours: 1/256); on this card's steepest
    # u16 slope (930 levels/px) that alone can move a value by 930 / 64 ~ 15
    # levels, 1/17 of a u8 grey level.
    tolerance = {np.uint8: 1, np.uint16: 16}[dtype]
    diff = np.abs(interior(ours).astype(np.int64) - interior(ref).astype(np.int64))
    assert diff.max() <= tolerance, diff.max()


def test_undistort_image_agrees_with_opencv_at_the_border_too():
    # Both use a constant border: the whole image agrees, edges included.
    cv2 = pytest.importorskip("cv2")
    img = smooth(dtype=np.uint8, channels=1)
    mx, my = cv2.initUndistortRectifyMap(K, LENS, None, K, (W, H), cv2.CV_32FC1)
    ref = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    ours = ig.undistort_image(img, K, LENS)
    assert np.abs(ours.astype(int) - ref).max() <= 2


def test_bicubic_is_close_to_opencv_cubic_and_exact_against_reference():
    cv2 = pytest.importorskip("cv2")
    img = smooth(dtype=np.float32, channels=1)
    mx, my = cv2.initUndistortRectifyMap(K, LENS, None, K, (W, H), cv2.CV_32FC1)
    ours = ig.undistort_image(img, K, LENS, interpolation="bicubic")
    # OpenCV's INTER_CUBIC is Keys with a = -0.75 (ours: -0.5): close on a smooth image.
    ref = cv2.remap(img, mx, my, cv2.INTER_CUBIC)
    assert np.abs(interior(ours) - interior(ref)).max() < 2e-3
    # Exact Keys a = -0.5 in float64 at the same (1/256 px) positions.
    px, py = ig.undistort_map(K, LENS, (H, W)).planes()
    np.testing.assert_allclose(
        interior(ours), interior(keys_reference(img, px, py)), atol=2e-5, rtol=0
    )


def keys_reference(img, px, py, a=-0.5):
    """Straightforward NumPy bicubic (Keys) for interior positions."""

    def kernel(d):
        d = np.abs(d)
        near = ((a + 2) * d - (a + 3)) * d * d + 1
        far = a * (d - 1) * (d - 2) ** 2
        return np.where(d <= 1, near, np.where(d < 2, far, 0.0))

    x0, y0 = np.floor(px).astype(int), np.floor(py).astype(int)
    h, w = img.shape
    out = np.zeros(px.shape)
    for j in range(-1, 3):
        for i in range(-1, 3):
            xi, yi = np.clip(x0 + i, 0, w - 1), np.clip(y0 + j, 0, h - 1)
            out += kernel(px - (x0 + i)) * kernel(py - (y0 + j)) * img[yi, xi]
    return out


@pytest.mark.parametrize("interpolation", ["bilinear", "bicubic"])
def test_distort_then_undistort_recovers_a_smooth_image(interpolation):
    img = smooth(dtype=np.float32)
    distorted = ig.distort_image(img, K, LENS, interpolation=interpolation)
    back = ig.undistort_image(distorted, K, LENS, interpolation=interpolation)
    tol = 6e-3 if interpolation == "bilinear" else 2e-3
    assert np.abs(interior(back, 30) - interior(img, 30)).max() < tol


def test_division_model_and_new_k():
    img = smooth(dtype=np.uint16, channels=1)
    new_k = K.copy()
    new_k[:2, :2] *= 0.8
    m = ig.undistort_map(K, [-0.3], (H, W), model="division", new_K=new_k)
    np.testing.assert_array_equal(
        ig.undistort_image(img, K, [-0.3], model="division", new_K=new_k), ig.remap(img, m)
    )
    # Near the principal point (159.5, 119.5) the lens is the identity, so the
    # map only rescales by K's focal length over new_K's.
    px, py = m.planes()
    assert abs(px[119, 159] - (159.5 - 0.5 / 0.8)) < 0.01
    assert abs(py[119, 159] - (119.5 - 0.5 / 0.8)) < 0.01


def test_precomputed_map_is_reused_and_camera_objects_work():
    class Camera:  # duck-typed stand-in for imgform_rs.Camera
        def __init__(self, K, dist):
            self.K, self.dist = K, dist

    cam = Camera(K, LENS)
    img = smooth(dtype=np.uint8)
    m = ig.undistort_map(cam, shape=img.shape)
    a = ig.undistort_image(img, map=m)
    np.testing.assert_array_equal(a, ig.undistort_image(img, cam))
    np.testing.assert_array_equal(a, ig.undistort_image(img, K, LENS))
    assert repr(m) == f"RemapMap(shape=({H}, {W}))"


def test_fill_and_nan_sources():
    img = np.full((4, 4), 9, np.uint8)
    x = np.array([[1.0, np.nan, -5.0, 3.5]], np.float32)
    y = np.array([[1.0, 1.0, 1.0, 1.0]], np.float32)
    out = ig.remap(img, (x, y), fill=201)
    # In range; NaN and far outside give fill; half a pixel off the edge blends.
    assert out.tolist() == [[9, 201, 201, 105]]


def test_strong_lens_leaves_fill_beyond_the_fold():
    img = np.full((H, W), 1.0, np.float32)
    out = ig.distort_image(img, K, [-0.9, 0.0, 0.0, 0.0], fill=-1.0)
    px, _ = ig.distort_map(K, [-0.9, 0.0, 0.0, 0.0], (H, W)).planes()
    assert np.isnan(px[0, 0]) and out[0, 0] == -1.0
    assert out[H // 2, W // 2] == 1.0


@settings(max_examples=30, deadline=None)
@given(
    shift=st.tuples(st.floats(-3, 3), st.floats(-3, 3)),
    interpolation=st.sampled_from(["bilinear", "bicubic"]),
)
def test_constant_image_stays_constant_where_all_taps_are_inside(shift, interpolation):
    img = np.full((20, 24, 3), 1234, np.uint16)
    x, y = identity_map(20, 24)
    out = ig.remap(img, (x + shift[0], y + shift[1]), interpolation=interpolation)
    assert (out[5:-5, 5:-5] == 1234).all()


@settings(max_examples=30, deadline=None)
@given(dx=st.integers(-4, 4), dy=st.integers(-4, 4))
def test_integer_shift_is_exact_roll(dx, dy):
    img = smooth(40, 50, channels=1, dtype=np.uint16)
    x, y = identity_map(40, 50)
    for interpolation in ("bilinear", "bicubic"):
        out = ig.remap(img, (x - dx, y - dy), interpolation=interpolation)
        np.testing.assert_array_equal(out[5:-5, 5:-5], np.roll(img, (dy, dx), (0, 1))[5:-5, 5:-5])


@settings(max_examples=30, deadline=None)
@given(t=st.tuples(st.floats(0, 1), st.floats(0, 1)))
def test_bilinear_of_an_affine_ramp_is_exact(t):
    # Bilinear interpolation reproduces any affine function inside the image.
    y, x = np.mgrid[0:8, 0:8].astype(np.float32)
    img = 0.25 * x - 0.125 * y + 1.0
    px = np.array([[2 + t[0]]], np.float32)
    py = np.array([[3 + t[1]]], np.float32)
    out = ig.remap(img, (px, py))
    # Positions are stored to 1/256 px.
    qx, qy = np.round(px * 256) / 256, np.round(py * 256) / 256
    assert abs(out[0, 0] - (0.25 * qx - 0.125 * qy + 1.0)[0, 0]) < 1e-5


@settings(max_examples=20, deadline=None)
@given(scale_r=st.floats(0.97, 1.03), scale_b=st.floats(0.97, 1.03))
def test_add_then_correct_lateral_ca_recovers_the_image(scale_r, scale_b):
    img = smooth(dtype=np.float32)
    aberrated = ig.add_lateral_ca(img, scale_r, scale_b, interpolation="bicubic")
    np.testing.assert_array_equal(aberrated[..., 1], img[..., 1])
    back = ig.correct_lateral_ca(aberrated, scale_r, scale_b, interpolation="bicubic")
    assert np.abs(interior(back) - interior(img)).max() < 2e-3


def test_lateral_ca_magnifies_about_the_given_centre():
    img = np.zeros((21, 21, 3), np.uint8)
    img[10, 15] = 255  # a white dot 5 px right of (10, 10)
    out = ig.add_lateral_ca(img, 1.2, 0.8, center=(10, 10))
    assert out[10, 16, 0] == 255  # red moved out to radius 6
    assert out[10, 14, 2] == 255  # blue moved in to radius 4
    assert out[10, 15, 1] == 255 and out[10, 15, 0] < 255  # green stays, red has left
    np.testing.assert_array_equal(out[10, 10], [0, 0, 0])
    back = ig.correct_lateral_ca(out, 1.2, 0.8, center=(10, 10))
    np.testing.assert_array_equal(back[10, 15], [255, 255, 255])


def test_output_is_the_same_for_one_and_two_threads():
    code = """
        import sys, numpy as np, imgform_rs as ig
        rng = np.random.default_rng(5)
        img = rng.integers(0, 65535, (301, 203, 3)).astype(np.uint16)
        K = np.array([[150.0, 0, 101], [0, 150, 150], [0, 0, 1]])
        a = ig.undistort_image(img, K, [-0.3, 0.1, 1e-3, 0], interpolation="bicubic")
        b = ig.distort_image(img.astype(np.float32), K, [-0.3, 0.1, 1e-3, 0])
        c = ig.add_lateral_ca(img, 1.01, 0.99)
        sys.stdout.buffer.write(a.tobytes() + b.tobytes() + c.tobytes())
    """
    one, two = (output_with_threads(code, n) for n in (1, 2))
    assert len(one) == 301 * 203 * 3 * (2 + 4 + 2) and one == two


IMG = np.zeros((8, 8, 3), np.uint8)
IDENT = identity_map(8, 8)


@pytest.mark.parametrize(
    ("call", "exc", "match"),
    [
        (
            lambda: ig.remap(IMG.astype(np.int64), IDENT),
            TypeError,
            "uint8, uint16 or float32.*int64",
        ),
        (lambda: ig.remap(IMG.astype(bool), IDENT), TypeError, "got an array of dtype bool"),
        (lambda: ig.remap(IMG.astype(np.float64), IDENT), TypeError, "dtype float64"),
        (lambda: ig.remap(IMG.tolist(), IDENT), TypeError, "got an object of type list"),
        (lambda: ig.remap(IMG[None], IDENT), ValueError, r"\(H, W\) or \(H, W, C\), got \[1, 8"),
        (lambda: ig.remap(IMG[:, :, :0], IDENT), ValueError, "must not be empty"),
        (
            lambda: ig.remap(IMG, IDENT, interpolation="nearest"),
            ValueError,
            "unknown interpolation",
        ),
        (lambda: ig.remap(IMG, IDENT, fill=300), ValueError, "fill must be .* got 300"),
        (lambda: ig.remap(IMG, IDENT, fill=np.nan), ValueError, "fill must be"),
        (lambda: ig.remap(IMG, IMG), TypeError, "map must be a RemapMap"),
        (lambda: ig.remap(IMG, (IDENT[0], IDENT[1][:4])), ValueError, "same shape"),
        (
            lambda: ig.remap(IMG, (IDENT[0][None], IDENT[1])),
            TypeError,
            r"map_x must be a float32 array of shape \(H, W\), got an array .* shape \[1, 8, 8\]",
        ),
        (lambda: ig.undistort_image(IMG, K, [0.1, 0.2]), ValueError, "4, 5 or 8 coefficients"),
        (
            lambda: ig.undistort_image(IMG, np.eye(2), LENS),
            ValueError,
            r"K must have shape \(3, 3\)",
        ),
        (lambda: ig.undistort_map(K, LENS), TypeError, "shape is required"),
        (lambda: ig.undistort_map(K, LENS, (0, 5)), ValueError, "non-empty"),
        (lambda: ig.undistort_map(K, LENS, (-5, 10)), ValueError, "non-empty"),
        (lambda: ig.distort_map(K, LENS, (100_000, 100_000)), MemoryError, "100000x100000"),
        (
            lambda: ig.remap(IMG.astype(np.float32), ig.undistort_map(K, LENS, (4, 4)), fill=1e40),
            ValueError,
            "fill must be",
        ),
        (lambda: ig.undistort_map(K, LENS, (3, 4, 5, 6)), ValueError, "shape must be"),
        # Before: "'int' object is not iterable", a (1, 1) map, and "K must be
        # upper triangular" of the new_K.
        (lambda: ig.undistort_map(K, LENS, 48), ValueError, "shape must be .* got 48"),
        (lambda: ig.undistort_map(K, LENS, (True, True)), ValueError, "shape must be"),
        (
            lambda: ig.undistort_map(K, LENS, (4, 4), new_K=np.diag([100.0, 100.0, 2.0])),
            ValueError,
            r"new_K must be upper triangular with new_K\[2\]",
        ),
        (
            lambda: ig.add_lateral_ca(IMG, np.nan, 1.0),
            ValueError,
            "scale_r must be a finite number > 0",
        ),
        (lambda: ig.add_lateral_ca(IMG, 1.0, 0.0), ValueError, "scale_b must be .* got 0"),
        (lambda: ig.correct_lateral_ca(IMG, -1.0, 1.0), ValueError, "scale_r .* got -1"),
        (
            lambda: ig.add_lateral_ca(IMG[..., 0], 1.0, 1.0),
            ValueError,
            "RGB image .* got 1 channels",
        ),
        (
            lambda: ig.add_lateral_ca(IMG, 1.0, 1.0, center=(1,)),
            ValueError,
            "center must be a pair",
        ),
        (
            lambda: ig.add_lateral_ca(IMG, 1.0, 1.0, center=(np.inf, 0)),
            ValueError,
            "center x must be finite",
        ),
    ],
)
def test_bad_input_is_refused_clearly(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


def test_a_camera_brings_its_own_distortion_model():
    cam = ig.Camera(K, dist=[0.3], model="division", image_size=(H, W))
    own = ig.undistort_map(cam, shape=(H, W)).planes()
    given = ig.undistort_map(K, [0.3], (H, W), model="division").planes()
    np.testing.assert_array_equal(own[0], given[0])
    with pytest.raises(ValueError, match="contradicts the camera's own model"):
        ig.undistort_map(cam, shape=(H, W), model="brown_conrady")


def test_a_strong_barrel_lens_is_inverted_up_to_its_fold_as_opencv_does():
    # r_d = r (1 - 0.34 r² + 0.105 r⁴ - 0.011 r⁶) folds at r = 2.127
    # (r_d = 1.2599), beyond this frame's corners (r_d 1.23).
    cv2 = pytest.importorskip("cv2")
    lens = np.array([-0.34, 0.105, 0.0, 0.0, -0.011])
    k = np.array([[650.0, 0, 639.5], [0, 650, 479.5], [0, 0, 1]])
    px, py = ig.distort_map(k, lens, (960, 1280)).planes()
    assert not np.isnan(px).any() and not np.isnan(py).any()
    corners = np.array([[0.0, 0.0], [1279.0, 959.0], [1279.0, 0.0]])
    ours = ig.undistort_points(corners, lens, K=k)
    ref = cv2.undistortPoints(corners[:, None], k, lens, P=k, criteria=(3, 300, 1e-15))[:, 0]
    np.testing.assert_allclose(ours, ref, atol=1e-6)
    np.testing.assert_allclose(ig.distort_points(ours, lens, K=k), corners, atol=1e-6)


def test_the_division_model_has_no_image_beyond_its_fold():
    # λ = 0.7 > 0: r_u = r_d / (1 + λ r_d²) turns back at r_d = 1/√λ = 1.195.
    k = np.array([[300.0, 0, 319.5], [0, 300, 239.5], [0, 0, 1]])
    px, _ = ig.distort_map(k, [0.7], (480, 640), model="division").planes()
    assert np.isnan(px[479, 639]) and not np.isnan(px[240, 320])
    cam = ig.Camera(k, dist=[0.7], model="division", image_size=(480, 640))
    assert np.isnan(cam.rays([639.0, 479.0])).all()
    ray = cam.rays([600.0, 400.0])
    np.testing.assert_allclose(cam.project(cam.center + 2 * ray), [600.0, 400.0], atol=1e-9)


def test_camera_and_dist_together_is_refused():
    class Camera:
        K, dist = K, LENS

    with pytest.raises(TypeError, match="dist was given twice"):
        ig.undistort_image(IMG, Camera(), LENS)
