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

use pino_data::{schema, Column, Table};
use pino_indices::{Aggregates, IndexConfig, Indices, INDEX_COLUMNS};
use polars::prelude::{
    col, len, DataFrame, DataType, Engine, Expr, IntoLazy, LazyFrame, NamedFrom, PlRefPath,
    ScanArgsParquet, Series,
};
use rayon::prelude::*;
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

/// What the spectral pass found for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spectral {
    /// Index of its simulation file.
    pub file: usize,
    /// Points of its evaluation window.
    pub n: usize,
    /// Time step (s).
    pub dt: f64,
    /// Time of the first point of the window (s).
    pub t_start: f64,
    /// Sperling `W_z` at the car body's centre, front and rear.
    pub wz: [f64; 3],
    /// `max_t |a|` of the car body at centre, front and rear (m/s^2).
    pub car_abs_max: [f64; 3],
    /// `sum_t a^2` of the same (summed in time order: deterministic).
    pub car_sum_sq: [f64; 3],
}

/// One sample's rows of the spectral columns.
struct Rows {
    id: i64,
    t: Vec<f64>,
    z: Vec<f64>,
    b: Vec<f64>,
}

fn spectral_of(
    r: &Rows,
    l_c: f64,
    cfg: &IndexConfig,
    path: &Path,
    file: usize,
) -> Result<Spectral> {
    let wrap = |source| Error::Index {
        path: path.to_owned(),
        sample: r.id,
        source,
    };
    let n = r.t.len();
    let first = cfg.first_index(n);
    if n < first + 2 {
        return Err(wrap(pino_indices::Error::TooShort {
            what: format!("record of {n} rows, window from row {first}"),
            found: n.saturating_sub(first),
            needed: 2,
        }));
    }
    let dt = r.t[1] - r.t[0];
    let span = r.t[n - 1] - r.t[0];
    if !(dt > 0.0 && (span - (n - 1) as f64 * dt).abs() <= 1e-6 * span) {
        return Err(dataset(
            path,
            format!(
                "sample {}: column `t` is not a uniform grid ({n} rows from {} to {} s, first step {dt} s)",
                r.id,
                r.t[0],
                r.t[n - 1]
            ),
        ));
    }
    for (name, s) in [
        (pino_indices::columns::Z_C_A, &r.z),
        (pino_indices::columns::BETA_C_A, &r.b),
    ] {
        if let Some((row, &value)) = s[first..].iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(wrap(pino_indices::Error::NotFinite {
                column: name.to_owned(),
                row,
                value,
            }));
        }
    }
    let car = pino_indices::car_body_signals(&r.z[first..], &r.b[first..], l_c);
    let (car_abs_max, car_sum_sq) = pino_indices::car_body_folds(&car);
    let mut wz = [0.0; 3];
    for (w, a) in wz.iter_mut().zip(&car) {
        *w = pino_indices::sperling::sperling_wz(a, dt, &cfg.sperling).map_err(wrap)?;
    }
    Ok(Spectral {
        file,
        n: n - first,
        dt,
        t_start: r.t[first],
        wz,
        car_abs_max,
        car_sum_sq,
    })
}

/// Pass 1: every sample's window and Sperling indices, streamed file by file in groups of
/// whole samples (memory: one group plus one batch), groups computed in parallel. Samples
/// must be in `params`, their rows contiguous, and each in one file only.
pub fn spectral_pass(
    files: &[PathBuf],
    params: &BTreeMap<i64, SampleInfo>,
    cfg: &IndexConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<BTreeMap<i64, Spectral>> {
    let cols = [
        schema::SAMPLE_ID,
        schema::TIME,
        pino_indices::columns::Z_C_A,
        pino_indices::columns::BETA_C_A,
    ];
    let group = 32 * rayon::current_num_threads().max(1);
    let mut out: BTreeMap<i64, Spectral> = BTreeMap::new();
    for (fi, path) in files.iter().enumerate() {
        let mut pending: Vec<Rows> = Vec::new();
        let mut current: Option<Rows> = None;
        let mut failure: Option<Error> = None;
        let flush = |pending: &mut Vec<Rows>, out: &mut BTreeMap<i64, Spectral>| -> Result<()> {
            let done: Vec<Result<(i64, Spectral)>> = pending
                .par_iter()
                .map(|r| {
                    let info = params.get(&r.id).ok_or_else(|| {
                        dataset(
                            path,
                            format!(
                                "sample {} is not in params.parquet (inputs from different runs?)",
                                r.id
                            ),
                        )
                    })?;
                    let l_c = vtcd::params::SampleParams::from_array(info.params).l_c;
                    let s = spectral_of(r, l_c, cfg, path, fi)?;
                    progress(1);
                    Ok((r.id, s))
                })
                .collect();
            pending.clear();
            for d in done {
                let (id, s) = d?;
                if let Some(prev) = out.insert(id, s) {
                    let msg = if prev.file == fi {
                        format!("rows of sample {id} are not contiguous: expected rows sorted by sample_id, t")
                    } else {
                        format!("sample {id} is also in {}", files[prev.file].display())
                    };
                    return Err(dataset(path, msg));
                }
            }
            Ok(())
        };
        let streamed = pino_data::for_each_batch(path, Some(&cols[..]), |t| {
            let ids = t.i64(schema::SAMPLE_ID)?;
            let (tt, z, b) = (
                t.f64(schema::TIME)?,
                t.f64(pino_indices::columns::Z_C_A)?,
                t.f64(pino_indices::columns::BETA_C_A)?,
            );
            let mut lo = 0;
            while lo < ids.len() {
                let id = ids[lo];
                let hi = (lo..ids.len()).find(|&r| ids[r] != id).unwrap_or(ids.len());
                if current.as_ref().is_some_and(|c| c.id != id) {
                    pending.push(current.take().expect("checked"));
                    if pending.len() >= group {
                        if let Err(e) = flush(&mut pending, &mut out) {
                            failure = Some(e);
                            return Err(pino_data::Error::Parquet {
                                path: path.clone(),
                                message: "stopped".into(),
                            });
                        }
                    }
                }
                let r = current.get_or_insert_with(|| Rows {
                    id,
                    t: Vec::new(),
                    z: Vec::new(),
                    b: Vec::new(),
                });
                r.t.extend_from_slice(&tt[lo..hi]);
                r.z.extend_from_slice(&z[lo..hi]);
                r.b.extend_from_slice(&b[lo..hi]);
                lo = hi;
            }
            Ok(())
        });
        if let Some(e) = failure {
            return Err(e);
        }
        streamed?;
        pending.extend(current.take());
        flush(&mut pending, &mut out)?;
    }
    Ok(out)
}

/// Name of the aggregate column of signal `c` and statistic `stat`.
fn agg_name(c: &str, stat: &str) -> String {
    format!("{c}__{stat}")
}

/// What the polars pass computes per sample: the extremes of the forces, bogie accelerations
/// and rail displacements over the window (order-independent, so the parallel streaming
/// engine gives the same bits on every run).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extremes {
    /// Rows in the window.
    pub n: usize,
    /// `max_t P_i` (N).
    pub p_max: [f64; 4],
    /// `min_t P_i` (N).
    pub p_min: [f64; 4],
    /// `max_t |Z_t1''|`, `max_t |Z_t2''|` (m/s^2).
    pub bogie_abs_max: [f64; 2],
    /// `max_t Z_ri` (m).
    pub z_r_max: [f64; 4],
}

/// Pass 2: the [`Extremes`] of every sample in `windows` (`(sample_id, t_start)`) over its
/// rows with `t >= t_start`, by one lazy polars query over all `files` (joined with the
/// windows, filtered, grouped by `sample_id`) on the streaming engine. A non-finite signal is
/// reported by column and sample (`file_of` names its file). The car-body aggregates come
/// from pass 1, where the time series are at hand and sums run in time order.
pub fn aggregate(
    files: &[PathBuf],
    windows: &[(i64, f64)],
    file_of: &dyn Fn(i64) -> PathBuf,
) -> Result<BTreeMap<i64, Extremes>> {
    let first = files.first().cloned().unwrap_or_default();
    let pe = |e: polars::prelude::PolarsError| polars_err(&first, e);
    let paths = files
        .iter()
        .map(|f| pl_path(f))
        .collect::<Result<Vec<_>>>()?;
    let keys = DataFrame::new_infer_height(vec![
        Series::new(
            schema::SAMPLE_ID.into(),
            windows.iter().map(|w| w.0).collect::<Vec<i64>>(),
        )
        .into(),
        Series::new(
            "t_start".into(),
            windows.iter().map(|w| w.1).collect::<Vec<f64>>(),
        )
        .into(),
    ])
    .map_err(pe)?;
    let scan =
        LazyFrame::scan_parquet_files(paths.into_iter().collect(), ScanArgsParquet::default())
            .map_err(pe)?;
    let signals: Vec<&str> = needed_columns()[2..].to_vec();
    let mut aggs: Vec<Expr> = vec![len().cast(DataType::Int64).alias("n")];
    for c in &signals {
        // The sum of every input signal: NaN or infinite exactly when one value is.
        aggs.push(col(*c).sum().alias(agg_name(c, "sum")));
    }
    for c in pino_indices::columns::P
        .iter()
        .chain(&pino_indices::columns::Z_R)
        .chain(&pino_indices::columns::Z_T_A)
    {
        aggs.push(col(*c).max().alias(agg_name(c, "max")));
    }
    // max |x| = max(max x, -min x): no `abs` kernel needed.
    for c in pino_indices::columns::P
        .iter()
        .chain(&pino_indices::columns::Z_T_A)
    {
        aggs.push(col(*c).min().alias(agg_name(c, "min")));
    }
    let mut select: Vec<Expr> = vec![col(schema::SAMPLE_ID), col(schema::TIME)];
    select.extend(signals.iter().map(|c| col(*c)));
    let df = scan
        .select(select)
        .inner_join(keys.lazy(), col(schema::SAMPLE_ID), col(schema::SAMPLE_ID))
        .filter(col(schema::TIME).gt_eq(col("t_start")))
        .group_by([col(schema::SAMPLE_ID)])
        .agg(aggs)
        .collect_with_engine(Engine::Streaming)
        .map_err(pe)?
        // A plain query has one result (several only with several sinks).
        .unwrap_single();
    let f64s = |name: &str| -> Result<Vec<f64>> {
        let c = df.column(name).map_err(pe)?;
        let ca = c.as_materialized_series().f64().map_err(pe)?;
        Ok(ca.iter().map(|v| v.unwrap_or(f64::NAN)).collect())
    };
    let ids: Vec<i64> = {
        let c = df.column(schema::SAMPLE_ID).map_err(pe)?;
        let ca = c.as_materialized_series().i64().map_err(pe)?;
        ca.iter().map(|v| v.unwrap_or(-1)).collect()
    };
    let ns: Vec<i64> = {
        let c = df.column("n").map_err(pe)?;
        let ca = c.as_materialized_series().i64().map_err(pe)?;
        ca.iter().map(|v| v.unwrap_or(0)).collect()
    };
    for c in &signals {
        let sums = f64s(&agg_name(c, "sum"))?;
        if let Some(k) = sums.iter().position(|s| !s.is_finite()) {
            return Err(Error::Index {
                path: file_of(ids[k]),
                sample: ids[k],
                source: pino_indices::Error::NotFinite {
                    column: (*c).to_owned(),
                    row: 0,
                    value: sums[k],
                },
            });
        }
    }
    let get = |c: &str, stat: &str| f64s(&agg_name(c, stat));
    let all = |cols: &[&str], stat: &str| -> Result<Vec<Vec<f64>>> {
        cols.iter().map(|c| get(c, stat)).collect()
    };
    let p_max = all(&pino_indices::columns::P, "max")?;
    let p_min = all(&pino_indices::columns::P, "min")?;
    let zr_max = all(&pino_indices::columns::Z_R, "max")?;
    let t_max = all(&pino_indices::columns::Z_T_A, "max")?;
    let t_min = all(&pino_indices::columns::Z_T_A, "min")?;
    let mut out = BTreeMap::new();
    for (k, &id) in ids.iter().enumerate() {
        out.insert(
            id,
            Extremes {
                n: ns[k] as usize,
                p_max: std::array::from_fn(|i| p_max[i][k]),
                p_min: std::array::from_fn(|i| p_min[i][k]),
                bogie_abs_max: std::array::from_fn(|i| t_max[i][k].max(-t_min[i][k])),
                z_r_max: std::array::from_fn(|i| zr_max[i][k]),
            },
        );
    }
    Ok(out)
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

/// The output table: `sample_id`, `split`, the 14 parameters, the 14 indices, `window_s`,
/// `pass` (1/0), `failed` (comma-separated limit names).
pub fn to_table(rows: &[Row]) -> pino_data::Result<Table> {
    let mut t = Table::default();
    t.push(
        schema::SAMPLE_ID,
        Column::I64(rows.iter().map(|r| r.id).collect()),
    )?;
    t.push(
        schema::SPLIT,
        Column::Str(rows.iter().map(|r| r.info.split.clone()).collect()),
    )?;
    for (j, name) in schema::PARAMETERS.iter().enumerate() {
        t.push(
            name,
            Column::F64(rows.iter().map(|r| r.info.params[j]).collect()),
        )?;
    }
    for (k, c) in INDEX_COLUMNS.iter().enumerate() {
        t.push(
            c.name,
            Column::F64(rows.iter().map(|r| r.indices.values()[k]).collect()),
        )?;
    }
    t.push(
        pino_indices::WINDOW_COLUMN,
        Column::F64(rows.iter().map(|r| r.indices.window_s).collect()),
    )?;
    t.push(
        pino_indices::PASS_COLUMN,
        Column::I64(rows.iter().map(|r| r.failed.is_empty() as i64).collect()),
    )?;
    t.push(
        pino_indices::FAILED_COLUMN,
        Column::Str(rows.iter().map(|r| r.failed.join(",")).collect()),
    )?;
    Ok(t)
}

/// The settings and column catalogue as JSON text (the `indices.json` beside the table).
pub fn describe_json(cfg: &IndexConfig) -> String {
    let params: serde_json::Map<String, serde_json::Value> = cfg
        .describe()
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v.into()))
        .collect();
    let mut columns: Vec<serde_json::Value> = INDEX_COLUMNS
        .iter()
        .map(|c| serde_json::json!({"name": c.name, "unit": c.unit, "definition": c.definition}))
        .collect();
    for (name, unit, definition) in [
        (
            pino_indices::WINDOW_COLUMN,
            "s",
            "length of the evaluation window",
        ),
        (
            pino_indices::PASS_COLUMN,
            "-",
            "1 when no limit is exceeded, else 0",
        ),
        (
            pino_indices::FAILED_COLUMN,
            "-",
            "the limits exceeded, comma-separated",
        ),
    ] {
        columns.push(serde_json::json!({"name": name, "unit": unit, "definition": definition}));
    }
    let doc = serde_json::json!({"parameters": params, "columns": columns});
    serde_json::to_string_pretty(&doc).expect("plain JSON values") + "\n"
}

/// Writes `indices.parquet` and `indices.json` into `dir` (atomically, deterministic bytes).
pub fn write_outputs(dir: &Path, rows: &[Row], cfg: &IndexConfig) -> Result<()> {
    pino_data::write_parquet(&dir.join("indices.parquet"), &to_table(rows)?)?;
    let path = dir.join("indices.json");
    atomic_write(&path, describe_json(cfg).as_bytes())
}

fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_file::write_atomic(path, bytes).map_err(|e| {
        Error::Data(pino_data::Error::Io {
            path: e.path,
            source: e.source,
        })
    })
}

#[cfg(test)]
mod tests;
