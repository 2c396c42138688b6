"""imgform-rs: how a photograph is formed, in Rust, for NumPy.

Camera geometry and lens optics, colour filter arrays and demosaicing,
three-colour alignment and raw development. Conventions (axis order, colour
order, camera frame, CFA patterns, shift sign) are documented in
``CONVENTIONS.md``.
"""

from ._native import RawError
from .cfa import (
    channel_masks,
    mosaic,
    pattern_cells,
    pattern_from_rawpy,
    shift_pattern,
    simulate_sensor,
)
from .demosaic import DEMOSAIC_METHODS, demosaic
from .distortion import distort_points, undistort_points
from .projection import project_orthographic, project_pinhole

__all__ = [
    "DEMOSAIC_METHODS",
    "RawError",
    "channel_masks",
    "demosaic",
    "distort_points",
    "mosaic",
    "pattern_cells",
    "pattern_from_rawpy",
    "project_orthographic",
    "project_pinhole",
    "shift_pattern",
    "simulate_sensor",
    "undistort_points",
]
