# Stubs of the private native module; the documented API is the package itself.
# Checked against the built module by `make lint` (mypy.stubtest).

from collections.abc import Sequence
from typing import Any, final

import numpy as np
import numpy.typing as npt

class RawError(ValueError): ...

# --- projection ---
def project_pinhole(
    points_cam: npt.NDArray[np.float64], f: float, invert: bool = True
) -> npt.NDArray[np.float64]: ...
def project_orthographic(
    points_cam: npt.NDArray[np.float64], scale: float = 1.0
) -> npt.NDArray[np.float64]: ...

# --- optics ---
# Every formula takes 1-D float64 arrays, each of one common length or of 1 element.
_F64 = npt.NDArray[np.float64]

def image_distance(f: _F64, d: _F64) -> _F64: ...
def magnification(f: _F64, d: _F64) -> _F64: ...
def circle_of_confusion(f: _F64, n: _F64, focus_distance: _F64, d: _F64) -> _F64: ...
def depth_of_field(f: _F64, n: _F64, focus_distance: _F64, coc: _F64) -> tuple[_F64, _F64]: ...
def hyperfocal_distance(f: _F64, n: _F64, coc: _F64) -> _F64: ...
def field_of_view(f: _F64, sensor_size: _F64) -> _F64: ...
def dolly_zoom_focal_length(f0: _F64, d0: _F64, d: _F64) -> _F64: ...

# --- defocus ---
def render_defocus(
    image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32],
    depth: npt.NDArray[np.float32] | npt.NDArray[np.float64],
    f: float,
    n: float,
    focus_distance: float,
    pixel_pitch: float,
) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32]: ...

# --- distortion ---
def remap_lens_points(
    pts: npt.NDArray[np.float64],
    coeffs: list[float],
    model_name: str,
    k: npt.NDArray[np.float64] | None = None,
    undistort: bool = False,
) -> tuple[npt.NDArray[np.float64], int]: ...

# --- camera ---
@final
class NativeCamera:
    def __new__(
        cls,
        k: npt.NDArray[np.float64],
        r: npt.NDArray[np.float64],
        t: npt.NDArray[np.float64],
        coeffs: list[float],
        model_name: str,
    ) -> NativeCamera: ...
    def project(self, points_world: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...
    def unproject(
        self, pixels: npt.NDArray[np.float64], depth: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]: ...
    def rays(self, pixels: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...
    def fov(self, width: int, height: int) -> tuple[float, float, float]: ...
    def center(self) -> tuple[float, float, float]: ...
    def vanishing_point(
        self, direction: npt.NDArray[np.float64]
    ) -> tuple[tuple[float, float], tuple[float, float, float], bool]: ...
    def vanishing_line(
        self, plane_normal: npt.NDArray[np.float64]
    ) -> tuple[float, float, float]: ...

# --- lens ---
@final
class NativeLensCorrection:
    def __new__(
        cls,
        width: int,
        height: int,
        crop: float,
        calibration_crop: float,
        aspect_ratio: float,
        center: tuple[float, float],
        distortion: str,
        distortion_terms: Sequence[float],
        tca: str,
        tca_terms: Sequence[float],
        vignetting: tuple[float, float, float] | None = None,
    ) -> NativeLensCorrection: ...
    def positions(self) -> npt.NDArray[np.float64]: ...
    def correct_geometry(
        self,
        image: npt.NDArray[Any],
        interpolation: str = "bilinear",
        fill: float = 0.0,
        vignetting: bool = False,
        *,
        out: npt.NDArray[Any] | None = None,
    ) -> npt.NDArray[Any]: ...
    def devignette(
        self, image: npt.NDArray[Any], black: npt.NDArray[np.float64]
    ) -> npt.NDArray[Any]: ...

# --- remap ---
@final
class RemapMap:
    def __new__(
        cls, map_x: npt.NDArray[np.float32], map_y: npt.NDArray[np.float32]
    ) -> RemapMap: ...
    @staticmethod
    def undistort(
        k: npt.NDArray[np.float64],
        coeffs: list[float],
        model_name: str,
        shape: tuple[int, int],
        new_k: npt.NDArray[np.float64] | None = None,
    ) -> RemapMap: ...
    @staticmethod
    def distort(
        k: npt.NDArray[np.float64],
        coeffs: list[float],
        model_name: str,
        shape: tuple[int, int],
        new_k: npt.NDArray[np.float64] | None = None,
    ) -> RemapMap: ...
    @property
    def shape(self) -> tuple[int, int]: ...
    def planes(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]: ...

def remap_image(
    image: npt.NDArray[Any], map: RemapMap, interpolation: str = "bilinear", fill: float = 0.0
) -> npt.NDArray[Any]: ...

# --- chromatic ---
def lateral_ca(
    image: npt.NDArray[Any],
    scale_r: float,
    scale_b: float,
    center: tuple[float, float] | None = None,
    correct: bool = False,
    interpolation: str = "bilinear",
    fill: float = 0.0,
) -> npt.NDArray[Any]: ...

# --- align ---
def similarity(a: npt.NDArray[np.generic], b: npt.NDArray[np.generic], metric: str) -> float: ...
def align_images(
    reference: npt.NDArray[np.generic],
    moving: npt.NDArray[np.generic],
    max_shift: int,
    metric: str,
    crop: float,
    levels: int | None,
    features: str,
    subpixel: bool,
) -> tuple[
    tuple[float, float],
    float,
    npt.NDArray[np.float64],
    tuple[int, int],
    list[tuple[int, int, tuple[int, int], float]],
]: ...
def refine_warp(
    reference: npt.NDArray[np.generic],
    movings: Sequence[npt.NDArray[np.generic]],
    motion: str,
    inits: Sequence[Sequence[Sequence[float]]],
    crop: float,
    levels: int | None,
    max_iterations: int,
    tolerance: float,
    features: str,
) -> list[
    tuple[tuple[tuple[float, float, float], tuple[float, float, float]], float, list[int], bool]
]: ...

# --- cfa ---
def pattern_cells(pattern: str | npt.NDArray[np.int64]) -> npt.NDArray[np.uint8]: ...
def shift_pattern(
    pattern: str | npt.NDArray[np.int64], dy: int, dx: int
) -> str | npt.NDArray[np.uint8]: ...
def mosaic(rgb: npt.NDArray[Any], pattern: str | npt.NDArray[np.int64]) -> npt.NDArray[Any]: ...
def channel_masks(
    shape: tuple[int, int], pattern: str | npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]: ...
def simulate_sensor(
    rgb: npt.NDArray[Any],
    pattern: str | npt.NDArray[np.int64],
    full_well: float,
    read_noise: float,
    bit_depth: int,
    black_level: int,
    seed: int,
) -> npt.NDArray[np.uint16]: ...

# --- demosaic ---
DEMOSAIC_METHODS: tuple[str, ...]
BAYER_DEMOSAIC_METHODS: tuple[str, ...]
XTRANS_DEMOSAIC_METHODS: tuple[str, ...]
SCALED_DEMOSAIC_METHODS: tuple[str, ...]
DEMOSAIC_SAMPLE_LIMIT: float
FILM_MAX_BLUR: float

def demosaic(
    raw: npt.NDArray[Any],
    pattern: str | npt.NDArray[np.int64],
    method: str = "bilinear",
    *,
    white_level: float | None = None,
    out: npt.NDArray[Any] | None = None,
) -> npt.NDArray[Any]: ...
def demosaic_halo(method: str, pattern: str | npt.NDArray[np.int64]) -> int: ...

# --- develop ---
TONES: tuple[str, ...]

def develop(
    raw: npt.NDArray[np.uint16],
    pattern: str | npt.NDArray[np.int64],
    black: npt.NDArray[np.float64],
    scale: npt.NDArray[np.float64],
    matrix: npt.NDArray[np.float64],
    tone: str,
    method: str,
    bps: str,
    lens: NativeLensCorrection | None = None,
    auto_bright: int | None = None,
) -> npt.NDArray[Any]: ...

# --- metrology ---
def fit_vanishing_point(
    segments: npt.NDArray[np.float64], threshold: float, seed: int, allow_infinite: bool
) -> tuple[tuple[float, float, float], bool, float, npt.NDArray[np.bool_]]: ...
def fit_horizon(
    vp1: npt.NDArray[np.float64], vp2: npt.NDArray[np.float64]
) -> tuple[float, float, float]: ...
def relative_height(
    horizon: npt.NDArray[np.float64],
    vertical_vp: npt.NDArray[np.float64],
    ref_base: npt.NDArray[np.float64],
    ref_top: npt.NDArray[np.float64],
    ref_height: float,
    base: npt.NDArray[np.float64],
    top: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]: ...
def camera_height(
    horizon: npt.NDArray[np.float64],
    vertical_vp: npt.NDArray[np.float64],
    ref_base: npt.NDArray[np.float64],
    ref_top: npt.NDArray[np.float64],
    ref_height: float,
) -> float: ...

# --- aberration ---
def pupil_psf(
    n_pixels: int,
    pixel_pitch: float,
    f_number: float,
    wavelength: float,
    defocus: float,
    spherical: float,
    oversample: int | None = None,
) -> npt.NDArray[np.float64]: ...
def spot_diagram(
    f: float, f_number: float, spherical_lsa: float, n_rays: int, image_plane: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float]: ...
def best_focus(f: float, f_number: float, spherical_lsa: float, n_rays: int) -> float: ...
def strehl_ratio(psf: npt.NDArray[np.float64], reference: npt.NDArray[np.float64]) -> float: ...
def render_aberrated(
    image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32],
    psf: npt.NDArray[np.float64],
) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32]: ...

# --- lightfield ---
def focal_stack(
    views: npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32],
    grid: tuple[int, int],
    alphas: list[float],
    aperture: list[bool],
) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32]: ...

# --- film ---
def film_develop(
    exposure: npt.NDArray[np.float32],
    gain: float,
    curves: list[tuple[float, float, list[float]]],
    matrix: list[float],
    diffusion: float,
    halation: tuple[list[float], float] | None = None,
) -> npt.NDArray[np.float32]: ...
def film_transmit(
    density: npt.NDArray[np.float32],
    base: list[float],
    dyes: list[float],
    response: list[float],
) -> npt.NDArray[np.float32]: ...
def film_print(
    density: npt.NDArray[np.float32],
    base: list[float],
    dyes: list[float],
    light: list[float],
    curves: list[tuple[float, float, list[float]]],
    matrix: list[float],
    diffusion: float,
    gain: float,
) -> npt.NDArray[np.float32]: ...
def film_halation(
    exposure: npt.NDArray[np.float32], strength: list[float], sigma: float
) -> npt.NDArray[np.float32]: ...
def film_grain(
    density: npt.NDArray[np.float32], per_grain: list[float], seed: int
) -> npt.NDArray[np.float32]: ...

# --- spectral ---
def spectral_weights(wavelengths: list[float], rule: str) -> list[float]: ...
def check_wavelengths(wavelengths: list[float]) -> None: ...
def check_spectra(name: str, spectra: list[float], grid_len: int) -> int: ...
def blackbody(wavelengths: list[float], temperature: float) -> list[float]: ...
def spectral_integrate(
    spectra: npt.NDArray[np.float32], response: npt.NDArray[np.float64]
) -> npt.NDArray[np.float32]: ...
def flat_pair_stats(
    a: npt.NDArray[np.uint16], b: npt.NDArray[np.uint16]
) -> tuple[float, float, float]: ...

@final
class NativeSensor:
    def __new__(
        cls,
        *,
        exposure_time: float,
        full_well: float,
        read_noise: float,
        electrons_per_dn: float,
        analog_gain: float,
        black_level: int,
        bit_depth: int,
        dark_current: float,
        temperature: float,
        reference_temperature: float,
        doubling_temperature: float,
        dsnu: float,
        prnu: float,
        column_noise: float,
        seed: int,
        pattern_seed: int,
    ) -> NativeSensor: ...
    def with_frame(self, seed: int, exposure_time: float) -> NativeSensor: ...
    def dark_rate(self) -> float: ...
    def capture_rates(self, rates: npt.NDArray[np.float32]) -> npt.NDArray[np.uint16]: ...
    def capture_spectral(
        self,
        spectra: npt.NDArray[np.float32],
        response: npt.NDArray[np.float64],
        pattern: str | npt.NDArray[np.int64],
        falloff: tuple[float, float, float] | None = None,
    ) -> npt.NDArray[np.uint16]: ...
    def capture_rgb(
        self,
        rgb: npt.NDArray[np.float32],
        matrix: npt.NDArray[np.float64],
        pattern: str | npt.NDArray[np.int64],
        falloff: tuple[float, float, float] | None = None,
    ) -> npt.NDArray[np.uint16]: ...

# --- cpu ---
def instruction_set() -> str: ...
def instruction_sets() -> list[str]: ...
