//! The `lgdm` Python extension module: a thin pyo3 layer over the Rust crates.
//!
//! Python sees the package `lgdm` (`python/lgdm/`), whose pure-Python part gives the
//! scikit-learn-style class `lgdm.GDM`, the exception hierarchy and the type stubs; this crate
//! is its native part `lgdm._lgdm`:
//!
//! - [`model`]: `Model`, the dual-memory model on numpy arrays, GIL released while it works.
//! - [`data`]: `Dataset` (sequences as numpy arrays), the GOOD descriptor and feature tables,
//!   dataset generation, projection of clouds to depth / RGB-D images, best-view selection.
//! - `ae` (cargo feature `ae`): the embedding side: Rust calls the torch autoencoder of
//!   `python/train_ae` (`AutoEncoder::load`, `infer`, `crop_grasps`) through an embedded
//!   interpreter.
//! - [`experiment`]: `run_scenario`, the paper's scenarios over trials on a feature table (the
//!   library code `lgdm train` runs).
//! - [`sim`]: the robot (`lgdm.sim`): `lgdm sim grasp`, `pick-place` and `packing` as library
//!   calls, with grasp sources written in Python.
//! - [`errors`]: Rust errors → `lgdm.LgdmError` and its subclasses.
//!
//! Build and install into a venv with `maturin develop --release -m crates/pybridge/Cargo.toml`;
//! then:
//!
//! ```python
//! import numpy as np, lgdm
//! m = lgdm.GDM(seed=1).fit(np.random.rand(50, 3), category=np.arange(50) % 2)
//! ```
#![allow(unsafe_code)] // pyo3's macros expand to FFI glue.

#[cfg(feature = "ae")]
pub mod ae;
pub mod data;
pub mod decode;
pub mod errors;
pub mod experiment;
pub mod model;
pub mod sim;

use pyo3::prelude::*;

/// The native part of the `lgdm` package (`lgdm._lgdm`).
#[pymodule]
fn _lgdm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("AUTO_SEQUENCE_BASE", model::AUTO_SEQUENCE_BASE)?;
    m.add(
        "PRESETS",
        lgdm_gdm::config::PRESETS
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>(),
    )?;
    m.add(
        "LEARNERS",
        lgdm_gdm::learner::LearnerKind::ALL
            .iter()
            .map(|l| l.name())
            .collect::<Vec<_>>(),
    )?;
    m.add(
        "SCENARIOS",
        lgdm_gdm::experiment::Scenario::ALL
            .iter()
            .map(|s| s.name())
            .collect::<Vec<_>>(),
    )?;
    m.add_class::<model::Model>()?;
    m.add_function(wrap_pyfunction!(model::config_json, m)?)?;
    m.add_function(wrap_pyfunction!(experiment::run_scenario, m)?)?;
    m.add_function(wrap_pyfunction!(experiment::merge_runs, m)?)?;
    m.add_function(wrap_pyfunction!(experiment::scenario_defaults, m)?)?;
    m.add_class::<data::PyDataset>()?;
    m.add_class::<data::SequenceIter>()?;
    m.add_function(wrap_pyfunction!(data::good_descriptor, m)?)?;
    m.add_function(wrap_pyfunction!(data::good_features, m)?)?;
    m.add_function(wrap_pyfunction!(data::generate_dataset, m)?)?;
    m.add_function(wrap_pyfunction!(data::project_to_image, m)?)?;
    m.add_function(wrap_pyfunction!(data::view_entropy, m)?)?;
    m.add_function(wrap_pyfunction!(data::best_view, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sim_grasp, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sim_pick_place, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sim_resume, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sim_decode_grasps, m)?)?;
    Ok(())
}
