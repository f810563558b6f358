//! `pino_mbd.Model`: a trained model (`train`'s output) with its calibration when given,
//! through the `predict` command's library (`pino_eval::predict::Predictor`): time histories
//! of designs, and their engineering indices with calibrated intervals and three-valued
//! verdicts; the same tables, numbers and `outside_training_range` flags as `predict --out`
//! and `predict --indices`, computed with the GIL released.

use crate::arrow::{import, ArrowTable};
use crate::designs::designs;
use crate::error::{to_py, value_error};
use pino_eval::predict::{outside_flag, Predictor, ProfileChoice};
use pino_learn::config::DeviceKind;
use pyo3::prelude::*;
use pyo3::types::PyString;
use std::path::PathBuf;

/// A trained model loaded for prediction.
#[pyclass(module = "pino_mbd._pino_mbd", name = "Model", frozen)]
pub struct PyModel {
    predictor: Predictor,
    dir: PathBuf,
    calibration: Option<PathBuf>,
}

/// The designs of a call and their run: sets, profiles, run controls, outside flags.
struct Call {
    sets: Vec<Vec<f64>>,
    profiles: Vec<Option<mbd_engine::Profile>>,
    run: mbd_engine::RunConfig,
    outside: Vec<Vec<pino_learn::checkpoint::OutOfRange>>,
}

impl PyModel {
    fn call(
        &self,
        designs_obj: &Bound<'_, PyAny>,
        excitation: Option<&Bound<'_, PyAny>>,
        excitation_id: Option<i64>,
        x0: Option<f64>,
        strict: bool,
    ) -> PyResult<Call> {
        let p = &self.predictor;
        let table = import(designs_obj, "designs")?;
        let sets = designs(&p.space, &table, "designs")?.sets;
        if let Some(id) = excitation_id.filter(|id| *id < 0) {
            return Err(value_error(format!(
                "excitation_id = {id}: allowed an integer >= 0"
            )));
        }
        let choice = match excitation.filter(|e| !e.is_none()) {
            None => None,
            Some(e) if e.is_instance_of::<PyString>() || e.hasattr("__fspath__")? => {
                Some(ProfileChoice::File {
                    path: e.extract()?,
                    sample_id: excitation_id,
                })
            }
            Some(e) => {
                let seed: u64 = e.extract().map_err(|_| {
                    value_error(
                        "excitation: allowed a seed (an integer >= 0: the profiles generated with the model's dataset's settings) or the path of a profile file",
                    )
                })?;
                Some(ProfileChoice::Generated {
                    seed,
                    id: excitation_id.unwrap_or(0) as u64,
                })
            }
        };
        let profiles = p.profiles(choice.as_ref()).map_err(to_py)?;
        let run = p.run_config(x0).map_err(to_py)?;
        let outside = p.outside_training(&sets).map_err(to_py)?;
        if strict {
            if let Some(k) = outside.iter().position(|o| !o.is_empty()) {
                return Err(value_error(format!(
                    "strict: designs[{k}] is outside the model's training ranges (from {}): {}",
                    p.meta.training_ranges.source,
                    outside_flag(&outside[k])
                )));
            }
        }
        Ok(Call {
            sets,
            profiles,
            run,
            outside,
        })
    }
}

#[pymethods]
impl PyModel {
    /// Loads `model.safetensors` + `model.json` from `dir` (a `train` output) and, when
    /// given, its calibration (the `calibrate` stage's output or a `calibration.json`).
    #[staticmethod]
    #[pyo3(signature = (dir, calibration=None))]
    fn load(py: Python<'_>, dir: PathBuf, calibration: Option<PathBuf>) -> PyResult<Self> {
        py.detach(|| {
            pino_learn::candle_single_threaded_by_default();
            let device = DeviceKind::Cpu.device().map_err(to_py)?;
            let mut predictor = Predictor::load(&dir, &device).map_err(to_py)?;
            if let Some(path) = &calibration {
                predictor
                    .load_calibration(path)
                    .map_err(|e| value_error(format!("calibration {}: {e}", path.display())))?;
            }
            Ok(Self {
                predictor,
                dir,
                calibration,
            })
        })
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

    /// The name of the model's system.
    #[getter]
    fn system_name(&self) -> String {
        self.predictor.system().name.clone()
    }

    /// The design parameters (sampled), in value order.
    #[getter]
    fn design_parameters(&self) -> Vec<String> {
        self.predictor.space.names().to_vec()
    }

    /// Training algorithm (1-5).
    #[getter]
    fn algorithm(&self) -> i64 {
        self.predictor.meta.train.algorithm.id()
    }

    /// Time histories of every design (the table of `predict --out`).
    #[pyo3(signature = (designs, excitation, excitation_id, x0, coverage, batch, strict))]
    #[allow(clippy::too_many_arguments)]
    fn _predict(
        &self,
        py: Python<'_>,
        designs: &Bound<'_, PyAny>,
        excitation: Option<&Bound<'_, PyAny>>,
        excitation_id: Option<i64>,
        x0: Option<f64>,
        coverage: Option<f64>,
        batch: usize,
        strict: bool,
    ) -> PyResult<ArrowTable> {
        let c = self.call(designs, excitation, excitation_id, x0, strict)?;
        let p = &self.predictor;
        let level = p.interval_level(coverage).map_err(to_py)?;
        let table = py.detach(|| {
            p.histories_flagged(&c.sets, &c.profiles, &c.run, batch, level)
                .map_err(to_py)
        })?;
        ArrowTable::new(table, "predict")
    }

    /// The engineering indices of every design (the table of `predict --indices`).
    #[pyo3(signature = (designs, excitation, excitation_id, x0, coverage, batch, strict))]
    #[allow(clippy::too_many_arguments)]
    fn _indices(
        &self,
        py: Python<'_>,
        designs: &Bound<'_, PyAny>,
        excitation: Option<&Bound<'_, PyAny>>,
        excitation_id: Option<i64>,
        x0: Option<f64>,
        coverage: Option<f64>,
        batch: usize,
        strict: bool,
    ) -> PyResult<ArrowTable> {
        let c = self.call(designs, excitation, excitation_id, x0, strict)?;
        let p = &self.predictor;
        let level = p
            .interval_level(coverage)
            .map_err(to_py)?
            .unwrap_or(pino_eval::calibration::DEFAULT_COVERAGE);
        let table = py.detach(|| -> PyResult<_> {
            let cfg = p.index_config().map_err(to_py)?;
            let answers = p
                .answers(&c.sets, &c.profiles, &c.run, &cfg, batch, level)
                .map_err(to_py)?;
            p.indices_table(&c.sets, &answers, &c.outside)
                .map_err(to_py)
        })?;
        ArrowTable::new(table, "indices")
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({}: system {:?}, algorithm {}, {})",
            self.dir.display(),
            self.predictor.system().name,
            self.predictor.meta.train.algorithm.id(),
            match &self.calibration {
                Some(c) => format!("calibrated by {}", c.display()),
                None => "no calibration".to_owned(),
            }
        )
    }
}
