//! `kinmo._core`: Python bindings of the kinmo geometry core.
//!
//! Every function checks its numpy inputs (shape, finiteness, index range), releases the
//! GIL while the pure-Rust function in `kinmo-geometry` runs, and maps `GeometryError`
//! to a Python exception in one place (`errors.rs`). No panic crosses into Python.

use pyo3::prelude::*;

mod contact;
mod convert;
mod decompose;
mod errors;
mod hull;
mod interaction;
mod mesh;
mod motion;
mod obb;
mod pointnet;
mod sampling;
mod sweep;

/// The native module.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    mesh::register(m)?;
    sampling::register(m)?;
    obb::register(m)?;
    pointnet::register(m)?;
    hull::register(m)?;
    contact::register(m)?;
    decompose::register(m)?;
    interaction::register(m)?;
    motion::register(m)?;
    sweep::register(m)?;
    Ok(())
}
