//! The excitation of a call, in the one vocabulary of every front that runs designs
//! (`System.simulate`, `Model.predict`, `Model.indices`; docs/python.md): the `excitation`
//! argument names where the profile points under the system come from, and each design row
//! names its own stream or sample of it.
//!
//! `excitation` is one of
//! - `None`: no profile points (a system whose profiles are all analytic);
//! - a seed (an integer >= 0), short for `{"seed": N}`;
//! - `{"seed": N, "dx": m, "length": m}`: profiles generated as the `irregularity` stage
//!   generates them; `dx` and `length` default to the caller's ([`Generation`]);
//! - a profile table (`sample_id`, `x`, `eta` in m, and `profile` when the system has several
//!   generated profiles: the `irregularity` artifact), given as a table or a Parquet file's
//!   path; a table without `sample_id` is one profile set for every row.
//!
//! Row `k` runs on stream (generated) or sample (table) `ids[k]` ([`Excitation::rows`]): the
//! profiles of each distinct id are made once and shared by its rows ([`RowProfiles`]).

use crate::arrow::import;
use crate::error::{to_py, value_error};
use mbd_dataset::ProfileParams;
use mbd_engine::Profile;
use mbd_system::System;
use pino_data::{schema, Column, Table};
use pino_predict::{profiles_of_table, GeneratedProfiles};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The argument's name, which every refusal of an excitation starts with.
pub const ARGUMENT: &str = "excitation";

/// The forms an excitation takes, as one line for messages.
const FORMS: &str = "a seed (an integer >= 0), {\"seed\": N, \"dx\": m, \"length\": m} or a profile table (sample_id, x, eta in m; a DataFrame or a Parquet file's path)";

/// The spacing and length (m) of a generated excitation when the argument leaves them out:
/// the model's dataset's for a model, derived from the run for the solver.
pub type Generation<'a> = &'a dyn Fn() -> PyResult<(f64, f64)>;

/// Where the profile points come from.
pub enum Excitation {
    /// None given.
    None,
    /// Generated as `irregularity` generates them; `dx` and `length` (m) when given.
    Generated {
        /// Seed of the random phases.
        seed: u64,
        /// Profile spacing (m).
        dx: Option<f64>,
        /// Profile length (m), from `x = 0`.
        length: Option<f64>,
    },
    /// A profile table and the name its refusals give (the file, or `excitation`).
    Table(Table, PathBuf),
}

impl Excitation {
    /// The excitation `obj` names (module doc); anything else is refused listing the forms.
    pub fn parse(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let Some(obj) = obj.filter(|o| !o.is_none()) else {
            return Ok(Self::None);
        };
        if let Ok(d) = obj.cast::<PyDict>() {
            return generated(d);
        }
        if obj.is_instance_of::<PyString>() || obj.hasattr("__fspath__")? {
            let path: PathBuf = obj.extract()?;
            let t = pino_data::read_parquet(&path, None)
                .map_err(|e| value_error(format!("{ARGUMENT}: {e}")))?;
            return Ok(Self::Table(t, path));
        }
        if obj.hasattr("__arrow_c_stream__")? {
            return Ok(Self::Table(import(obj, ARGUMENT)?, PathBuf::from(ARGUMENT)));
        }
        if !obj.is_instance_of::<PyBool>() {
            if let Ok(seed) = obj.extract::<i128>() {
                return Ok(Self::Generated {
                    seed: seed_of(seed)?,
                    dx: None,
                    length: None,
                });
            }
        }
        Err(value_error(format!(
            "{ARGUMENT} = {}: allowed {FORMS}",
            obj.repr()?
        )))
    }

    /// The id every row runs on when the designs name none: stream 0 of a generated
    /// excitation, the first sample of a table (as `predict --profile-id` left out).
    pub fn first_id(&self) -> i64 {
        match self {
            Self::Table(t, _) => t
                .i64(schema::SAMPLE_ID)
                .ok()
                .and_then(|ids| ids.first().copied())
                .unwrap_or(0),
            Self::None | Self::Generated { .. } => 0,
        }
    }

    /// The profiles of `system` under each row, row `k` on stream or sample `ids[k]`;
    /// `generation` gives the spacing and length a generated excitation leaves out.
    pub fn rows(
        &self,
        system: &System,
        generation: Generation<'_>,
        ids: Vec<i64>,
    ) -> PyResult<RowProfiles> {
        let mut unique = ids.clone();
        unique.sort_unstable();
        unique.dedup();
        let by_id = match self {
            Self::None => {
                refuse_none(system)?;
                unique
                    .iter()
                    .map(|&id| (id, vec![None; system.profiles.len()]))
                    .collect()
            }
            Self::Generated { seed, dx, length } => {
                let (dx, length) = match (*dx, *length) {
                    (Some(dx), Some(length)) => (dx, length),
                    (dx, length) => {
                        let (d, l) = generation()?;
                        (dx.unwrap_or(d), length.unwrap_or(l))
                    }
                };
                let settings = ProfileParams {
                    seed: *seed,
                    dx,
                    length,
                };
                let g =
                    GeneratedProfiles::named(system, &settings, *seed, ARGUMENT).map_err(to_py)?;
                use rayon::prelude::*;
                unique
                    .par_iter()
                    .map(|&id| -> PyResult<_> { Ok((id, g.of(id as u64).map_err(to_py)?)) })
                    .collect::<PyResult<_>>()?
            }
            Self::Table(t, path) => of_table(system, t, path, &unique)?,
        };
        Ok(RowProfiles { by_id, ids })
    }
}

/// The profile points under each row of a call.
pub struct RowProfiles {
    by_id: BTreeMap<i64, Vec<Option<Profile>>>,
    ids: Vec<i64>,
}

impl RowProfiles {
    /// The profiles of row `k` (for `pino_predict::ProfileSource::PerDesign`).
    pub fn of(&self, k: usize) -> pino_outputs::Result<Vec<Option<Profile>>> {
        Ok(self.by_id[&self.ids[k]].clone())
    }

    /// Every row's profiles, in row order.
    pub fn into_rows(self) -> Vec<Vec<Option<Profile>>> {
        let Self { by_id, ids } = self;
        ids.iter().map(|id| by_id[id].clone()).collect()
    }
}

/// `{"seed": N, "dx": m, "length": m}`: the keys checked, `dx` and `length` optional.
fn generated(d: &Bound<'_, PyDict>) -> PyResult<Excitation> {
    for key in d.keys() {
        let key: String = key.extract()?;
        if !["seed", "dx", "length"].contains(&key.as_str()) {
            return Err(value_error(format!(
                "{ARGUMENT}: unknown key `{key}`; allowed: seed, dx (m), length (m)"
            )));
        }
    }
    let Some(seed) = d.get_item("seed")? else {
        return Err(value_error(format!(
            "{ARGUMENT}: missing `seed` (a generated excitation is {{\"seed\": N, \"dx\": m, \"length\": m}}, dx and length optional)"
        )));
    };
    let seed = match seed.extract::<i128>() {
        Ok(s) if !seed.is_instance_of::<PyBool>() => seed_of(s)?,
        _ => {
            return Err(value_error(format!(
                "{ARGUMENT}[\"seed\"] = {}: allowed an integer >= 0",
                seed.repr()?
            )))
        }
    };
    let metres = |key: &str| -> PyResult<Option<f64>> {
        d.get_item(key)?
            .filter(|v| !v.is_none())
            .map(|v| {
                v.extract::<f64>().map_err(|_| {
                    value_error(format!(
                        "{ARGUMENT}[\"{key}\"]: allowed a number of metres, got {}",
                        v.repr().map(|r| r.to_string()).unwrap_or_default()
                    ))
                })
            })
            .transpose()
    };
    Ok(Excitation::Generated {
        seed,
        dx: metres("dx")?,
        length: metres("length")?,
    })
}

fn seed_of(seed: i128) -> PyResult<u64> {
    u64::try_from(seed).map_err(|_| {
        value_error(format!(
            "{ARGUMENT}: seed {seed}: allowed an integer >= 0 (below 2^64)"
        ))
    })
}

/// Refuses no excitation for a system with generated profiles, naming them.
fn refuse_none(system: &System) -> PyResult<()> {
    let generated: Vec<&str> = system
        .profiles
        .iter()
        .filter(|p| matches!(p, mbd_system::system::Profile::Generated { .. }))
        .map(|p| p.name())
        .collect();
    if generated.is_empty() {
        return Ok(());
    }
    Err(value_error(format!(
        "{ARGUMENT}: missing; the system `{}` has generated profile(s) {}: give {FORMS}",
        system.name,
        generated.join(", ")
    )))
}

/// The profiles of each of `ids` from table `t`; a table without `sample_id` is one set of
/// profiles for every id.
fn of_table(
    system: &System,
    t: &Table,
    path: &std::path::Path,
    ids: &[i64],
) -> PyResult<BTreeMap<i64, Vec<Option<Profile>>>> {
    if t.column(schema::SAMPLE_ID).is_ok() {
        return profiles_of_table(system, t, path, ids).map_err(to_py);
    }
    let mut one = t.clone();
    one.push(schema::SAMPLE_ID, Column::I64(vec![0; t.num_rows()]))
        .map_err(to_py)?;
    let profiles = profiles_of_table(system, &one, path, &[0]).map_err(to_py)?;
    Ok(ids.iter().map(|&id| (id, profiles[&0].clone())).collect())
}
