//! `pino_mbd.Pipeline` and `pino_mbd.study`: the orchestrator's library (`pipeline::spec`,
//! `run`, `status`) as the `pipeline` command drives it (`status`, `run`, `show`), and one
//! design study (`pino_study::run`, the `study` stage's library) on given models; both
//! release the GIL while they work.

use crate::error::to_py;
use pipeline::run::RunOptions;
use pipeline::spec::{locate, LoadOptions, Pipeline};
use pipeline::ui::Ui;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// A pipeline file in its workspace.
#[pyclass(module = "pino_mbd._pino_mbd", name = "Pipeline", frozen)]
pub struct PyPipeline {
    file: PathBuf,
    workspace: Option<PathBuf>,
    bin_dir: Option<PathBuf>,
    sets: Vec<String>,
}

impl PyPipeline {
    fn load(&self, extra: &[String]) -> PyResult<Pipeline> {
        let opts = LoadOptions {
            bin_dir: self.bin_dir.clone().or_else(|| {
                std::env::var_os("PINO_BIN_DIR")
                    .filter(|v| !v.is_empty())
                    .map(PathBuf::from)
            }),
            sets: self.sets.iter().chain(extra).cloned().collect(),
        };
        let (workspace, file) = locate(&self.file, self.workspace.as_deref()).map_err(to_py)?;
        Pipeline::load(&workspace, &file, &opts).map_err(to_py)
    }
}

#[pymethods]
impl PyPipeline {
    /// The pipeline file `file` in `workspace` (the `pipeline` command's `-f` and `-C`:
    /// without a workspace, the file's `workspace:` or its directory, `file` relative to the
    /// current directory), with `sets` (`STAGE.KEY=VALUE`, YAML values) applied to every call.
    #[new]
    #[pyo3(signature = (file, workspace, bin_dir, sets))]
    fn new(
        file: PathBuf,
        workspace: Option<PathBuf>,
        bin_dir: Option<PathBuf>,
        sets: Vec<String>,
    ) -> Self {
        Self {
            file,
            workspace,
            bin_dir,
            sets,
        }
    }

    /// Every unit's state as columns: unit, state, detail (`pipeline status`).
    fn _status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let p = self.load(&[])?;
        let units = py
            .detach(|| pipeline::status::unit_states(&p))
            .map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item(
            "unit",
            units.iter().map(|u| u.key.clone()).collect::<Vec<_>>(),
        )?;
        d.set_item("state", units.iter().map(|u| u.state).collect::<Vec<_>>())?;
        d.set_item(
            "detail",
            units.iter().map(|u| u.detail.clone()).collect::<Vec<_>>(),
        )?;
        Ok(d)
    }

    /// Runs `targets` (all when empty) and what is stale upstream (`pipeline run`).
    #[pyo3(signature = (targets, sets, force, jobs))]
    fn _run(
        &self,
        py: Python<'_>,
        targets: Vec<String>,
        sets: Vec<String>,
        force: bool,
        jobs: usize,
    ) -> PyResult<()> {
        let p = self.load(&sets)?;
        py.detach(|| {
            let opts = RunOptions {
                targets,
                force,
                jobs: jobs.max(1),
                wait: true,
                executor: None,
            };
            pipeline::run::run(&p, &opts, &Ui::new())
        })
        .map_err(to_py)
    }

    /// The paths of a stage's current output files (`pipeline show`).
    #[pyo3(signature = (stage, sets))]
    fn _show(&self, py: Python<'_>, stage: String, sets: Vec<String>) -> PyResult<Vec<String>> {
        let p = self.load(&sets)?;
        let text = py
            .detach(|| pipeline::status::show(&p, &stage))
            .map_err(to_py)?;
        Ok(text.lines().map(str::to_owned).collect())
    }

    /// The pipeline file (relative to the current directory, or absolute).
    #[getter]
    fn file(&self) -> PyResult<PathBuf> {
        Ok(locate(&self.file, self.workspace.as_deref())
            .map_err(to_py)?
            .1)
    }

    /// The workspace: the one given, else the file's (`workspace:` or its directory).
    #[getter]
    fn workspace(&self) -> PyResult<PathBuf> {
        Ok(locate(&self.file, self.workspace.as_deref())
            .map_err(to_py)?
            .0)
    }
}

/// One design study (`docs/studies.md`) through the surrogate in `surrogate` or, without one,
/// the model of the parameters' `algorithm` among `models` (directories of `train`) with the
/// calibration's output when given, written to `out`; `params_json` is the `study` stage's
/// parameters (`study`, `algorithm`, `coverage`, `seed`, ...). Returns the stage's summary line.
#[pyfunction]
#[pyo3(signature = (models, params_json, out, calibration=None, surrogate=None))]
pub fn _study(
    py: Python<'_>,
    models: Vec<PathBuf>,
    params_json: String,
    out: PathBuf,
    calibration: Option<PathBuf>,
    surrogate: Option<PathBuf>,
) -> PyResult<String> {
    let params: pino_study::StudyParams = serde_json::from_str(&params_json)
        .map_err(|e| crate::error::value_error(format!("study parameters: {e}")))?;
    py.detach(|| {
        pino_learn::candle_single_threaded_by_default();
        let device = params.device.device().map_err(to_py)?;
        std::fs::create_dir_all(&out)
            .map_err(|e| crate::error::value_error(format!("{}: {e}", out.display())))?;
        let surrogate = pino_study::load_surrogate(
            surrogate.as_deref(),
            &models,
            calibration.as_deref(),
            &params,
            &device,
        )
        .map_err(to_py)?;
        pino_study::run(&surrogate, &params, Path::new(&out)).map_err(to_py)
    })
}
