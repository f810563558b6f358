//! The `indices` stage's engine: the indices of every simulated sample
//! (`docs/indices.md`), in bounded memory on datasets far larger than RAM.
//!
//! Two passes over the `simulation.parquet` shards:
//!
//! 1. [`spectral_pass`] (plain Rust, rayon): streams `sample_id, t, z_c_a, beta_c_a` batch by
//!    batch, one group of whole samples at a time, checks each record (contiguous rows, a
//!    uniform grid, finite values), fixes its evaluation window (the first kept point
//!    `floor(f n)`, [`pino_indices::IndexConfig::first_index`]) and computes everything of the
//!    car body: the Sperling index of the three car-body signals (rustfft), their peaks and
//!    sums of squares (in time order, so the RMS has the same bits on every run).
//! 2. [`aggregate`] (polars): one lazy query over all shards, joined with each sample's window
//!    start, filtered to the window and grouped by `sample_id`: the extremes of the contact
//!    forces, bogie accelerations and rail displacements ([`Extremes`]: maxima and minima, exact
//!    whatever the order, so deterministic on the parallel streaming engine) and a finiteness
//!    check of every signal, on every core, without materialising the dataset.
//!
//! [`pino_indices::Indices::from_parts`] then combines the two with the static wheel load `W`
//! (`vtcd::vehicle::Vehicle`), as `evaluate` and `predict` do from their plain-Rust folds.
//! [`write_outputs`] writes `indices.parquet` (`sample_id`, `split`, the 14 parameters, the 14
//! indices, `window_s`, `pass`, `failed`; sorted by `sample_id`) and `indices.json` (the
//! settings used and every column's unit and definition).

mod aggregate;
mod output;
mod spectral;

pub use aggregate::{aggregate, Extremes};
pub use output::{describe_json, to_table, write_outputs};
pub use spectral::{spectral_pass, Spectral};

use pino_data::schema;
use pino_indices::{Aggregates, IndexConfig, Indices};
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
    /// The 14 parameters (spec order).
    pub params: [f64; 14],
}

/// Reads `params.parquet`: every sample's split and parameters, by id.
pub fn read_params(path: &Path) -> Result<BTreeMap<i64, SampleInfo>> {
    let mut cols = vec![schema::SAMPLE_ID, schema::SPLIT];
    cols.extend(schema::PARAMETERS);
    let t = pino_data::read_parquet(path, Some(&cols))?;
    let values: Vec<&[f64]> = schema::PARAMETERS
        .iter()
        .map(|c| t.f64(c))
        .collect::<pino_data::Result<_>>()?;
    let mut out = BTreeMap::new();
    for (row, (&id, split)) in t
        .i64(schema::SAMPLE_ID)?
        .iter()
        .zip(t.str(schema::SPLIT)?)
        .enumerate()
    {
        let info = SampleInfo {
            split: split.clone(),
            params: std::array::from_fn(|j| values[j][row]),
        };
        if out.insert(id, info).is_some() {
            return Err(dataset(path, format!("sample_id {id} appears twice")));
        }
    }
    Ok(out)
}

/// The columns the indices read from a simulation file: `sample_id`, `t`, then the signals.
pub fn needed_columns() -> Vec<&'static str> {
    let mut c = vec![schema::SAMPLE_ID, schema::TIME];
    c.extend(pino_indices::columns::P);
    c.push(pino_indices::columns::Z_C_A);
    c.push(pino_indices::columns::BETA_C_A);
    c.extend(pino_indices::columns::Z_T_A);
    c.extend(pino_indices::columns::Z_R);
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

/// Checks, from each file's footer, that every [`needed_columns`] is there.
pub fn check_columns(files: &[PathBuf]) -> Result<()> {
    for f in files {
        let mut lf = LazyFrame::scan_parquet(pl_path(f)?, ScanArgsParquet::default())
            .map_err(|e| polars_err(f, e))?;
        let schema = lf.collect_schema().map_err(|e| polars_err(f, e))?;
        let present: Vec<String> = schema.iter_names().map(|n| n.to_string()).collect();
        for c in needed_columns() {
            if !present.iter().any(|p| p == c) {
                return Err(Error::MissingColumn {
                    path: f.clone(),
                    column: c.to_owned(),
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
    /// Its indices.
    pub indices: Indices,
    /// Limits it exceeds (empty: it passes).
    pub failed: Vec<&'static str>,
}

/// Everything the stage computed.
#[derive(Debug, Clone)]
pub struct Computed {
    /// One row per simulated sample, by id.
    pub rows: Vec<Row>,
    /// Samples of `params.parquet` absent from the simulation (failed runs).
    pub absent: usize,
}

/// Both passes and the combination: the indices of every sample of `files`.
pub fn compute_all(
    params_file: &Path,
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
    let params = read_params(params_file)?;
    check_columns(files)?;
    let spectral = spectral_pass(files, &params, cfg, progress)?;
    if spectral.is_empty() {
        return Err(dataset(
            &files[0],
            format!("no simulated sample in {} file(s)", files.len()),
        ));
    }
    let windows: Vec<(i64, f64)> = spectral.iter().map(|(id, s)| (*id, s.t_start)).collect();
    let file_of = |id: i64| {
        spectral
            .get(&id)
            .map_or_else(|| files[0].clone(), |s| files[s.file].clone())
    };
    let aggs = aggregate(files, &windows, &file_of)?;
    let mut rows = Vec::with_capacity(spectral.len());
    for (id, s) in &spectral {
        let path = &files[s.file];
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
            car_body_abs_max: s.car_abs_max,
            car_body_sum_sq: s.car_sum_sq,
            bogie_abs_max: ext.bogie_abs_max,
            z_r_max: ext.z_r_max,
        };
        let info = params[id].clone();
        let w = vtcd::vehicle::Vehicle::new(
            &vtcd::params::SampleParams::from_array(info.params),
            cfg.gravity,
        )
        .w;
        let ix = Indices::from_parts(&agg, s.wz, w, s.dt);
        rows.push(Row {
            id: *id,
            failed: cfg.limits.failed(&ix),
            info,
            indices: ix,
        });
    }
    Ok(Computed {
        absent: params.len().saturating_sub(rows.len()),
        rows,
    })
}

#[cfg(test)]
mod tests;
