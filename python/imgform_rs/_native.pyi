# Stubs of the private native module; the documented API is the package itself.
# Checked against the built module by `make lint` (mypy.stubtest).

from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "RawError",
    "RemapMap",
    "lateral_ca",
    "project_orthographic",
    "project_pinhole",
    "remap_image",
    "remap_lens_points",
]

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
