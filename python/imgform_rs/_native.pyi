# Stubs of the private native module; the documented API is the package itself.
# Checked against the built module by `make lint` (mypy.stubtest).

from typing import Any

import numpy as np
import numpy.typing as npt

__all__: list[str]

class RawError(ValueError): ...

# --- projection ---
def project_pinhole(
    points_cam: npt.NDArray[np.float64], f: float, invert: bool = True
) -> npt.NDArray[np.float64]: ...
def project_orthographic(
    points_cam: npt.NDArray[np.float64], scale: float = 1.0
) -> npt.NDArray[np.float64]: ...

# --- distortion ---
def remap_lens_points(
    pts: npt.NDArray[np.float64],
    coeffs: list[float],
    model_name: str,
    k: npt.NDArray[np.float64] | None = None,
    undistort: bool = False,
) -> tuple[npt.NDArray[np.float64], int]: ...

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

def demosaic(
    raw: npt.NDArray[Any], pattern: str | npt.NDArray[np.int64], method: str = "bilinear"
) -> npt.NDArray[Any]: ...
