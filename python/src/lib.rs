//! The native module `pino_mbd._pino_mbd` of the Python package `pino_mbd` (python/pino_mbd:
//! the typed Python layer over it). Nothing of the physics or the learning is written here:
//! each class calls the workspace's libraries, and tables cross as Arrow C streams.
//!
//! - [`system`]: `System` (a description, its tables, the exact solver on designs).
//! - [`answers`]: what `Model` and `Surrogate` answer alike (predictions and indices of designs).
//! - [`model`]: `Model` (a trained model: predictions and indices with calibrated intervals).
//! - [`surrogate`]: `Surrogate` (the `surrogate` stage's output: the same answers, each index
//!   and channel from its routed member).
//! - [`pipeline`]: `Pipeline` (status, run, show) and `_study` (one design study).
//! - [`arrow`]: tables in and out through `__arrow_c_stream__`; [`designs`]: a table of
//!   designs checked by name; [`excitation`]: the `excitation` argument and each row's
//!   profiles (every front that runs designs shares it); [`progress`]: the stderr progress
//!   bar; [`error`]: `PinoError`.

pub mod answers;
pub mod arrow;
pub mod designs;
pub mod error;
pub mod excitation;
pub mod model;
pub mod pipeline;
pub mod progress;
pub mod surrogate;
pub mod system;

use pyo3::prelude::*;

#[pymodule]
fn _pino_mbd(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("PinoError", m.py().get_type::<error::PinoError>())?;
    m.add_class::<arrow::ArrowTable>()?;
    m.add_class::<system::PySystem>()?;
    m.add_class::<answers::PyAnswers>()?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<surrogate::PySurrogate>()?;
    m.add_class::<pipeline::PyPipeline>()?;
    m.add_function(wrap_pyfunction!(pipeline::_study, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
