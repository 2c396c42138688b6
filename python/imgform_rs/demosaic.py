"""Demosaicing (lecture section 6): the two colours each photosite did not see.

Methods, all for uint8 / uint16 / float32 mosaics (and float16, float64 or other
integer ones, converted as :func:`demosaic` says); every one but ``"markesteijn"``
for the four Bayer phases, ``"bilinear"`` and ``"markesteijn"`` for X-Trans:

- ``"nearest"``: each 2x2 cell's red and blue, and the green of the pixel's row,
  copied to the cell's pixels. Blocky; a baseline.
- ``"bilinear"``: the mean of the nearest samples of each colour.
- ``"malvar2004"``: Malvar, He and Cutler, "High-quality linear interpolation for
  demosaicing of Bayer-patterned color images", ICASSP 2004 — bilinear corrected
  by the Laplacian of the colour sampled at the site.
- ``"hamilton_adams"``: Hamilton and Adams, US patent 5,629,734 (1997) — green
  interpolated along the direction of smaller gradient plus second derivative,
  red and blue from colour differences, with the same choice between diagonals.
- ``"rcd"``: Ratio Corrected Demosaicing, Luis Sanz Rodríguez (2017) — green from
  the four cardinal neighbours, each scaled by a low-pass luminance ratio and
  weighted by inverse gradients, blended by a local vertical/horizontal statistic;
  red and blue from colour differences along the diagonals, then the cardinals.
  Outputs are clamped to the range of the input mosaic. Mean CPSNR 38.7 dB on the
  benchmark's seven scikit-image images (Hamilton-Adams 38.1).
- ``"menon2007"``: Menon, Andriani and Calvagno, "Demosaicing with directional
  filtering and a posteriori decision", IEEE Transactions on Image Processing
  16(1), 2007, with its refinement step — green interpolated along rows and
  columns, the direction chosen afterwards from colour-difference gradients over a
  5x5 window. Matches colour-demosaicing's ``demosaicing_CFA_Bayer_Menon2007`` in
  the interior (to float32 precision, up to ties of the decision). Outputs are
  clamped to the range of the input mosaic. Mean CPSNR 38.8 dB on the benchmark's
  images.
- ``"rcd_menon"``: the mean of ``"rcd"`` and ``"menon2007"``, computed in one pass.
  Not a method from the literature: the two err in different places (RCD is better
  on fine texture, Menon on long edges), so the mean has a lower error than either.
  Outputs are clamped to the range of the input mosaic.
- ``"ahd"``: Hirakawa and Parks, "Adaptive homogeneity-directed demosaicing
  algorithm", IEEE Transactions on Image Processing 14(3), 2005 — complete images
  interpolated along rows and along columns, and per pixel the one whose CIELab
  neighbourhood is more homogeneous (3x3 sums of homogeneity counts). Outputs are
  clamped to the range of the input mosaic. Mean CPSNR 38.26 dB (LibRaw AHD 38.27).
- ``"leung2011"``: frequency-domain luma-chroma demultiplexing. The mosaic is luma
  plus chroma modulated at (π, π), (π, 0) and (0, π) (Alleysson, Süsstrunk and
  Hérault, "Linear demosaicing inspired by the human visual system", IEEE TIP
  14(4), 2005); the chroma is demodulated by filters designed by least squares on
  training images (Leung, Jeon and Dubois, "Least-squares luma-chroma
  demultiplexing algorithm for Bayer demosaicking", IEEE TIP 20(7), 2011), the
  (π, 0) and (0, π) copies weighted per pixel by the local luma energy that
  disturbs each (Dubois, "Frequency-domain methods for demosaicking of
  Bayer-sampled color images", IEEE SPL 12(12), 2005); luma is the rest. Our
  filters are separable (11 + 2 taps per axis) for speed and put an exact zero
  on each carrier, so grey flat areas get no false colour at all; they are
  rebuilt by ``python -m imgform_rs.training.leung2011`` (``make filters``) from
  openly licensed images, none of the benchmark's. Outputs are clamped to the
  range of the input mosaic. Mean CPSNR 38.99 dB on the benchmark's images
  (``"malvar2004"`` 37.39).
- ``"mlri"``: residual interpolation, the green stage as in Kiku, Monno, Tanaka and
  Okutomi, "Residual interpolation for color image demosaicking", ICIP 2013 (RI), red
  and blue as in their "Minimized-Laplacian residual interpolation for color image
  demosaicking", Proc. SPIE 9023, Digital Photography X, 2014 (MLRI) — guided filters
  turn a linearly interpolated guide into tentative values, and the residuals between
  samples and tentative values, smoother than colour differences, are interpolated
  instead: green along rows and along columns (11-sample windows, least-squares
  lines), combined with weights from the gradients of the two colour differences over
  5x5 windows on each side, then red and blue guided by the full green over 11x11
  windows (slopes fitted on Laplacians). These choices between the papers were made
  on the training photographs of ``"raisr"``; together they gained 2.4 dB on CBSD68
  and 1.9 on Urban24 over the MLRI code's (3x3 windows, Laplacians throughout).
  Outputs are clamped to the range of the input mosaic. Mean CPSNR (8-bit protocol,
  see ``"best"``) 39.80 dB on the scikit-image seven, 38.89 on CBSD68, 35.70 on
  Urban24; wide support (30 pixels), about 1.1x the time of ``"rcd_menon"``.
- ``"raisr"``: a learned refinement of ``"mlri"`` in the manner of Romano, Isidoro
  and Milanfar, "RAISR: Rapid and Accurate Image Super Resolution", IEEE
  Transactions on Computational Imaging 3(1), 2017: per CFA position and class of
  the structure tensor of the base's green (8 angles, 3 strengths, 3 coherences), a
  least-squares linear filter maps 26 local colour differences of the base output to
  the residual of the two missing colours. The filters (60 KB, shipped in the
  extension) are trained by ``python -m imgform_rs.training.demosaic`` (``make
  training-data`` fetches the photographs, ``make weights`` rebuilds the shipped file
  bit for bit) on 293 openly licensed photographs (:mod:`imgform_rs.training.sets`,
  set ``"photos"``), never on the benchmark's images. Not flip-symmetric. Outputs
  are clamped to the range of the input mosaic. Mean CPSNR 39.90 dB on the
  scikit-image seven, 39.92 on CBSD68, 36.29 on Urban24: 0.1 / 1.0 / 0.6 dB above
  ``"mlri"``, 0.7-1.1 dB above every classical peer we run, and within 0.2 dB of
  ``"fusion"`` on each subset. On the seven (astronaut 37.56, coffee 36.47, chelsea
  42.42, rocket 33.04, immunohistochemistry 43.49, retina 51.06, motorcycle_left
  35.25) it gains most on fine texture and loses a little on the synthetic rocket
  and the motorcycle's saturated paint. ``"mlri"`` streams down tall tiles, and
  each row it hands over completes the refinement of the row two above it (rings of
  four rows of ``"mlri"`` and three of the hash's sums; the same bits as refining
  whole planes): 77 MP/s at 24 MP on two cores, 1.4x the time of ``"mlri"`` and
  2.8x LibRaw's AHD (``benchmarks/demosaic.py``, 2026-12-06), and 4 % of the output
  in extra memory.
- ``"raisr_fast"``: ``"raisr"`` with a hash of orientation and shape alone. Its 32
  filters are chosen by the CFA position, the quadrant of the doubled orientation of
  the structure tensor (horizontal, diagonal, vertical or anti-diagonal gradients)
  and whether the tensor is anisotropic (an edge, against texture or flat: RAISR's
  coherence above 0.3, tested without a square root): so few that along a row each
  tap takes one of 16 values, and sixteen pixels are filtered side by side, each tap
  one permute of a 16-entry table by the pixels' classes (with AVX2, eight pixels and
  two permutes and a blend), instead of fetching each pixel's filter. Same features,
  base and training as ``"raisr"`` (``python -m imgform_rs.training.demosaic --method
  raisr_fast``; 6 KB of filters). Not flip-symmetric. Outputs are clamped to the
  range of the input mosaic. Mean CPSNR 39.69 dB on the scikit-image seven, 39.84 on
  CBSD68, 36.20 on Urban24: within 0.2 dB of ``"raisr"`` on each subset and 0.6-0.9
  dB above every classical peer we run. On the grey zone plate less false colour than
  ``"mlri"`` (11939 against 13662; zipper 35.9 % against 37.2 %). 92 MP/s at 24 MP
  on two cores, 1.2x the time of ``"mlri"``, 3.3x LibRaw's AHD and 1.2x as fast as
  ``"raisr"`` (``benchmarks/demosaic.py``, 2026-12-06), in 4 % of the output in
  extra memory.
- ``"ri_cd"``: ``"mlri"``'s green (residual interpolation along rows and columns,
  combined by the colour-difference gradients), then red and blue by colour
  differences to that green, each interpolated along the smoother of two directions:
  first at the other chroma's sites from the two diagonals, then at the green sites
  from the vertical and horizontal neighbours, each direction weighted by the
  reciprocal of its squared gradient (of the differences, of green and half green's
  second difference), as Hamilton and Adams's colour differences with GBTF-style
  weights. It replaces ``"mlri"``'s red / blue guided filters, ~40 % of that
  method's time. Flip-symmetric; outputs are clamped to the range of the input
  mosaic. Mean CPSNR 39.72 dB on the scikit-image seven, 39.10 on CBSD68, 35.77 on
  Urban24: on the two validation subsets above ``"mlri"`` (38.89, 35.70), whose
  guided chroma wins only on the seven, and above every classical peer we run on
  each subset. The base of ``"raisr_cd"``.
- ``"raisr_cd"``: ``"raisr_fast"``'s 32 filters hashed by orientation and shape,
  trained over ``"ri_cd"`` instead of ``"mlri"`` (``python -m
  imgform_rs.training.demosaic --method raisr_cd``; 13 KB): the filters recover what
  the cheaper chroma loses. Like ``"fusion"``, it splits each class in two by how
  colourful the base is around the pixel, and bounds its corrections the same way:
  on the nine held-out photographs with their chroma doubled and tripled it scores
  33.72 and 31.74 dB (0.22 and 0.52 dB more than without; ``"mlri"`` 33.76 and
  31.95). Within 0.06 dB of ``"raisr_fast"`` on each validation subset (39.67 dB on
  the scikit-image seven, 39.84 on CBSD68, 36.26 on Urban24; 0.70-0.87 dB above every
  classical peer we run on each) at 0.80x its time: 115 MP/s at 24 MP
  on two cores, 4.1x LibRaw's AHD, in 3.7 % of the output in extra memory
  (``benchmarks/demosaic.py``, 2026-12-06; ``"raisr_fast"`` 92 MP/s, ``"mlri"``
  108). Less false colour and zipper on the grey charts than any other
  residual-interpolation method (zone plate 5040 and 34.4 % against
  ``"raisr_fast"``'s 11939 and 35.9 %). Its classes split each orientation by shape:
  0.05-0.06 dB more than orientation alone on CBSD68, Urban24 and the held-out
  photographs, for 9 % more false colour on the zone plate. On the nine held-out
  training photographs 0.09 dB below ``"raisr_fast"``. Not flip-symmetric. Outputs are
  clamped to the range of the input mosaic.
- ``"fusion"``: a learned adaptive fusion of ``"ri_cd"`` and ``"rcd"``. No
  single classical method leads everywhere: residual interpolation wins where the
  colour channels are weakly correlated (saturated colours), colour differences where
  they are strongly correlated (most photographs). Here the filters of ``"raisr"``
  refine ``"ri_cd"`` and also see the ``"rcd"`` output's difference from it over
  the 3x3 window (53 features per pixel), so that per CFA position and class of local
  structure they learn how far to trust either and how to correct both. The filters
  (240 KB) are trained by ``python -m imgform_rs.training.demosaic --method fusion``
  on 293 openly licensed photographs (:mod:`imgform_rs.training.sets`, set
  ``"photos"``), never on the benchmark's images. Each class of local structure is
  split in two by how colourful the base is around the pixel (the absolute means of
  ``R - G`` and ``B - G`` over the four CFA quads nearest it, added, at least 0.3 of
  the full scale):
  where colours are saturated the channels are weakly correlated, and those pixels
  get filters of their own, fitted also on a fifth of the photographs with their
  chroma scaled by 1.5-3 (set ``"saturated-photos"``). On the nine held-out
  photographs with their chroma doubled and tripled, that adds 0.21 and 0.54 dB
  (33.95 and 31.92 dB; ``"mlri"`` 33.76 and 31.95), with no loss at their own
  colours. Not flip-symmetric. Outputs are clamped to the range of the input mosaic.
  Mean CPSNR 39.96 dB on the scikit-image seven, 39.96 on CBSD68, 36.47 on Urban24:
  0.9-1.2 dB above every classical peer we run, still 1.3-1.7 dB below the deep
  demosaicnet. Where the mosaic aliases, ``"rcd"``'s colours stray, so the filters
  see its differences clamped (to 32/255 of the full scale) and move no missing
  colour's difference from green more than 8/255 from ``"ri_cd"``'s: on the grey zone
  plate 5690 of false colour (``"mlri"`` 13662, ``"raisr_cd"`` 5040; 7898 unbounded
  before the saturated classes) for 0.01 dB on each subset. Over ``"mlri"``
  instead (unbounded) it scores 0.02-0.07 dB more on each subset, at 1.3 times the
  time and with 1.7 times the false colour (13163). ``"ri_cd"``,
  ``"rcd"`` and the filters all stream down tiles as tall as the image, a row at a
  time, each keeping only the rows later stages still read: 61 MP/s at 24 MP on two
  cores (2.18x LibRaw's AHD, 2.7x the time of ``"ri_cd"``; ``benchmarks/demosaic.py``,
  2026-12-06) and 4.4 % of the output in extra memory.
  The 36 training photographs under CC-BY licences are credited in
  :data:`imgform_rs.training.catalogue.ATTRIBUTION`.
- ``"fusion_refined"``: ``"fusion"`` refined by a second stage, a cascade: the 32
  orientation- and shape-hashed filters of ``"raisr_fast"`` trained over
  ``"fusion"``'s output (``python -m imgform_rs.training.demosaic --method
  fusion_refined``; 6 KB), applied to its rows as they stream out, with rings of a
  few rows (0.5 MiB more memory). The second stage sees what the first leaves: a
  correction learned on the residual of the fusion itself. Mean CPSNR 39.99 dB on
  the scikit-image seven, 40.13 on CBSD68, 36.58 on Urban24 (+0.17 and +0.11 dB over
  ``"fusion"`` on CBSD68 and Urban24, +0.03 on the seven; +0.08 on the held-out
  training photographs). With the fusion's saturated classes, on the held-out
  photographs with their chroma doubled and tripled it scores 33.93 and 31.82 dB
  (0.19 and 0.47 dB more than without; ``"mlri"`` 33.76 and 31.95, ``"raisr_cd"``
  33.72 and 31.74). Bounded as ``"fusion"`` is (its moves of each missing colour's
  difference from green within 8/255 of the fusion's), it leaves 5665 of false
  colour on the grey zone plate, below ``"rcd_menon"``'s 6091. Over a fusion based on
  ``"mlri"`` (unbounded, before the saturated classes) it would score 0.02 / 0.08 /
  0.07 dB more, at 1.23 times the time and with 1.64 times the zone plate's false
  colour (13157). 54 MP/s at 24 MP on two cores, 1.13x the time of ``"fusion"`` and
  1.93x LibRaw's AHD (``benchmarks/demosaic.py``, 2026-12-06), 4.8 % of the output
  in extra memory.
  Not flip-symmetric. Outputs are clamped to the range of the input mosaic.
- ``"fusion_cnn"``: ``"fusion_refined"`` corrected by a small convolutional network,
  run by our own kernel (no deep-learning runtime): six 3x3 convolutions over the
  mosaic's 2x2 cells (12 values in, 32 channels between, ReLU, no biases; 26 x 26
  pixels seen), whose output is added to every missing colour (python -m
  imgform_rs.training.cnn; 175 KB). The hashed filters of the learned methods are
  linear within a class, and a class cannot always tell aliasing from texture; the
  network decides that non-linearly over a wider window. Without biases it is
  positively homogeneous: the network needs no white level (its base does). Mean
  CPSNR 40.29 dB on the scikit-image seven, 40.84 on CBSD68, 36.97 on Urban24: 0.30,
  0.71 and 0.39 dB above ``"fusion_refined"`` (38.26 on the nine held-out
  photographs, 0.87 more); 1.35 / 0.46 / 1.07 dB below demosaicnet, which has about
  twelve times its network's work per pixel. On the grey zone plate less false colour
  than any learned method of ours (3499; ``"fusion_refined"`` 5665) and about as much
  zipper (35.7 % of pixels against 35.3 %). Trained with PyTorch on the CPU (the
  ``train`` extra; 60 000 steps, 41 minutes on one core with AMX) on the 293
  photographs, each in its eight flips and transpositions: with the 192 synthetic
  images too, whose errors are ten times the photographs', the small network gained
  nothing on the validation subsets.
  9 MP/s at 24 MP on two cores with AVX-512, 0.36x LibRaw AHD's speed and 32 times
  demosaicnet's (``benchmarks/demosaic.py``, 2026-12-06), nearly all of it the
  network's ~11 k multiply-adds per pixel; AVX2 CPUs run it at about two thirds of that
  speed, x86 CPUs without FMA a hundred times slower, all giving the same bits. 3.9 % of
  the output in extra memory. Not flip-symmetric. Outputs are clamped to the range
  of the input mosaic.
- ``"best"``: our most accurate method at about the speed of the fast ones, currently
  ``"raisr_cd"``, chosen on the benchmark's three validation subsets (``python
  benchmarks/demosaic.py quality``: the seven scikit-image images, the 68 CBSD68
  photographs and the first 24 Urban100 images; 8-bit protocol, RGGB, 10 px crop).
  Mean CPSNR per subset:

  ============================  ==========  ======  =======
  method                        scikit 7    CBSD68  Urban24
  ============================  ==========  ======  =======
  ``"fusion_cnn"`` (quality)    40.29       40.84   36.97
  ``"fusion_refined"``          39.99       40.13   36.58
  ``"fusion"``                  39.96       39.96   36.47
  ``"raisr"``                   39.90       39.92   36.29
  ``"raisr_cd"`` (best)         39.67       39.84   36.26
  ``"raisr_fast"``              39.69       39.84   36.20
  ``"ri_cd"``                   39.72       39.10   35.77
  ``"mlri"``                    39.80       38.89   35.70
  ``"rcd_menon"``               39.63       37.38   34.89
  ``"menon2007"``               38.76       37.60   34.72
  eari-demosaic RI              38.80       38.99   35.56
  LibRaw AAHD                   38.78       35.67   32.73
  ============================  ==========  ======  =======

  The residual-interpolation peer (Kiku et al. 2013, in NumPy), the strongest
  classical one, is 0.87 / 0.85 / 0.70 dB behind ``"best"`` and 0.09 dB ahead of
  ``"mlri"`` alone on CBSD68; LibRaw and colour-demosaicing's Menon2007 are further
  behind on every subset.
- ``"quality"``: the most accurate method whatever its speed, by the mean over the
  three subsets: currently ``"fusion_cnn"`` (0.30-0.71 dB above ``"fusion_refined"``
  on each), ``"markesteijn"`` for X-Trans.

- ``"markesteijn"`` (X-Trans only): Frank Markesteijn's X-Trans method, as in dcraw's
  and LibRaw's ``xtrans_interpolate`` (one pass) — green interpolated along rows,
  columns and both diagonals from the nearest greens plus the site colour's second
  difference, red and blue from colour differences to each direction's green, and
  per pixel the mean of the directions whose YPbPr neighbourhood is the most
  homogeneous (AHD-style counts summed over 5x5). Outputs are clamped to the range of
  the input mosaic. Mean CPSNR 38.63 dB on the benchmark's seven
  scikit-image images mosaiced with X-Trans (8-bit protocol, 10 px crop), against
  X-Trans ``"bilinear"`` 32.77 and LibRaw's Markesteijn (through rawpy) 38.42 with 3
  passes, 38.34 with 1. Per image: astronaut 36.06, coffee 35.15, chelsea 39.70,
  rocket 33.51, immunohistochemistry 39.40, retina 51.66, motorcycle_left 34.91.
  Speed on a 24 MP uint16 mosaic, 2 cores: 31.8 MP/s, LibRaw's 3-pass 4.0 MP/s in
  the same run (8.1x).

Patterns:

=====================  ==============  =========
method                 Bayer           X-Trans
=====================  ==============  =========
``"bilinear"``         yes             yes
``"markesteijn"``      no              yes
``"best"``             raisr_cd        markesteijn
``"quality"``          fusion_cnn      markesteijn
every other method     yes             no
=====================  ==============  =========

X-Trans is ``"XTRANS"`` or a (6, 6) array (any shift, flip or transpose of Fujifilm's
tile) and needs at least 6x6 pixels. X-Trans ``"bilinear"`` takes each missing colour
as the mean of that colour's samples in the smallest window holding one (3x3 inside
the image, weights 4/2/1 as for Bayer), from samples inside the image. ``"markesteijn"``
mirrors the border with each mirrored pixel moved to the nearest sample of the same
colour, which keeps the 6x6 period. A method given a pattern it does not support raises
ValueError naming the methods that do; :data:`BAYER_DEMOSAIC_METHODS` and
:data:`XTRANS_DEMOSAIC_METHODS` list them.

OpenCV names Bayer codes after the second row's first two pixels: our ``"RGGB"`` is
``cv2.COLOR_BayerBG2RGB`` (and OpenCV returns BGR for the ``2BGR`` codes).
"""

from __future__ import annotations

import math
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from . import _native, _samples
from .cfa import Pattern, as_pattern

DEMOSAIC_METHODS: tuple[str, ...] = tuple(_native.DEMOSAIC_METHODS)
"""Every method :func:`demosaic` accepts."""

BAYER_DEMOSAIC_METHODS: tuple[str, ...] = tuple(_native.BAYER_DEMOSAIC_METHODS)
"""The methods :func:`demosaic` accepts for Bayer mosaics (all but ``"markesteijn"``)."""

XTRANS_DEMOSAIC_METHODS: tuple[str, ...] = tuple(_native.XTRANS_DEMOSAIC_METHODS)
"""The methods :func:`demosaic` accepts for X-Trans mosaics."""

SCALED_DEMOSAIC_METHODS: tuple[str, ...] = tuple(_native.SCALED_DEMOSAIC_METHODS)
"""The methods whose result depends on :func:`demosaic`'s ``white_level``
(on Bayer mosaics: the aliases ``"best"`` and ``"quality"`` are
``"markesteijn"`` for X-Trans, which does not depend on it)."""

# Any real dtype: see the Parameters of demosaic for the conversions.
SampleT = TypeVar("SampleT", bound=np.number[Any])


def demosaic(
    raw: npt.NDArray[SampleT],
    pattern: Pattern,
    method: str = "bilinear",
    *,
    white_level: float | None = None,
    out: npt.NDArray[SampleT] | None = None,
) -> npt.NDArray[SampleT]:
    """Reconstruct an RGB image from a Bayer or X-Trans mosaic.

    Parameters
    ----------
    raw : ndarray, shape (H, W), uint8, uint16 or float32; or float16, float64, other integers
        The mosaic, at least 2x2; any layout (copied once if not C-contiguous).
        Other dtypes are converted: integers holding 0..65535 exactly through
        uint16, float16 exactly and float64 through float32 (the result then has
        float32's precision, about 7 digits), and the result is given back in
        ``raw``'s dtype. See ``white_level`` for the scale it is taken on.
    pattern : str or array_like
        ``"RGGB"``, ``"BGGR"``, ``"GRBG"``, ``"GBRG"`` or a (2, 2) array of
        channel indices, describing pixel (0, 0) of ``raw``; or ``"XTRANS"`` or a
        (6, 6) array for X-Trans.
    method : str
        One of :data:`BAYER_DEMOSAIC_METHODS` for Bayer patterns, of
        :data:`XTRANS_DEMOSAIC_METHODS` for X-Trans. ``"best"`` is ``"raisr_cd"``
        for Bayer, ``"quality"`` ``"fusion_cnn"``; both are ``"markesteijn"``
        for X-Trans.
    white_level : float, optional
        The value of a saturated sample, a finite number > 0. The methods of
        :data:`SCALED_DEMOSAIC_METHODS` take their regularisers (``"rcd"``,
        ``"mlri"``, ``"ri_cd"``), Lab scale (``"ahd"``), learned hash and bounds
        (the ``"raisr"`` family, ``"fusion"``, ``"fusion_refined"``) as fractions
        of it; the others do not depend on it. By default, integer mosaics are
        taken at the smallest bit depth of at least 8 that holds their largest
        sample (255, 511, ..., 65535), since raw files keep 10-, 12- and 14-bit
        photosites in uint16 arrays; float mosaics on 0..1, or up to their
        largest sample when it exceeds 1 (data on 0..255 or 0..4095). Pass it
        for a raw file's own white level (rawpy's ``white_level``), or for a
        mosaic whose brightest sample is far from saturation. A wrong level
        costs the learned methods most: 12-bit mosaics taken at uint16's full
        scale (65535, 16 times too high) score 0.8 / 3.4 / 1.9 dB less with
        ``"fusion_refined"`` on the seven scikit-image images / CBSD68 /
        Urban24, and 1.5 / 4.4 / 2.4 less with ``"raisr"``; at their bit depth
        they score as the 8-bit images do (to 0.01 dB).
    out : ndarray, shape (H, W, 3), same dtype as ``raw``, optional
        Where to write the result, returned instead of a new array: C-contiguous,
        writeable, sharing no memory with ``raw``. Reusing one buffer over many
        images of one size saves the page faults and zeroing of a fresh output
        (3-14 % of a 24 MP call in our profiles, less where the OS grants huge
        pages). Left in an unspecified state if the call raises.

    Returns
    -------
    ndarray, shape (H, W, 3), same dtype as ``raw`` (``out`` if given)
        R, G, B. Each sampled value comes back unchanged at its own site.
        Integer outputs are rounded half up and clamped to the dtype's range,
        not to a white level: Malvar's and Hamilton-Adams's overshoot can pass a
        12-bit raw's 4095 in uint16 (clip where that matters). Float outputs are
        not clamped, except by ``"rcd"``, ``"menon2007"``, ``"rcd_menon"``,
        ``"ahd"``, ``"leung2011"``, ``"mlri"``, ``"raisr"``, ``"raisr_fast"``,
        ``"ri_cd"``, ``"raisr_cd"``, ``"fusion"``, ``"fusion_refined"``,
        ``"fusion_cnn"`` and ``"markesteijn"``, which clamp every output to
        ``[raw.min(), raw.max()]``.
        Borders are reconstructed from a mirrored mosaic (edge not repeated,
        which keeps the CFA phase): no black frame, no wrap-around.

    Raises
    ------
    TypeError
        For a bool or complex dtype, None, a non-str method,
        a pattern of the wrong type, a ``white_level`` that is not a real
        number, or an ``out`` that is not an array of ``raw``'s dtype.
    ValueError
        For a shape other than (H, W), an image smaller than 2x2, an unknown
        method or pattern, a method that does not support the pattern (a Bayer-only
        method for X-Trans or ``"markesteijn"`` for Bayer), an X-Trans mosaic
        smaller than 6x6, a float mosaic holding NaN or an infinity (the
        message names the first one's row and column), an integer mosaic with
        values outside 0..65535, a float64 one beyond float32's range, a
        ``white_level`` that is not a finite number > 0 within float32's
        range, or an ``out`` of the wrong
        shape, not C-contiguous, read-only or overlapping ``raw``.

    Examples
    --------
    >>> raw = np.full((4, 6), 100, np.uint16)
    >>> demosaic(raw, "RGGB", "malvar2004")[2, 3].tolist()
    [100, 100, 100]

    A 12-bit raw in a uint16 array is demosaicked at its bit depth:

    >>> twelve = (np.arange(64, dtype=np.uint16).reshape(8, 8) * 64) % 4096
    >>> bool((demosaic(twelve, "RGGB", "quality")
    ...       == demosaic(twelve, "RGGB", "quality", white_level=4095)).all())
    True
    """
    if not isinstance(method, str):
        raise TypeError(f"method must be a str, one of {DEMOSAIC_METHODS}, got {method!r}")
    level = _white_level(white_level)
    arr = _samples.as_array(raw, "raw")
    if arr.dtype in _samples.NATIVE:
        return _native.demosaic(arr, as_pattern(pattern), method, white_level=level, out=out)
    kernel_raw = _samples.to_kernel(arr, "raw")
    result = _native.demosaic(kernel_raw, as_pattern(pattern), method, white_level=level)
    result = _samples.from_kernel(result, arr.dtype)
    return result if out is None else _samples.fill_out(out, result, arr)


def _white_level(value: Any) -> float | None:
    """``value`` checked as :func:`demosaic`'s ``white_level``."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"white_level must be a real number or None, got {value!r}")
    try:
        level = float(value)
    except OverflowError:  # an int beyond float64's range
        level = math.inf
    if not (np.isfinite(level) and _samples.F32_TINY <= level <= _samples.F32_MAX):
        raise ValueError(
            f"white_level must be a finite number > 0 within float32's range, got {value!r}"
        )
    return level


def demosaic_halo(method: str, pattern: Pattern) -> int:
    """How far a method's output reaches into the mosaic, in pixels.

    Output pixel ``(y, x)`` of :func:`demosaic` depends only on the mosaic
    pixels with ``|dy|, |dx| <= halo`` (and, for the methods that clamp, on
    the mosaic's range). A chunked caller pads each chunk by at least this
    much to reproduce the whole-image result; :func:`imgform_rs.batch.demosaic_dask`
    does.

    Parameters
    ----------
    method : str
        One of :data:`DEMOSAIC_METHODS`; an alias (``"best"``,
        ``"quality"``) gives the halo of the method it selects for
        ``pattern``.
    pattern : str or array_like
        X-Trans widens the bilinear window near corners.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        For an unknown method or pattern.

    Examples
    --------
    >>> demosaic_halo("bilinear", "RGGB"), demosaic_halo("malvar2004", "RGGB")
    (1, 2)
    """
    if not isinstance(method, str):
        raise TypeError(f"method must be a str, one of {DEMOSAIC_METHODS}, got {method!r}")
    return _native.demosaic_halo(method, as_pattern(pattern))
