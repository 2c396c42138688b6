//! Image-formation kernels over plain slices.
//!
//! Every public kernel takes `&[T]` / `&mut [T]` plus its dimensions, validates
//! them, and returns [`Result`]; none of them panics on bad input. Work is
//! spread over rayon row bands (or point chunks) whose results never depend on
//! the number of threads. Conventions (axis order, camera frame, CFA patterns,
//! shift sign) are those of `shared/CONVENTIONS.md`.

pub mod cpu;
pub mod error;
pub mod image;
pub mod parallel;

pub mod aberration;
pub mod align;
mod auto_bright;
pub mod camera;
pub mod cfa;
pub mod chromatic;
pub mod defocus;
pub mod demosaic;
pub mod develop;
pub mod distortion;
pub mod film;
mod interleave;
pub mod intrinsics;
pub mod lens;
pub mod lightfield;
pub mod metrology;
pub mod optics;
pub mod projection;
mod random;
pub mod remap;
pub mod spectral;

pub use error::{CoreError, Result};
