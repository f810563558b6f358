//! `pino_mbd.Model`: a trained model (`train`'s output) with its calibration when given,
//! answering designs as `predict --model DIR --calibration DIR` does ([`crate::answers`]), and
//! written as one ONNX file as `export` does.

use crate::answers::PyAnswers;
use crate::error::{to_py, value_error};
use pino_learn::config::DeviceKind;
use pino_predict::Predictor;
use pino_surrogate::Surrogate;
use pyo3::prelude::*;
use std::path::PathBuf;

/// A trained model loaded for prediction.
#[pyclass(module = "pino_mbd._pino_mbd", name = "Model", extends = PyAnswers, frozen)]
pub struct PyModel {
    dir: PathBuf,
    calibration: Option<PathBuf>,
}

#[pymethods]
impl PyModel {
    /// Loads `model.safetensors` + `model.json` from `dir` (a `train` output) and, when
    /// given, its calibration (the `calibrate` stage's output or a `calibration.json`).
    #[staticmethod]
    #[pyo3(signature = (dir, calibration=None))]
    fn load(py: Python<'_>, dir: PathBuf, calibration: Option<PathBuf>) -> PyResult<Py<Self>> {
        let model = py.detach(|| {
            pino_learn::candle_single_threaded_by_default();
            let device = DeviceKind::Cpu.device().map_err(to_py)?;
            let mut predictor = Predictor::load(&dir, &device).map_err(to_py)?;
            if let Some(path) = &calibration {
                predictor
                    .load_calibration(path)
                    .map_err(|e| value_error(format!("calibration {}: {e}", path.display())))?;
            }
            PyResult::Ok(Surrogate::of_model(predictor))
        })?;
        let init =
            PyClassInitializer::from(PyAnswers::new(model)).add_subclass(Self { dir, calibration });
        Py::new(py, init)
    }

    /// Writes the model with its calibration as one ONNX file (`export`, docs/export.md);
    /// returns the output line `export` prints.
    #[pyo3(signature = (path, spectral=None, levels=None))]
    fn _export_onnx(
        &self,
        py: Python<'_>,
        path: PathBuf,
        spectral: Option<String>,
        levels: Option<Vec<f64>>,
    ) -> PyResult<String> {
        py.detach(|| {
            let mut spec = onnx_export::ExportSpec::single(&self.dir, self.calibration.as_deref());
            if let Some(s) = spectral {
                spec.spectral = onnx_export::Spectral::parse(&s).map_err(to_py)?;
            }
            spec.levels = levels;
            let s = onnx_export::export(&spec, &path).map_err(to_py)?;
            Ok(format!(
                "{}: {} channels, {} indices, levels {:?}",
                path.display(),
                s.channels.len(),
                s.indices.len(),
                s.levels
            ))
        })
    }

    /// The model's directory.
    #[getter]
    fn dir(&self) -> PathBuf {
        self.dir.clone()
    }

    /// The calibration given at load, if any.
    #[getter]
    fn calibration(&self) -> Option<PathBuf> {
        self.calibration.clone()
    }

    /// Training algorithm (1-5).
    #[getter]
    fn algorithm(slf: PyRef<'_, Self>) -> i64 {
        slf.as_super()
            .surrogate()
            .primary()
            .meta
            .train
            .algorithm
            .id()
    }

    fn __repr__(slf: PyRef<'_, Self>) -> String {
        let p = slf.as_super().surrogate().primary();
        format!(
            "Model({}: system {:?}, algorithm {}, {})",
            slf.dir.display(),
            p.system().name,
            p.meta.train.algorithm.id(),
            match &slf.calibration {
                Some(c) => format!("calibrated by {}", c.display()),
                None => "no calibration".to_owned(),
            }
        )
    }
}
