//! Python bindings of `imgform-core`, loaded as `imgform_rs._native`.
//!
//! Bindings only: each file mirrors one core module, checks arrays, releases
//! the GIL around the kernel and maps errors. The public, documented API is
//! the Python package `imgform_rs`, which wraps these functions.

mod arrays;
mod errors;

mod aberration;
mod align;
mod camera;
mod cfa;
mod chromatic;
mod cpu;
mod defocus;
mod demosaic;
mod develop;
mod distortion;
mod film;
mod lens;
mod lightfield;
mod metrology;
mod optics;
mod projection;
mod remap;
mod spectral;

use pyo3::prelude::*;

#[pymodule(gil_used = false)]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("RawError", m.py().get_type::<errors::RawError>())?;
    aberration::register(m)?;
    align::register(m)?;
    camera::register(m)?;
    cfa::register(m)?;
    chromatic::register(m)?;
    cpu::register(m)?;
    defocus::register(m)?;
    demosaic::register(m)?;
    develop::register(m)?;
    distortion::register(m)?;
    film::register(m)?;
    metrology::register(m)?;
    lens::register(m)?;
    lightfield::register(m)?;
    optics::register(m)?;
    projection::register(m)?;
    remap::register(m)?;
    spectral::register(m)?;
    Ok(())
}
