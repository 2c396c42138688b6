"""Synthetic saturated, weakly correlated images for training the learned demosaicers.

Why: the photographs of :mod:`imgform_rs.training.catalogue` are mostly wallpapers
and well-lit snapshots whose detail lies in the luminance, so their three channels
move together and a demosaicer trained on them learns to lean on that correlation
(to take red and blue detail from green). The benchmark sets also hold saturated
film scans whose channels are weakly correlated: a red flower on green leaves, blue
print on a yellow sign, dyed cloth. These three generators add such content:

- :func:`colour_field_image`: a natural photograph's luminance times a field of
  highly saturated hues that drift smoothly across the image and turn with the
  brightness. Where the field is pure red there is no green or blue detail to borrow,
  and where the hue turns, the channels change in opposite directions.
- :func:`text_image`: coloured letters on coloured blocks, in contrasting hues
  (Pillow's built-in font; nothing is downloaded).
- :func:`fabric_image`: woven cloth of saturated threads (plain, twill or basket
  weave) with shaded threads and a gentle waviness.

Every image is band-limited, so it is valid ground truth for demosaicing: text and
cloth are drawn at :data:`SUPERSAMPLE` times their size and area-averaged down,
which anti-aliases their edges as a sensor's pixel area does; the colour field is a
cubic spline through a coarse grid plus the photograph's luminance, which was
already area-downsampled. Thread periods are 6 to 20 pixels, well below the 2-pixel
Nyquist period: the sinusoidal fabrics tried for raisr had near-Nyquist content,
whose aliasing dominated the error (see :mod:`imgform_rs.training.demosaic`).

Each image draws from its own :class:`numpy.random.Generator`, so a seed gives the
same arrays on every run (text depends on Pillow's FreeType rendering, so bytes may
differ between Pillow versions, never between runs).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from imgform_rs.training.photos import area_downsample

#: Text and cloth are drawn this many times larger, then area-averaged down.
SUPERSAMPLE = 4
#: Rec. 709 luma weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: Thread period range, output pixels: far from the 2-pixel Nyquist period.
THREAD_PERIOD = (6.0, 20.0)
#: Letter height range, output pixels: from small print to headings.
TEXT_SIZE = (9, 40)
_ALPHABET = np.array(list("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789"))


def hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """RGB of hue ``h`` (turns, any real: it wraps), saturation and value in [0, 1],
    stacked on a new last axis."""
    h6 = np.mod(h, 1.0) * 6.0
    sector = np.floor(h6).astype(int) % 6
    f = h6 - np.floor(h6)
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    # The six sectors of the hexcone, each a (red, green, blue) choice.
    table = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)]
    return np.stack([np.choose(sector, [row[c] for row in table]) for c in range(3)], axis=-1)


def saturated_colours(rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` random colours of saturation 0.8-1 and value 0.6-1, shaped (count, 3)."""
    return hsv_to_rgb(rng.random(count), rng.uniform(0.8, 1.0, count), rng.uniform(0.6, 1.0, count))


def smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cells: int) -> np.ndarray:
    """A smooth random field in about [0, 1]: a cubic spline through a grid of about
    ``cells`` uniform values along the longer side."""
    h, w = shape
    grid = (max(2, round(cells * h / max(h, w))) + 2, max(2, round(cells * w / max(h, w))) + 2)
    coarse = rng.random(grid)
    # The spline spans the inner grid, so the border cells only steer its slope.
    rows = np.linspace(1, grid[0] - 2, h)
    cols = np.linspace(1, grid[1] - 2, w)
    return ndimage.map_coordinates(coarse, np.meshgrid(rows, cols, indexing="ij"), order=3)


def colour_field_image(luminance: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A photograph's luminance (H, W) times a field of saturated hues, scaled so that
    its brightest 0.5 % just clip; float32 (H, W, 3) in [0, 1].

    The hue is a smooth random field plus a multiple of the luminance itself: objects
    differ in colour as well as in brightness (a yellow flower on dark leaves), so at
    the photograph's edges the hue turns and the channels change in opposite
    directions; inside an object the colour is one saturated hue.
    """
    shape = luminance.shape
    # At most about two thirds of the colour wheel across the image: a few broad hues,
    # as in a scene, rather than a rainbow.
    hue = rng.random() + rng.uniform(0.25, 0.7) * smooth_noise(rng, shape, int(rng.integers(2, 5)))
    hue += rng.uniform(0.2, 0.6) * luminance
    saturation = 0.85 + 0.15 * smooth_noise(rng, shape, 3)
    field = hsv_to_rgb(hue, saturation, np.ones(shape))
    image = luminance[..., None] * field
    scale = np.quantile(image.max(axis=-1), 0.995)
    return np.clip(image / max(scale, 1e-6), 0.0, 1.0).astype(np.float32)


def text_image(rng: np.random.Generator, size: int) -> np.ndarray:
    """Lines of random letters in saturated colours on blocks of contrasting saturated
    colours; float32 (size, size, 3) in [0, 1]."""
    from PIL import Image, ImageDraw, ImageFont

    big = size * SUPERSAMPLE
    canvas = Image.new("RGB", (big, big))
    draw = ImageDraw.Draw(canvas)
    background_hues = []
    for _ in range(int(rng.integers(2, 6))):
        hue = rng.random()
        background_hues.append(hue)
        x0, y0 = rng.integers(0, big, 2)
        x1, y1 = x0 + rng.integers(big // 3, big, 2)
        colour = hsv_to_rgb(
            np.array(hue), np.array(rng.uniform(0.8, 1)), np.array(rng.uniform(0.5, 1))
        )
        draw.rectangle((int(x0) - big, int(y0) - big, int(x1), int(y1)), fill=_rgb8(colour))
    y = int(rng.integers(-SUPERSAMPLE * TEXT_SIZE[0], SUPERSAMPLE * TEXT_SIZE[0]))
    while y < big:
        height = SUPERSAMPLE * int(rng.integers(*TEXT_SIZE))
        font = ImageFont.load_default(size=height)
        # Opposite the blocks' hues on the colour wheel, so the letters stand out in
        # chroma, not only in brightness.
        hue = rng.choice(background_hues) + rng.uniform(0.3, 0.7)
        colour = hsv_to_rgb(
            np.array(hue), np.array(rng.uniform(0.8, 1)), np.array(rng.uniform(0.5, 1))
        )
        text = "".join(rng.choice(_ALPHABET, int(rng.integers(4, 40))))
        draw.text((int(rng.integers(-big // 4, big // 2)), y), text, fill=_rgb8(colour), font=font)
        y += int(height * rng.uniform(1.1, 1.8))
    pixels = np.asarray(canvas)
    return (area_downsample(pixels, SUPERSAMPLE) / 255.0).astype(np.float32)


def _rgb8(colour: np.ndarray) -> tuple[int, int, int]:
    r, g, b = np.round(np.asarray(colour) * 255).astype(int).tolist()
    return (r, g, b)


def _weave(rng: np.random.Generator, warp: np.ndarray, weft: np.ndarray) -> np.ndarray:
    """Whether the warp thread lies on top at each crossing (thread indices)."""
    kind = int(rng.integers(3))
    if kind == 0:  # plain
        return (warp + weft) % 2 == 0
    if kind == 1:  # 2/2 twill: the diagonal ribs of denim
        return (warp - weft) % 4 < 2
    return (warp // 2 + weft // 2) % 2 == 0  # basket


def fabric_image(rng: np.random.Generator, size: int) -> np.ndarray:
    """Woven cloth of saturated threads, slightly rotated and wavy, threads shaded
    across their width; float32 (size, size, 3) in [0, 1]."""
    big = size * SUPERSAMPLE
    period = SUPERSAMPLE * rng.uniform(*THREAD_PERIOD)
    angle = rng.uniform(-0.5, 0.5)
    y, x = np.mgrid[0:big, 0:big].astype(np.float32)
    # Coordinates in thread periods, rotated, with a gentle waviness many threads long.
    u = (np.cos(angle) * x + np.sin(angle) * y) / period
    v = (np.cos(angle) * y - np.sin(angle) * x) / period
    u += 0.3 * np.sin(2 * np.pi * v / rng.uniform(8, 20))
    v += 0.3 * np.sin(2 * np.pi * u / rng.uniform(8, 20))
    warp, weft = np.floor(u).astype(int), np.floor(v).astype(int)
    on_top = _weave(rng, warp, weft)
    # Stripes: each thread takes one of a few colours, in a repeating sequence.
    warp_colours = saturated_colours(rng, int(rng.integers(1, 4)))
    weft_colours = saturated_colours(rng, int(rng.integers(1, 4)))
    warp_stripes = rng.integers(len(warp_colours), size=int(rng.integers(2, 12)))
    weft_stripes = len(warp_colours) + rng.integers(
        len(weft_colours), size=int(rng.integers(2, 12))
    )
    palette = np.concatenate([warp_colours, weft_colours]).astype(np.float32)
    colour = palette[
        np.where(
            on_top, warp_stripes[warp % len(warp_stripes)], weft_stripes[weft % len(weft_stripes)]
        )
    ]
    # A round thread is brightest along its middle and dark in the gaps.
    across = np.where(on_top, u - warp, v - weft)
    shade = np.sqrt(np.sin(np.pi * across))
    image = colour * (0.25 + 0.75 * shade)[..., None]
    return area_downsample(image, SUPERSAMPLE).astype(np.float32)


def highpass_correlation(rgb: np.ndarray) -> float:
    """The mean, over the three channel pairs, of the correlation between the
    channels' high-pass (the image less its 5x5 box blur): near 1 where the detail
    is all luminance, lower where the channels carry their own detail."""
    detail = rgb - ndimage.uniform_filter(rgb, size=(5, 5, 1), mode="reflect")
    flat = detail.reshape(-1, 3).T
    c = np.corrcoef(flat)
    return float((c[0, 1] + c[0, 2] + c[1, 2]) / 3)
