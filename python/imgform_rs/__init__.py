"""imgform-rs: how a photograph is formed, in Rust, for NumPy.

Camera geometry and lens optics, colour filter arrays and demosaicing,
three-colour alignment and raw development. Conventions (axis order, colour
order, camera frame, CFA patterns, shift sign) are set out in the
documentation's conventions page, ``docs/conventions.rst``.
"""

from . import film as film  # a submodule with its own API page, not in __all__
from . import spectral as spectral  # a submodule with its own API page, not in __all__
from . import three_colour as three_colour  # a submodule with its own API page, not in __all__
from ._exif import ShotInfo
from ._native import RawError
from .aberration import (
    SpotDiagram,
    best_focus,
    pupil_psf,
    render_aberrated,
    spot_diagram,
    strehl_ratio,
)
from .align import (
    Alignment,
    align,
    apply_shift,
    apply_warp,
    auto_balance,
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
from .cpu import instruction_set
from .demosaic import (
    BAYER_DEMOSAIC_METHODS,
    DEMOSAIC_METHODS,
    SCALED_DEMOSAIC_METHODS,
    XTRANS_DEMOSAIC_METHODS,
    demosaic,
    demosaic_halo,
)
from .develop import COLORS, TONES, develop, develop_file, raw_exif, write_image
from .distortion import distort_points, undistort_points
from .lightfield import focal_stack, refocus, render_light_field, view_disparity
from .metrology import (
    VanishingPointFit,
    camera_height,
    fit_horizon,
    fit_vanishing_point,
    relative_height,
)
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
    "COLORS",
    "DEMOSAIC_METHODS",
    "SCALED_DEMOSAIC_METHODS",
    "TONES",
    "XTRANS_DEMOSAIC_METHODS",
    "Alignment",
    "Camera",
    "RawError",
    "RawImage",
    "RemapMap",
    "ShotInfo",
    "SpotDiagram",
    "VanishingPoint",
    "VanishingPointFit",
    "add_lateral_ca",
    "align",
    "apply_shift",
    "apply_warp",
    "auto_balance",
    "best_focus",
    "camera_height",
    "channel_masks",
    "circle_of_confusion",
    "colorize_plate",
    "correct_lateral_ca",
    "demosaic",
    "demosaic_halo",
    "depth_of_field",
    "develop",
    "develop_file",
    "distort_image",
    "distort_map",
    "distort_points",
    "dolly_zoom_focal_length",
    "field_of_view",
    "fit_horizon",
    "fit_vanishing_point",
    "focal_stack",
    "hyperfocal_distance",
    "image_distance",
    "instruction_set",
    "load_raw",
    "look_at",
    "magnification",
    "mosaic",
    "pattern_cells",
    "pattern_from_rawpy",
    "project_orthographic",
    "project_pinhole",
    "pupil_psf",
    "raw_exif",
    "read_plate",
    "refocus",
    "relative_height",
    "remap",
    "render_aberrated",
    "render_defocus",
    "render_light_field",
    "shift_pattern",
    "similarity",
    "simulate_sensor",
    "spot_diagram",
    "stack_channels",
    "strehl_ratio",
    "undistort_image",
    "undistort_map",
    "undistort_points",
    "vanishing_line",
    "vanishing_point",
    "view_disparity",
    "write_image",
]
