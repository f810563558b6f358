//! Reading the weights stage's inputs: training parameters from `params.parquet` and, per
//! simulate shard, the columns of `simulation.parquet` the ten vehicle residuals need, split
//! into per-sample row ranges.

use anyhow::{bail, Context, Result};
use pino_data::{read_parquet, read_parquet_files, schema, Table};
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use vtcd::params::SampleParams;
use vtcd::weights::SampleSignals;

/// Every sample's parameters and whether it is a training sample.
pub fn read_params(files: &[PathBuf]) -> Result<BTreeMap<i64, (bool, SampleParams)>> {
    let mut cols = vec![schema::SAMPLE_ID, schema::SPLIT];
    cols.extend(schema::PARAMETERS);
    let table = read_parquet_files(files, Some(&cols))?;
    let values: Vec<&[f64]> = schema::PARAMETERS
        .iter()
        .map(|c| table.f64(c))
        .collect::<Result<_, _>>()?;
    let ids = table.i64(schema::SAMPLE_ID)?;
    let splits = table.str(schema::SPLIT)?;
    let mut out = BTreeMap::new();
    for (row, (&id, split)) in ids.iter().zip(splits).enumerate() {
        let p = SampleParams::from_array(std::array::from_fn(|j| values[j][row]));
        if out.insert(id, (split == schema::SPLIT_TRAIN, p)).is_some() {
            bail!("params.parquet: sample_id {id} appears twice");
        }
    }
    Ok(out)
}

/// The columns of one simulate shard that the residuals need, in [`SampleSignals`] order.
pub struct ShardData {
    table: Table,
    names: Vec<String>,
    /// `(sample_id, rows)` of each sample, in file order.
    pub runs: Vec<(i64, Range<usize>)>,
}

impl ShardData {
    /// Reads `sample_id`, the ten DOFs, `z_r1..4`, the `_v` and `_a` columns and `eta_1..4`.
    pub fn read(path: &Path) -> Result<Self> {
        let dofs = schema::VEHICLE_DOFS;
        let names: Vec<String> = std::iter::once(schema::SAMPLE_ID.to_owned())
            .chain(dofs.iter().map(|s| s.to_string()))
            .chain(schema::RAIL_UNDER_WHEEL.iter().map(|s| s.to_string()))
            .chain(dofs.iter().map(|s| schema::velocity(s)))
            .chain(dofs.iter().map(|s| schema::acceleration(s)))
            .chain(schema::ETA_UNDER_WHEEL.iter().map(|s| s.to_string()))
            .collect();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let table = read_parquet(path, Some(&refs))?;
        for name in &refs[1..] {
            table.f64(name)?;
        }
        let runs = sample_runs(table.i64(schema::SAMPLE_ID)?)
            .with_context(|| path.display().to_string())?;
        Ok(Self { table, names, runs })
    }

    /// The signals of the rows `r` (one sample).
    pub fn signals(&self, r: &Range<usize>) -> SampleSignals<'_> {
        // Columns were type-checked in `read`.
        let col = |k: usize| &self.table.f64(&self.names[1 + k]).expect("checked f64")[r.clone()];
        SampleSignals {
            z: std::array::from_fn(col),
            z_r: std::array::from_fn(|j| col(10 + j)),
            v: std::array::from_fn(|i| col(14 + i)),
            a: std::array::from_fn(|i| col(24 + i)),
            eta: std::array::from_fn(|j| col(34 + j)),
        }
    }
}

/// Contiguous row ranges of each sample id; an id split over two runs is an error.
fn sample_runs(ids: &[i64]) -> Result<Vec<(i64, Range<usize>)>> {
    let mut runs: Vec<(i64, Range<usize>)> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (row, &id) in ids.iter().enumerate() {
        match runs.last_mut() {
            Some((last, r)) if *last == id => r.end = row + 1,
            _ => {
                if !seen.insert(id) {
                    bail!("rows of sample {id} are not contiguous (row {row}): expected rows sorted by sample_id, t");
                }
                runs.push((id, row..row + 1));
            }
        }
    }
    Ok(runs)
}
