//! The `indices` stage's engine: the indices of every simulated sample of any described system
//! (`docs/indices.md`), in bounded memory on datasets far larger than RAM.
//!
//! A description brings two families of indices ([`pino_indices::IndexSet`]): the railway
//! indices, when its `railway:` section binds them to its stored columns by name (the
//! vehicle-track description does), and its own simple indices (`indices:`,
//! `stat(channel - subtract) / divide` with `stat` one of max, min, max |.|, RMS,
//! peak-to-peak). Two passes over the `simulation.parquet` shards:
//!
//! 1. [`record_pass`] (plain Rust, rayon): streams `sample_id, t`, the car-body columns of the
//!    railway binding and the channels of the simple indices through the shared record reader
//!    ([`pino_data::records::for_each_record`]), one group of whole samples at a time; checks
//!    each record (a uniform grid, finite values in the window), fixes its evaluation window
//!    (from the later of the start-up fraction's first point `floor(f n)` and the description's
//!    `indices_from`, [`pino_indices::IndexConfig::first_row`]) and
//!    computes everything of the car body (the Sperling index of the three car-body signals,
//!    their peaks and sums of squares, in time order so the RMS has the same bits on every
//!    run) and every simple index ([`pino_indices::system::simple`]).
//! 2. [`aggregate`] (polars, railway binding only): one lazy query over all shards, joined with
//!    each sample's window start, filtered to the window and grouped by `sample_id`: the
//!    extremes of the bound contact forces, bogie accelerations and rail displacements
//!    ([`Extremes`]: maxima and minima, exact whatever the order, so deterministic on the
//!    parallel streaming engine) and a finiteness check of every railway signal, on every
//!    core, without materialising the dataset.
//!
//! [`pino_indices::Indices::from_parts`] then combines the two with the sample's static wheel
//! load `W` and half bogie distance `l_c` (the binding's `static_wheel_load` and `half_length`
//! expressions over the sample's parameters, [`mbd_system::System::values`]), as `evaluate`
//! and `predict` do from their plain-Rust folds. [`write_outputs`] writes `indices.parquet`
//! (`sample_id`, `split`, the sampled parameters, the index columns in
//! [`pino_indices::IndexSet::columns`] order, `window_s`, `pass`, `failed`; sorted by
//! `sample_id`) and `indices.json` (the settings used and every column's unit and definition).
//! A description with neither family still gets both files, with the keys only.

mod aggregate;
mod output;
mod records;

pub use aggregate::{aggregate, Extremes};
pub use output::{describe_json, summary, to_table, write_outputs};
pub use records::{record_pass, CarBody, RecordIndices};

use mbd_system::System;
use pino_data::schema;
use pino_indices::system::IndexInfo;
use pino_indices::{Aggregates, IndexConfig, IndexSet, Indices};
use polars::prelude::{LazyFrame, PlRefPath, ScanArgsParquet};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Errors of the scan; each names the file and, where it applies, the sample and column.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The data layer failed (unreadable file, missing column, ...).
    #[error(transparent)]
    Data(#[from] pino_data::Error),
    /// A sample's record is unusable (NaN, too short, ...).
    #[error("{path}: sample {sample}: {source}")]
    Index {
        /// The simulation file.
        path: PathBuf,
        /// The sample.
        sample: i64,
        /// What is wrong.
        source: pino_indices::Error,
    },
    /// A design that does not fit the system's sampled parameters.
    #[error(transparent)]
    Design(#[from] mbd_system::SampledError),
    /// The index parameters are invalid.
    #[error("bad parameters: {0}")]
    Params(pino_indices::Error),
    /// A required column is absent from a simulation file.
    #[error("{path}: missing column `{column}` (present: {present})")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column.
        column: String,
        /// The columns that are there.
        present: String,
    },
    /// The dataset is inconsistent (rows out of order, unknown or duplicate samples, ...).
    #[error("{path}: {message}")]
    Dataset {
        /// The file at fault.
        path: PathBuf,
        /// What is wrong, with the offending values.
        message: String,
    },
    /// polars failed.
    #[error("{path}: polars: {message}")]
    Polars {
        /// The file (or files) of the query.
        path: PathBuf,
        /// What polars said.
        message: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

fn dataset(path: &Path, message: String) -> Error {
    Error::Dataset {
        path: path.to_owned(),
        message,
    }
}

/// One sample of `params.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleInfo {
    /// Its split label.
    pub split: String,
    /// Its design: the sampled parameters' values (the columns of `params.parquet`).
    pub params: mbd_system::Sampled,
    /// Every parameter's value ([`System::values`] of `params`): what the description's
    /// expressions (`static_wheel_load`, `half_length`, `subtract`, `divide`) evaluate over.
    pub values: Vec<f64>,
}

/// Reads `params.parquet` (one file per upstream shard, usually one) through
/// [`pino_data::records::read_params`]: every sample's split and sampled parameters, by id.
pub fn read_params(system: &System, files: &[PathBuf]) -> Result<BTreeMap<i64, SampleInfo>> {
    pino_data::records::read_params_of(files, system)?
        .rows()
        .map(|(id, split, params)| {
            let params = system.sampled_values(params)?;
            let values = system.values(&params)?;
            Ok((
                id,
                SampleInfo {
                    split,
                    params,
                    values,
                },
            ))
        })
        .collect()
}

/// The columns the indices of `set` read from a simulation file: `sample_id`, `t`, then the
/// signals ([`IndexSet::inputs`]: the railway binding's, then the simple indices' channels).
pub fn needed_columns(set: &IndexSet) -> Vec<String> {
    let mut c = vec![schema::SAMPLE_ID.to_owned(), schema::TIME.to_owned()];
    c.extend(set.inputs());
    c
}

fn pl_path(path: &Path) -> Result<PlRefPath> {
    let s = path.to_str().ok_or_else(|| {
        dataset(
            path,
            "the path is not valid UTF-8 (polars needs UTF-8 paths)".into(),
        )
    })?;
    Ok(PlRefPath::new(s))
}

fn polars_err(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Polars {
        path: path.to_owned(),
        message: e.to_string(),
    }
}

/// Checks, from each file's footer, that every column of `needed` is there.
pub fn check_columns(files: &[PathBuf], needed: &[String]) -> Result<()> {
    for f in files {
        let mut lf = LazyFrame::scan_parquet(pl_path(f)?, ScanArgsParquet::default())
            .map_err(|e| polars_err(f, e))?;
        let schema = lf.collect_schema().map_err(|e| polars_err(f, e))?;
        let present: Vec<String> = schema.iter_names().map(|n| n.to_string()).collect();
        for c in needed {
            if !present.contains(c) {
                return Err(Error::MissingColumn {
                    path: f.clone(),
                    column: c.clone(),
                    present: present.join(", "),
                });
            }
        }
    }
    Ok(())
}

/// One output row.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// `sample_id`.
    pub id: i64,
    /// Its split and parameters.
    pub info: SampleInfo,
    /// Its index values, in [`Computed::columns`] order.
    pub values: Vec<f64>,
    /// Its railway indices, when the description binds them.
    pub railway: Option<Indices>,
    /// Length of its evaluation window (s): points times `dt`.
    pub window_s: f64,
    /// Limits it exceeds (empty: it passes).
    pub failed: Vec<String>,
}

/// Everything the stage computed.
#[derive(Debug, Clone)]
pub struct Computed {
    /// The description's name.
    pub system: String,
    /// The index columns ([`IndexSet::columns`]).
    pub columns: Vec<IndexInfo>,
    /// Whether the railway family is bound (the first 14 columns are then its indices).
    pub railway: bool,
    /// One row per simulated sample, by id.
    pub rows: Vec<Row>,
    /// Samples of `params.parquet` absent from the simulation (failed runs).
    pub absent: usize,
}

/// Both passes and the combination: the indices `system` defines of every sample of `files`
/// (`params`: [`read_params`]), with `cfg` for `system` ([`IndexConfig::of_system`]: from its
/// `indices_from` on).
pub fn compute_all(
    system: &System,
    params: &BTreeMap<i64, SampleInfo>,
    files: &[PathBuf],
    cfg: &IndexConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Computed> {
    if files.is_empty() {
        return Err(dataset(
            Path::new("dataset"),
            "no simulation.parquet given".into(),
        ));
    }
    let cfg = &cfg.of_system(system);
    let set = IndexSet::of(system);
    check_columns(files, &needed_columns(&set))?;
    let pass = record_pass(files, system, &set, params, cfg, progress)?;
    if pass.is_empty() {
        return Err(dataset(
            &files[0],
            format!("no simulated sample in {} file(s)", files.len()),
        ));
    }
    let extremes = match &set.railway {
        Some(r) => {
            let windows: Vec<(i64, f64)> = pass.iter().map(|(id, s)| (*id, s.t_start)).collect();
            let file_of = |id: i64| {
                pass.get(&id)
                    .map_or_else(|| files[0].clone(), |s| files[s.file].clone())
            };
            Some(aggregate(files, r, &windows, &file_of)?)
        }
        None => None,
    };
    let mut rows = Vec::with_capacity(pass.len());
    for (id, s) in &pass {
        let path = &files[s.file];
        let info = params[id].clone();
        let mut values = Vec::new();
        let mut railway = None;
        // The three come together: the binding makes the set's railway columns, from which
        // the record pass takes the car body and the aggregation the rest.
        if let (Some(aggs), Some(binding), Some(car)) = (&extremes, &system.railway, &s.car_body) {
            let ext = aggs
                .get(id)
                .ok_or_else(|| dataset(path, format!("sample {id}: no rows in the aggregation")))?;
            if ext.n != s.n {
                return Err(dataset(
                    path,
                    format!(
                        "sample {id}: {} window rows aggregated, {} read",
                        ext.n, s.n
                    ),
                ));
            }
            let agg = Aggregates {
                n: s.n,
                p_max: ext.p_max,
                p_min: ext.p_min,
                car_body_abs_max: car.abs_max,
                car_body_sum_sq: car.sum_sq,
                bogie_abs_max: ext.bogie_abs_max,
                z_r_max: ext.z_r_max,
            };
            let w = binding.static_wheel_load.eval(&info.values);
            let ix = Indices::from_parts(&agg, car.wz, w, s.dt);
            values.extend(ix.values());
            railway = Some(ix);
        }
        if let Some(l) = &s.lateral {
            values.extend_from_slice(l);
        }
        values.extend_from_slice(&s.simple);
        let failed = set.failed(system, &values, railway.as_ref(), cfg);
        rows.push(Row {
            id: *id,
            window_s: railway.map_or(s.n as f64 * s.dt, |ix| ix.window_s),
            info,
            values,
            railway,
            failed,
        });
    }
    Ok(Computed {
        system: system.name.clone(),
        columns: set.columns(system),
        railway: set.railway.is_some(),
        absent: params.len().saturating_sub(rows.len()),
        rows,
    })
}

#[cfg(test)]
mod tests;
