# Stubs of the private native module; the documented API is the package itself.
# Checked against the built module by `make lint` (mypy.stubtest).

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

# --- distortion ---
def remap_lens_points(
    pts: npt.NDArray[np.float64],
    coeffs: list[float],
    model_name: str,
    k: npt.NDArray[np.float64] | None = None,
    undistort: bool = False,
) -> tuple[npt.NDArray[np.float64], int]: ...

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
