//! `pino_mbd.System`: a system description (`docs/systems.md`) loaded, compiled and checked as
//! every stage loads it, its tables (parameters, stored columns, indices), and the exact solver
//! on a table of designs: the `simulate` stage's engine (`mbd_engine::prepare`, `run_all`) on
//! all cores with the GIL released, giving the columns and values of `simulation.parquet`.

use crate::arrow::{import, ArrowTable};
use crate::error::{to_py, value_error};
use crate::excitation::{Excitation, RowProfiles};
use crate::progress::Progress;
use mbd_engine::{RunConfig, SampleInput, StartMode};
use mbd_system::system::{ParamSource, Role};
use mbd_system::{Override, System, SystemSource};
use pino_data::{schema, Column, Table};
use pino_predict::DesignSpace;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Samples simulated at once (as the stage: memory holds at most this many trajectories
/// beyond the output columns).
const CHUNK: usize = 64;

/// A compiled system description.
#[pyclass(module = "pino_mbd._pino_mbd", name = "System", frozen)]
pub struct PySystem {
    source: SystemSource,
    system: Arc<System>,
    space: DesignSpace,
}

/// Profile spacing (m) of a generated excitation of `System.simulate` that gives none: the
/// shipped pipelines' `irregularity.dx`.
pub const DEFAULT_DX: f64 = 0.1;

/// Profile length (m) of a generated excitation of `System.simulate` that gives none: the
/// farthest point an element reads a generated profile over the description's sampling box
/// in this run, plus one spacing, rounded up to whole 10 m, and at least the longest
/// wavelength the description generates.
fn default_length(system: &System, config: &RunConfig, dx: f64) -> PyResult<f64> {
    let reach = mbd_engine::coverage::generated_profile_reach(system, config)
        .map_err(|e| value_error(format!("excitation: {e}")))?
        .unwrap_or(0.0);
    let longest = system
        .profiles
        .iter()
        .filter_map(|p| match p {
            mbd_system::system::Profile::Generated { wavelengths, .. } => Some(wavelengths[1]),
            _ => None,
        })
        .fold(0.0, f64::max);
    Ok((10.0 * ((reach.max(0.0) + dx) / 10.0).ceil()).max(longest))
}

impl PySystem {
    /// The compiled system.
    pub fn system(&self) -> &Arc<System> {
        &self.system
    }
}

#[pymethods]
impl PySystem {
    /// Reads and compiles the description at `path`, `values` overriding parameters (a
    /// number, or `[lo, hi]` for a sampled parameter's range).
    #[staticmethod]
    #[pyo3(signature = (path, values=None))]
    fn load(path: PathBuf, values: Option<BTreeMap<String, Bound<'_, PyAny>>>) -> PyResult<Self> {
        let mut overrides = BTreeMap::new();
        for (name, v) in values.unwrap_or_default() {
            let o = if let Ok(x) = v.extract::<f64>() {
                Override::Value(x)
            } else if let Ok([lo, hi]) = v.extract::<[f64; 2]>() {
                Override::Range([lo, hi])
            } else {
                return Err(value_error(format!(
                    "values.{name}: allowed a number or [lo, hi]"
                )));
            };
            overrides.insert(name, o);
        }
        let source = SystemSource::read(&path, overrides).map_err(to_py)?;
        let system = Arc::new(source.compile().map_err(|e| match e {
            // The argument's name, not the stages' `system_values` or a line of the file.
            mbd_system::SourceError::Override { error, .. } => {
                value_error(format!("values.{}: {}", error.name, error.message))
            }
            e => to_py(e),
        })?);
        Ok(Self {
            space: DesignSpace::of(system.clone()),
            source,
            system,
        })
    }

    /// The system's name.
    #[getter]
    fn name(&self) -> &str {
        &self.system.name
    }

    /// The description's file.
    #[getter]
    fn path(&self) -> &str {
        &self.source.file
    }

    /// The description's content hash (text and overrides).
    #[getter]
    fn hash(&self) -> String {
        self.source.hash()
    }

    /// The time (s) from which every index reads a record (`indices_from`).
    #[getter]
    fn indices_from(&self) -> f64 {
        self.system.indices_from
    }

    /// The design parameters (sampled), in value order.
    #[getter]
    fn design_parameters(&self) -> Vec<String> {
        self.space.names().to_vec()
    }

    /// The parameter table as columns: name, unit, kind (sampled / fixed / derived), nominal
    /// (the value of a fixed one), min, max (a sampled one's range), expr, doc.
    fn _parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let ps = &self.system.parameters;
        let mut kind = Vec::new();
        let (mut nominal, mut min, mut max, mut expr) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for p in ps {
            let (k, n, r, e) = match &p.source {
                ParamSource::Sampled { nominal, range } => {
                    ("sampled", Some(*nominal), Some(*range), None)
                }
                ParamSource::Fixed(v) => ("fixed", Some(*v), None, None),
                ParamSource::Derived(e) => ("derived", None, None, Some(e.to_string())),
            };
            kind.push(k);
            nominal.push(n);
            min.push(r.map(|r| r[0]));
            max.push(r.map(|r| r[1]));
            expr.push(e);
        }
        let d = PyDict::new(py);
        d.set_item(
            "name",
            ps.iter().map(|p| p.name.clone()).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "unit",
            ps.iter().map(|p| p.unit.clone()).collect::<Vec<_>>(),
        )?;
        d.set_item("kind", kind)?;
        d.set_item("nominal", nominal)?;
        d.set_item("min", min)?;
        d.set_item("max", max)?;
        d.set_item("expr", expr)?;
        d.set_item("doc", ps.iter().map(|p| p.doc.clone()).collect::<Vec<_>>())?;
        Ok(d)
    }

    /// The columns of `simulate` (and `simulation.parquet`) as columns: name, unit, kind.
    fn _columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let mut name = vec![schema::SAMPLE_ID.to_owned(), schema::TIME.to_owned()];
        let fixed = |n| {
            pino_data::units::fixed_unit(n)
                .unwrap_or_default()
                .to_owned()
        };
        let mut unit = vec![fixed(schema::SAMPLE_ID), fixed(schema::TIME)];
        let mut kind = vec!["id", "time"];
        for c in &self.system.channels {
            name.push(c.name.clone());
            unit.push(c.unit.clone());
            kind.push(match c.role {
                Role::Solution => "solution",
                Role::Velocity => "velocity",
                Role::Acceleration => "acceleration",
                Role::Excitation => "excitation",
                Role::Force => "force",
                Role::Other => "other",
            });
        }
        let d = PyDict::new(py);
        d.set_item("name", name)?;
        d.set_item("unit", unit)?;
        d.set_item("kind", kind)?;
        Ok(d)
    }

    /// The engineering indices as columns: name, unit, limit (at the defaults), definition.
    fn _indices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let set = pino_indices::system::IndexSet::of(&self.system);
        let cfg = pino_outputs::indices_eval::eval_config(&self.system).map_err(to_py)?;
        let cols = set.columns(&self.system);
        let limits = set.column_limits(&self.system, &cfg);
        let d = PyDict::new(py);
        d.set_item(
            "name",
            cols.iter().map(|c| c.name.clone()).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "unit",
            cols.iter().map(|c| c.unit.clone()).collect::<Vec<_>>(),
        )?;
        d.set_item("limit", limits)?;
        d.set_item(
            "definition",
            cols.iter()
                .map(|c| c.definition.clone())
                .collect::<Vec<_>>(),
        )?;
        Ok(d)
    }

    /// Runs the exact solver on every design (module doc); returns (simulation, failures).
    #[pyo3(signature = (designs, excitation, duration, dt, output_every, start, x0, startup_zero_fraction, startup_ramp_fraction, progress))]
    #[allow(clippy::too_many_arguments)]
    fn _simulate(
        &self,
        py: Python<'_>,
        designs: &Bound<'_, PyAny>,
        excitation: Option<&Bound<'_, PyAny>>,
        duration: f64,
        dt: f64,
        output_every: usize,
        start: String,
        x0: f64,
        startup_zero_fraction: f64,
        startup_ramp_fraction: f64,
        progress: bool,
    ) -> PyResult<(ArrowTable, ArrowTable)> {
        let start = StartMode::try_from(start).map_err(|e| value_error(format!("start: {e}")))?;
        let config = RunConfig {
            duration,
            dt,
            output_every,
            start,
            startup_zero_fraction,
            startup_ramp_fraction,
            x0,
        };
        config.validate().map_err(to_py)?;
        let table = import(designs, "designs")?;
        let d = crate::designs::designs(&self.space, &table, "designs")?;
        let ids = d.ids_or_rows();
        let mut seen = std::collections::BTreeSet::new();
        if let Some(id) = ids.iter().find(|&&id| !seen.insert(id)) {
            return Err(value_error(format!(
                "designs.sample_id: {id} appears twice; allowed: one row per sample"
            )));
        }
        let excitation = Excitation::parse(excitation)?;
        let system = self.system.clone();
        let (sim, failed) = py.detach(move || {
            let generation = || -> PyResult<(f64, f64)> {
                Ok((DEFAULT_DX, default_length(&system, &config, DEFAULT_DX)?))
            };
            let profiles = excitation.rows(&system, &generation, ids.clone())?;
            simulate(&system, &config, d.sets, &ids, profiles, progress)
        })?;
        Ok((
            ArrowTable::new(sim, "simulation")?,
            ArrowTable::new(failed, "failures")?,
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "System({:?}: {} design parameters, {} columns, from {})",
            self.system.name,
            self.space.names().len(),
            self.system.channels.len() + 2,
            self.source.file
        )
    }
}

/// The solver on designs `sets` with sample ids `sample_ids` on `profiles` (sorted by sample
/// id, as the stage writes them): the simulation table and the failures (`sample_id`,
/// `reason`).
fn simulate(
    system: &Arc<System>,
    config: &RunConfig,
    sets: Vec<Vec<f64>>,
    sample_ids: &[i64],
    profiles: RowProfiles,
    progress: bool,
) -> PyResult<(Table, Table)> {
    let mut inputs: Vec<SampleInput> = sets
        .into_iter()
        .zip(profiles.into_rows())
        .zip(sample_ids)
        .map(|((params, profiles), &id)| {
            let params = system
                .sampled_values(params)
                .map_err(|e| value_error(format!("designs: sample_id {id}: {e}")))?;
            Ok(SampleInput {
                id: id as u64,
                params,
                profiles,
            })
        })
        .collect::<PyResult<_>>()?;
    inputs.sort_by_key(|s| s.id);
    let engines = mbd_engine::prepare(system, config, inputs)
        .map_err(|(id, e)| value_error(format!("designs: sample_id {id}: {e}")))?;
    let bar = Progress::new("simulate", engines.len(), progress);
    let rows = engines.len() * config.n_outputs();
    let mut ids: Vec<i64> = Vec::with_capacity(rows);
    let mut t: Vec<f64> = Vec::with_capacity(rows);
    let mut cols: Vec<Vec<f64>> = vec![Vec::with_capacity(rows); system.channels.len()];
    let (mut failed_ids, mut reasons) = (Vec::new(), Vec::new());
    mbd_engine::run_all(&engines, CHUNK, &|| bar.inc(), |id, out| {
        match out {
            Ok(tr) => {
                ids.extend(std::iter::repeat_n(id as i64, tr.t.len()));
                t.extend_from_slice(&tr.t);
                for (col, c) in cols.iter_mut().zip(&tr.columns) {
                    col.extend_from_slice(c);
                }
            }
            Err(f) => {
                failed_ids.push(id as i64);
                reasons.push(f.reason);
            }
        }
        Ok::<(), std::convert::Infallible>(())
    })
    .unwrap_or_else(|e| match e {});
    bar.finish();
    let units = pino_data::system::units_of(system).map_err(to_py)?;
    let mut sim = Table::with_origin(Path::new("simulation")).with_units(units);
    let push = |t: &mut Table, name: &str, col| t.push(name, col).map_err(to_py);
    push(&mut sim, schema::SAMPLE_ID, Column::I64(ids))?;
    push(&mut sim, schema::TIME, Column::F64(t))?;
    for (c, col) in system.channels.iter().zip(cols) {
        push(&mut sim, &c.name, Column::F64(col))?;
    }
    let mut failures = Table::with_origin(Path::new("failures"));
    push(&mut failures, schema::SAMPLE_ID, Column::I64(failed_ids))?;
    push(&mut failures, "reason", Column::Str(reasons))?;
    Ok((sim, failures))
}
