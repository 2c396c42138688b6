//! Bindings of `imgform_core::cpu`.

use imgform_core::cpu::{self, Level};
use pyo3::prelude::*;

/// The widest instruction set the kernels run on this CPU within the cap
/// `IMGFORM_ISA` sets: "baseline", "avx2", "avx512" or "amx".
#[pyfunction]
fn instruction_set() -> &'static str {
    cpu::level().name()
}

/// The names `IMGFORM_ISA` takes, narrowest first.
#[pyfunction]
fn instruction_sets() -> Vec<&'static str> {
    Level::ALL.map(Level::name).to_vec()
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(instruction_set, m)?)?;
    m.add_function(wrap_pyfunction!(instruction_sets, m)?)?;
    Ok(())
}
