//! Pass 2 of the scan (railway binding only): the extremes of every sample's contact forces,
//! bogie accelerations and rail displacements, by one lazy polars query on the streaming
//! engine.
//!
//! The columns are the ones the description binds ([`RailwayColumns`]). The query scans every
//! shard, joins each sample's window start, keeps the window's rows and
//! groups by `sample_id`. Maxima and minima are exact whatever the order in which the engine
//! meets the rows, so the result is deterministic on every core count; a sum per signal checks
//! finiteness (NaN or infinite exactly when one value is), and a non-finite signal is then
//! located to its row by a plain read of the one file that holds it.

use crate::{pl_path, polars_err, Error, Result};
use pino_data::schema;
use pino_indices::RailwayColumns;
use polars::prelude::{
    col, len, DataFrame, DataType, Engine, Expr, IntoLazy, LazyFrame, NamedFrom, ScanArgsParquet,
    Series,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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
/// rows with `t >= t_start`, of the columns of `railway`, by one lazy polars query over all
/// `files` (joined with the windows, filtered, grouped by `sample_id`) on the streaming
/// engine. A non-finite signal is
/// reported by column and sample (`file_of` names its file). The car-body aggregates come
/// from pass 1, where the time series are at hand and sums run in time order.
pub fn aggregate(
    files: &[PathBuf],
    railway: &RailwayColumns,
    windows: &[(i64, f64)],
    file_of: &dyn Fn(i64) -> PathBuf,
) -> Result<BTreeMap<i64, Extremes>> {
    let per_sample = Aggregated::query(files, railway, windows)?;
    let ids = per_sample.i64s(schema::SAMPLE_ID, -1)?;
    let ns = per_sample.i64s("n", 0)?;
    per_sample.check_finite(railway, &ids, windows, file_of)?;
    per_sample.extremes(railway, &ids, &ns)
}

/// The result of the query: one row per sample, its `sample_id`, its window's row count `n`
/// and the aggregates named by [`agg_name`].
struct Aggregated {
    df: DataFrame,
    /// The first scanned file, which a polars error names.
    first: PathBuf,
}

impl Aggregated {
    /// Scans `files` (the columns of `railway`), joins each sample's window start from
    /// `windows`, keeps the window's rows and aggregates them by `sample_id` on the streaming
    /// engine.
    fn query(files: &[PathBuf], railway: &RailwayColumns, windows: &[(i64, f64)]) -> Result<Self> {
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
        let signals: Vec<&str> = railway.all();
        let mut select: Vec<Expr> = vec![col(schema::SAMPLE_ID), col(schema::TIME)];
        select.extend(signals.iter().map(|c| col(*c)));
        let df = scan
            .select(select)
            .inner_join(keys.lazy(), col(schema::SAMPLE_ID), col(schema::SAMPLE_ID))
            .filter(col(schema::TIME).gt_eq(col("t_start")))
            .group_by([col(schema::SAMPLE_ID)])
            .agg(aggregations(railway))
            .collect_with_engine(Engine::Streaming)
            .map_err(pe)?
            // A plain query has one result (several only with several sinks).
            .unwrap_single();
        Ok(Self { df, first })
    }

    fn polars_err(&self, e: polars::prelude::PolarsError) -> Error {
        polars_err(&self.first, e)
    }

    /// Column `name` (f64), a null read as NaN.
    fn f64s(&self, name: &str) -> Result<Vec<f64>> {
        let c = self.df.column(name).map_err(|e| self.polars_err(e))?;
        let ca = c
            .as_materialized_series()
            .f64()
            .map_err(|e| self.polars_err(e))?;
        Ok(ca.iter().map(|v| v.unwrap_or(f64::NAN)).collect())
    }

    /// Column `name` (i64), a null read as `null`.
    fn i64s(&self, name: &str, null: i64) -> Result<Vec<i64>> {
        let c = self.df.column(name).map_err(|e| self.polars_err(e))?;
        let ca = c
            .as_materialized_series()
            .i64()
            .map_err(|e| self.polars_err(e))?;
        Ok(ca.iter().map(|v| v.unwrap_or(null)).collect())
    }

    /// Refuses the first signal whose window sum is not finite, located to its row by a plain
    /// read of the file that holds the sample (`file_of`); `ids`: the rows' samples.
    fn check_finite(
        &self,
        railway: &RailwayColumns,
        ids: &[i64],
        windows: &[(i64, f64)],
        file_of: &dyn Fn(i64) -> PathBuf,
    ) -> Result<()> {
        for c in &railway.all() {
            let sums = self.f64s(&agg_name(c, "sum"))?;
            let Some(k) = sums.iter().position(|s| !s.is_finite()) else {
                continue;
            };
            let (id, path) = (ids[k], file_of(ids[k]));
            let t_start = windows
                .iter()
                .find(|w| w.0 == id)
                .map_or(f64::NEG_INFINITY, |w| w.1);
            let values = window_values(&path, id, t_start, c)?;
            pino_indices::check_finite_signal(c, &values).map_err(|source| Error::Index {
                path: path.clone(),
                sample: id,
                source,
            })?;
            return Err(crate::dataset(
                &path,
                format!(
                    "sample {id}: column `{c}` sums to {} over the window, yet a second read \
                     finds no value that is not finite (did the file change during the run?)",
                    sums[k]
                ),
            ));
        }
        Ok(())
    }

    /// The [`Extremes`] of every row (`ids`: its sample, `ns`: its window's row count).
    fn extremes(
        &self,
        railway: &RailwayColumns,
        ids: &[i64],
        ns: &[i64],
    ) -> Result<BTreeMap<i64, Extremes>> {
        let (p, z_r, z_t_a) = railway_names(railway);
        let all = |cols: &[&str], stat: &str| -> Result<Vec<Vec<f64>>> {
            cols.iter().map(|c| self.f64s(&agg_name(c, stat))).collect()
        };
        let p_max = all(&p, "max")?;
        let p_min = all(&p, "min")?;
        let zr_max = all(&z_r, "max")?;
        let t_max = all(&z_t_a, "max")?;
        let t_min = all(&z_t_a, "min")?;
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
}

/// The contact forces', rail displacements' and bogie accelerations' columns of `railway`.
fn railway_names(railway: &RailwayColumns) -> ([&str; 4], [&str; 4], [&str; 2]) {
    (
        railway.p.each_ref().map(String::as_str),
        railway.z_r.each_ref().map(String::as_str),
        railway.z_t_a.each_ref().map(String::as_str),
    )
}

/// The per-sample aggregates of the query: the row count `n`, every signal's sum, the maxima
/// of the forces, rail displacements and bogie accelerations and the minima of the forces and
/// bogie accelerations.
fn aggregations(railway: &RailwayColumns) -> Vec<Expr> {
    let (p, z_r, z_t_a) = railway_names(railway);
    let mut aggs: Vec<Expr> = vec![len().cast(DataType::Int64).alias("n")];
    for c in &railway.all() {
        // The sum of every input signal: NaN or infinite exactly when one value is.
        aggs.push(col(*c).sum().alias(agg_name(c, "sum")));
    }
    for c in p.iter().chain(&z_r).chain(&z_t_a) {
        aggs.push(col(*c).max().alias(agg_name(c, "max")));
    }
    // max |x| = max(max x, -min x): no `abs` kernel needed.
    for c in p.iter().chain(&z_t_a) {
        aggs.push(col(*c).min().alias(agg_name(c, "min")));
    }
    aggs
}

/// The values of `column` in sample `id`'s window (its rows with `t >= t_start`) of `path`,
/// in file order. A plain streaming read of one file, on the error path only: the query's
/// sums tell that a signal is not finite, not where.
fn window_values(path: &Path, id: i64, t_start: f64, column: &str) -> Result<Vec<f64>> {
    let mut out = Vec::new();
    let cols = [schema::SAMPLE_ID, schema::TIME, column];
    pino_data::for_each_batch(path, Some(&cols[..]), |t| {
        let (ids, times, values) = (
            t.i64(schema::SAMPLE_ID)?,
            t.f64(schema::TIME)?,
            t.f64(column)?,
        );
        out.extend(
            (0..ids.len())
                .filter(|&k| ids[k] == id && times[k] >= t_start)
                .map(|k| values[k]),
        );
        Ok(())
    })?;
    Ok(out)
}
