"""imgform-rs: how a photograph is formed, in Rust, for NumPy.

Camera geometry and lens optics, colour filter arrays and demosaicing,
three-colour alignment and raw development. Conventions (axis order, colour
order, camera frame, CFA patterns, shift sign) are documented in
``CONVENTIONS.md``.
"""

from ._native import RawError
from .align import (
    Alignment,
    align,
    apply_shift,
    colorize_plate,
    read_plate,
    similarity,
    stack_channels,
)
from .camera import Camera, VanishingPoint, look_at, vanishing_line, vanishing_point
from .cfa import (
    channel_masks,
    mosaic,
    pattern_cells,
    pattern_from_rawpy,
    shift_pattern,
    simulate_sensor,
)
from .chromatic import add_lateral_ca, correct_lateral_ca
from .demosaic import (
    BAYER_DEMOSAIC_METHODS,
    DEMOSAIC_METHODS,
    XTRANS_DEMOSAIC_METHODS,
    demosaic,
)
from .develop import TONES, develop, write_image
from .distortion import distort_points, undistort_points
from .optics import (
    circle_of_confusion,
    depth_of_field,
    dolly_zoom_focal_length,
    field_of_view,
    hyperfocal_distance,
    image_distance,
    magnification,
    render_defocus,
)
from .projection import project_orthographic, project_pinhole
from .raw import RawImage, load_raw
from .remap import (
    RemapMap,
    distort_image,
    distort_map,
    remap,
    undistort_image,
    undistort_map,
)

__all__ = [
    "BAYER_DEMOSAIC_METHODS",
    "DEMOSAIC_METHODS",
    "TONES",
    "XTRANS_DEMOSAIC_METHODS",
    "Alignment",
    "Camera",
    "RawError",
    "RawImage",
    "RemapMap",
    "VanishingPoint",
    "add_lateral_ca",
    "align",
    "apply_shift",
    "channel_masks",
    "circle_of_confusion",
    "colorize_plate",
    "correct_lateral_ca",
    "demosaic",
    "depth_of_field",
    "develop",
    "distort_image",
    "distort_map",
    "distort_points",
    "dolly_zoom_focal_length",
    "field_of_view",
    "hyperfocal_distance",
    "image_distance",
    "load_raw",
    "look_at",
    "magnification",
    "mosaic",
    "pattern_cells",
    "pattern_from_rawpy",
    "project_orthographic",
    "project_pinhole",
    "read_plate",
    "remap",
    "render_defocus",
    "shift_pattern",
    "similarity",
    "simulate_sensor",
    "stack_channels",
    "undistort_image",
    "undistort_map",
    "undistort_points",
    "vanishing_line",
    "vanishing_point",
    "write_image",
]
