//! `pino_mbd.System`: a system description (`docs/systems.md`) loaded, compiled and checked as
//! every stage loads it, its tables (parameters, stored columns, indices), and the exact solver
//! on a table of designs: the `simulate` stage's engine (`mbd_engine::prepare`, `run_all`) on
//! all cores with the GIL released, giving the columns and values of `simulation.parquet`.

use crate::arrow::{import, ArrowTable};
use crate::error::{to_py, value_error};
use crate::progress::Progress;
use mbd_engine::{Profile, RunConfig, SampleInput, StartMode};
use mbd_system::system::{ParamSource, Role};
use mbd_system::{Override, System, SystemSource};
use pino_data::{schema, Column, Table};
use pino_eval::predict::{profiles_of_table, DesignSpace, GeneratedProfiles};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
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

/// Where the profile points under each design come from.
pub enum Excitation {
    /// None given (fine when every profile is analytic).
    None,
    /// A profile table (`sample_id`, `x`, `eta`, optional `profile`) and its name.
    Table(Table, PathBuf),
    /// Generated as `irregularity` generates them.
    Generated(GeneratedProfiles),
}

impl Excitation {
    /// `obj`: `None`, a path to a Parquet profile file, a table with `sample_id`, `x`, `eta`
    /// (and `profile`), or `{"seed": N, "dx": m, "length": m}` (generated); the dict is only
    /// accepted when `generated` is allowed (without a model's settings).
    pub fn parse(system: &System, obj: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let Some(obj) = obj.filter(|o| !o.is_none()) else {
            return Ok(Self::None);
        };
        if let Ok(d) = obj.cast::<PyDict>() {
            let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
                d.get_item(k)?.ok_or_else(|| {
                    value_error(format!(
                        "excitation: missing `{k}` (a generated excitation is {{\"seed\": N, \"dx\": m, \"length\": m}})"
                    ))
                })
            };
            for key in d.keys() {
                let key: String = key.extract()?;
                if !["seed", "dx", "length"].contains(&key.as_str()) {
                    return Err(value_error(format!(
                        "excitation: unknown key `{key}`; allowed: seed, dx (m), length (m)"
                    )));
                }
            }
            let settings = mbd_dataset::ProfileParams {
                seed: get("seed")?.extract()?,
                dx: get("dx")?.extract()?,
                length: get("length")?.extract()?,
            };
            let g = GeneratedProfiles::new(system, &settings, settings.seed).map_err(to_py)?;
            return Ok(Self::Generated(g));
        }
        if obj.is_instance_of::<PyString>() || obj.hasattr("__fspath__")? {
            let path: PathBuf = obj.extract()?;
            let t = pino_data::read_parquet(&path, None).map_err(to_py)?;
            return Ok(Self::Table(t, path));
        }
        let t = import(obj, "excitation")?;
        Ok(Self::Table(t, PathBuf::from("excitation")))
    }

    /// The profiles under each design, by the designs' sample ids.
    pub fn profiles(&self, system: &System, ids: &[i64]) -> PyResult<Vec<Vec<Option<Profile>>>> {
        match self {
            Self::Generated(g) => {
                use rayon::prelude::*;
                ids.par_iter()
                    .map(|&id| g.of(id as u64).map_err(to_py))
                    .collect()
            }
            Self::Table(t, path) => {
                let mut by_id = profiles_of_table(system, t, path, ids).map_err(to_py)?;
                Ok(ids
                    .iter()
                    .map(|id| by_id.get_mut(id).map(std::mem::take).unwrap_or_default())
                    .collect())
            }
            Self::None => {
                let generated: Vec<&str> = system
                    .profiles
                    .iter()
                    .filter(|p| matches!(p, mbd_system::system::Profile::Generated { .. }))
                    .map(|p| p.name())
                    .collect();
                if !generated.is_empty() {
                    return Err(value_error(format!(
                        "excitation: the system `{}` has generated profile(s) {}: give a profile file or table (sample_id, x, eta) or {{\"seed\": N, \"dx\": m, \"length\": m}}",
                        system.name,
                        generated.join(", ")
                    )));
                }
                Ok(vec![vec![None; system.profiles.len()]; ids.len()])
            }
        }
    }
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
        let cfg = pino_eval::indices_eval::eval_config(&self.system).map_err(to_py)?;
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
        let mut seen = std::collections::BTreeSet::new();
        if let Some(id) = d.ids.iter().find(|&&id| !seen.insert(id)) {
            return Err(value_error(format!(
                "designs.sample_id: {id} appears twice; allowed: one row per sample"
            )));
        }
        let excitation = Excitation::parse(&self.system, excitation)?;
        let system = self.system.clone();
        let (sim, failed) =
            py.detach(move || simulate(&system, &config, d, &excitation, progress))?;
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

/// The solver on designs `d` (sorted by sample id, as the stage writes them): the simulation
/// table and the failures (`sample_id`, `reason`).
fn simulate(
    system: &Arc<System>,
    config: &RunConfig,
    d: crate::designs::Designs,
    excitation: &Excitation,
    progress: bool,
) -> PyResult<(Table, Table)> {
    let profiles = excitation.profiles(system, &d.ids)?;
    let mut inputs: Vec<SampleInput> = d
        .sets
        .into_iter()
        .zip(profiles)
        .zip(&d.ids)
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
