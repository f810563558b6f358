//! `pino_mbd.Surrogate`: the `surrogate` stage's output (`surrogate.json` and its member
//! models with their calibrations, `pino_surrogate::Surrogate::load`), answering as
//! `pino_mbd.Model` does ([`crate::answers`]) with each index
//! and channel from the member it is routed to: the tables of `predict --surrogate DIR --out`
//! and `--indices`. A member whose files changed since the surrogate was built, or a manifest
//! of another system, is refused with the message `predict --surrogate` gives.

use crate::answers::PyAnswers;
use crate::error::to_py;
use pino_learn::config::DeviceKind;
use pino_surrogate::Surrogate;
use pyo3::prelude::*;
use std::path::PathBuf;

/// A surrogate loaded for prediction.
#[pyclass(module = "pino_mbd._pino_mbd", name = "Surrogate", extends = PyAnswers, frozen)]
pub struct PySurrogate {
    dir: PathBuf,
}

#[pymethods]
impl PySurrogate {
    /// Loads the surrogate in `dir` (the `surrogate` stage's output), its members' files
    /// verified against the manifest.
    #[staticmethod]
    fn load(py: Python<'_>, dir: PathBuf) -> PyResult<Py<Self>> {
        let surrogate = py.detach(|| {
            pino_learn::candle_single_threaded_by_default();
            let device = DeviceKind::Cpu.device().map_err(to_py)?;
            Surrogate::load(&dir, &device).map_err(to_py)
        })?;
        let init = PyClassInitializer::from(PyAnswers::new(surrogate)).add_subclass(Self { dir });
        Py::new(py, init)
    }

    /// The surrogate's directory.
    #[getter]
    fn dir(&self) -> PathBuf {
        self.dir.clone()
    }

    /// The member models' names (`algorithm-5`, ...), in the manifest's order.
    #[getter]
    fn members(slf: PyRef<'_, Self>) -> Vec<String> {
        slf.as_super().surrogate().member_names().to_vec()
    }

    /// Per index (the description's order): its name and the member answering it.
    #[getter]
    fn index_routes(slf: PyRef<'_, Self>) -> Vec<(String, String)> {
        let s = slf.as_super().surrogate();
        let names = s.primary().index_inputs().columns();
        names
            .iter()
            .zip(s.index_routes())
            .map(|(c, m)| (c.name.clone(), m.to_owned()))
            .collect()
    }

    /// Per predicted channel (column order): its name and the member answering it.
    #[getter]
    fn channel_routes(slf: PyRef<'_, Self>) -> Vec<(String, String)> {
        let s = slf.as_super().surrogate();
        let names = s.member_names();
        s.channels()
            .iter()
            .map(|(c, m, _)| (c.clone(), names[*m].clone()))
            .collect()
    }

    /// Whether every member answering a quantity has calibrated intervals.
    #[getter]
    fn has_intervals(slf: PyRef<'_, Self>) -> bool {
        slf.as_super().surrogate().has_intervals()
    }

    fn __repr__(slf: PyRef<'_, Self>) -> String {
        let s = slf.as_super().surrogate();
        format!(
            "Surrogate({}: system {:?}, members {})",
            slf.dir.display(),
            s.primary().system().name,
            s.member_names().join(" + ")
        )
    }
}
