//! What `pino_mbd.Model` ([`crate::model`]) and `pino_mbd.Surrogate` ([`crate::surrogate`])
//! answer alike, through the `predict` command's library (`pino_surrogate::Surrogate`:
//! a model is a surrogate of one member, as `predict --model` reads it): time histories of
//! designs, and their engineering indices with calibrated intervals and three-valued verdicts;
//! the same tables, numbers and `outside_training_range` flags as `predict --out` and `predict
//! --indices` (row by row with `--profile-id` the row's excitation id), computed with the GIL
//! released. Each design row runs on its own excitation ([`crate::excitation`]).

use crate::arrow::{import, ArrowTable};
use crate::designs::designs;
use crate::error::{to_py, value_error};
use crate::excitation::{Excitation, RowProfiles};
use pino_predict::{outside_flag, Predictor, ProfileSource};
use pino_surrogate::Surrogate;
use pyo3::prelude::*;

/// The arguments of an `_answer` call, as the Python layer passes them.
struct Request<'a, 'py> {
    designs: &'a Bound<'py, PyAny>,
    excitation: Option<&'a Bound<'py, PyAny>>,
    excitation_id: Option<i64>,
    x0: Option<f64>,
    coverage: Option<f64>,
    batch: usize,
    strict: bool,
}

/// The designs of a call and their run: sets, each row's profiles, run controls, outside
/// flags.
struct Call {
    sets: Vec<Vec<f64>>,
    profiles: RowProfiles,
    run: mbd_engine::RunConfig,
    outside: Vec<Vec<pino_learn::checkpoint::OutOfRange>>,
}

/// The designs of `r` on its excitation ([`crate::excitation`]) for `s` (whose primary member
/// holds the design space, the run and the training ranges its members share): row `k` on
/// the stream or sample of its `sample_id` when the designs have that column (an
/// `excitation_id` beside it must name the same), else of `excitation_id` (default: the
/// excitation's first, [`Excitation::first_id`]).
fn call(s: &Surrogate, r: &Request<'_, '_>) -> PyResult<Call> {
    let p = s.primary();
    let table = import(r.designs, "designs")?;
    let d = designs(&p.space, &table, "designs")?;
    let excitation = Excitation::parse(r.excitation)?;
    let ids = match (d.ids, r.excitation_id) {
        (Some(ids), Some(id)) => match ids.iter().position(|&i| i != id) {
            Some(k) => {
                return Err(value_error(format!(
                    "excitation_id = {id}, but designs.sample_id[{k}] = {}: the `sample_id` column names each row's excitation (drop it to run every row on excitation_id)",
                    ids[k]
                )))
            }
            None => ids,
        },
        (Some(ids), None) => ids,
        (None, Some(id)) if id < 0 => {
            return Err(value_error(format!(
                "excitation_id = {id}: allowed an integer >= 0"
            )))
        }
        (None, Some(id)) => vec![id; d.sets.len()],
        (None, None) => vec![excitation.first_id(); d.sets.len()],
    };
    let generation = || dataset_generation(p);
    let profiles = excitation.rows(p.system(), &generation, ids)?;
    let run = p.run_config(r.x0).map_err(to_py)?;
    let outside = p.outside_training(&d.sets).map_err(to_py)?;
    if r.strict {
        if let Some(k) = outside.iter().position(|o| !o.is_empty()) {
            return Err(value_error(format!(
                "strict: designs[{k}] is outside the model's training ranges (from {}): {}",
                p.meta.training_ranges.source,
                outside_flag(&outside[k])
            )));
        }
    }
    Ok(Call {
        sets: d.sets,
        profiles,
        run,
        outside,
    })
}

/// The profile spacing and length (m) of the model's dataset: a generated excitation's
/// defaults.
fn dataset_generation(p: &Predictor) -> PyResult<(f64, f64)> {
    let settings = p.meta.data.as_ref().and_then(|d| d.profiles.as_ref());
    settings.map(|s| (s.dx, s.length)).ok_or_else(|| {
        value_error(
            "excitation: the model's dataset records no profile spacing and length: give {\"seed\": N, \"dx\": m, \"length\": m} or a profile table",
        )
    })
}

/// Time histories of every design of `r` (the table of `predict --out`): each channel and
/// its band from the member of `s` answering it.
fn predict(py: Python<'_>, s: &Surrogate, r: &Request<'_, '_>) -> PyResult<ArrowTable> {
    let c = call(s, r)?;
    let level = s.interval_level(r.coverage).map_err(to_py)?;
    let batch = r.batch;
    let table = py.detach(|| {
        let of = |k| c.profiles.of(k);
        s.histories_flagged(
            &c.sets,
            &ProfileSource::PerDesign(&of),
            &c.run,
            batch,
            level,
        )
        .map_err(to_py)
    })?;
    ArrowTable::new(table, "predict")
}

/// The engineering indices of every design of `r` (the table of `predict --indices`): each
/// index, its interval and verdict from the member of `s` answering it.
fn indices(py: Python<'_>, s: &Surrogate, r: &Request<'_, '_>) -> PyResult<ArrowTable> {
    let c = call(s, r)?;
    let level = s
        .interval_level(r.coverage)
        .map_err(to_py)?
        .unwrap_or(pino_calibration::DEFAULT_COVERAGE);
    let batch = r.batch;
    let table = py.detach(|| -> PyResult<_> {
        let cfg = s.primary().index_config().map_err(to_py)?;
        let of = |k| c.profiles.of(k);
        let profiles = ProfileSource::PerDesign(&of);
        let answers = s
            .answers(&c.sets, &profiles, &c.run, &cfg, batch, level)
            .map_err(to_py)?;
        s.indices_table(&c.sets, &answers, &c.outside)
            .map_err(to_py)
    })?;
    ArrowTable::new(table, "indices")
}

/// The native base class of `Model` and `Surrogate`: a surrogate (of one member for a
/// model) answering designs.
#[pyclass(module = "pino_mbd._pino_mbd", name = "_Answers", subclass, frozen)]
pub struct PyAnswers {
    surrogate: Surrogate,
}

impl PyAnswers {
    /// The answers of `surrogate`, whose refusals name the designs `designs`.
    pub fn new(mut surrogate: Surrogate) -> Self {
        surrogate.name_designs("designs");
        Self { surrogate }
    }

    /// The surrogate answering.
    pub fn surrogate(&self) -> &Surrogate {
        &self.surrogate
    }
}

#[pymethods]
impl PyAnswers {
    /// The name of the system.
    #[getter]
    fn system_name(&self) -> String {
        self.surrogate.primary().system().name.clone()
    }

    /// The design parameters (sampled), in value order.
    #[getter]
    fn design_parameters(&self) -> Vec<String> {
        self.surrogate.primary().space.names().to_vec()
    }

    /// One table of every design: `histories` (the table of `predict --out`) or `indices` (the
    /// table of `predict --indices`).
    #[pyo3(signature = (table, designs, excitation, excitation_id, x0, coverage, batch, strict))]
    #[allow(clippy::too_many_arguments)]
    fn _answer(
        &self,
        py: Python<'_>,
        table: &str,
        designs: &Bound<'_, PyAny>,
        excitation: Option<&Bound<'_, PyAny>>,
        excitation_id: Option<i64>,
        x0: Option<f64>,
        coverage: Option<f64>,
        batch: usize,
        strict: bool,
    ) -> PyResult<ArrowTable> {
        let r = Request {
            designs,
            excitation,
            excitation_id,
            x0,
            coverage,
            batch,
            strict,
        };
        match table {
            "histories" => predict(py, &self.surrogate, &r),
            "indices" => indices(py, &self.surrogate, &r),
            other => Err(value_error(format!(
                "table `{other}`: allowed `histories` or `indices`"
            ))),
        }
    }
}
