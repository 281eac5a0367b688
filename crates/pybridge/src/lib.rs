//! The `lgdm` Python extension module: a thin pyo3 layer over the Rust crates.
#![allow(unsafe_code)] // pyo3's macros expand to FFI glue.

use pyo3::prelude::*;

/// The native part of the `lgdm` package (`lgdm._lgdm`).
#[pymodule]
fn _lgdm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
