//! Spherical aberration: rays of a lens that do not all meet in one point.
//!
//! A perfect lens turns the plane wave of a distant point into a sphere
//! converging on the focus. A real spherical surface bends the rim of the
//! beam more than its centre, so marginal rays cross the axis before the
//! paraxial ones (longitudinal spherical aberration, LSA). The module looks
//! at this in the two classical ways:
//!
//! - [`spot`]: geometric optics. A bundle of rays through the aperture, each
//!   focused at its own distance, is cut by an image plane; the spread of the
//!   hits (the RMS spot radius) is smallest two thirds of the way from the
//!   paraxial towards the marginal focus.
//! - [`psf`]: wave optics. The same error as a wavefront deviation
//!   `W(rho) = W020 rho^2 + W040 rho^4` over the pupil; the point spread
//!   function is `|FFT(pupil)|^2`, integrated over each sensor pixel. With no
//!   error it is the Airy pattern, with a small one its peak drops as
//!   Marechal's `exp(-(2 pi sigma)^2)`.
//! - [`convolve`]: the PSF applied to an image, directly for small kernels,
//!   by overlap-save FFT tiles (`fft_tiles`) for large ones.

pub mod convolve;
mod fft_tiles;
pub mod psf;
pub mod spot;

pub use convolve::render_aberrated;
pub use psf::{pupil_psf, strehl_ratio, PupilPsf};
pub use spot::{best_focus, spot_diagram, Spot, SpotLens};
