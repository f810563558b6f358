//! Reading the weights stage's inputs: training parameters from `params.parquet` and, per
//! simulate shard, the columns of `simulation.parquet` the ten vehicle residuals need,
//! streamed batch by batch and handed on in groups of whole samples (bounded memory).

use anyhow::{bail, Context, Result};
use pino_data::{read_parquet_files, schema};
use std::collections::{BTreeMap, BTreeSet};
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

/// One sample's columns that the residuals need, in [`SampleSignals`] order: `z` (10),
/// `z_r1..4`, `_v` (10), `_a` (10), `eta_1..4`.
pub struct SampleData {
    /// `sample_id`.
    pub id: i64,
    cols: Vec<Vec<f64>>,
}

impl SampleData {
    /// The signals of this sample.
    pub fn signals(&self) -> SampleSignals<'_> {
        let col = |k: usize| self.cols[k].as_slice();
        SampleSignals {
            z: std::array::from_fn(col),
            z_r: std::array::from_fn(|j| col(10 + j)),
            v: std::array::from_fn(|i| col(14 + i)),
            a: std::array::from_fn(|i| col(24 + i)),
            eta: std::array::from_fn(|j| col(34 + j)),
        }
    }
}

/// The columns read: `sample_id`, then the [`SampleData`] columns.
fn column_names() -> Vec<String> {
    let dofs = schema::VEHICLE_DOFS;
    std::iter::once(schema::SAMPLE_ID.to_owned())
        .chain(dofs.iter().map(|s| s.to_string()))
        .chain(schema::RAIL_UNDER_WHEEL.iter().map(|s| s.to_string()))
        .chain(dofs.iter().map(|s| schema::velocity(s)))
        .chain(dofs.iter().map(|s| schema::acceleration(s)))
        .chain(schema::ETA_UNDER_WHEEL.iter().map(|s| s.to_string()))
        .collect()
}

/// Streams the samples of one simulate shard (batch by batch, with column projection), in
/// file order, in groups of up to `group` samples to `f`; samples for which `keep(id)` is
/// false are dropped as soon as they are read. Memory: one group of samples plus one batch
/// of rows. Rows of one sample must be contiguous.
pub fn for_each_group(
    path: &Path,
    group: usize,
    keep: &dyn Fn(i64) -> Result<bool>,
    f: &mut dyn FnMut(Vec<SampleData>) -> Result<()>,
) -> Result<()> {
    let names = column_names();
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut seen = BTreeSet::new();
    let mut current: Option<SampleData> = None;
    let mut pending: Vec<SampleData> = Vec::new();
    let mut failure: Option<anyhow::Error> = None;
    // Closes the current sample; hands a full group to `f`.
    let mut close = |s: SampleData, pending: &mut Vec<SampleData>, flush: bool| -> Result<()> {
        if !seen.insert(s.id) {
            bail!(
                "rows of sample {} are not contiguous: expected rows sorted by sample_id, t",
                s.id
            );
        }
        if keep(s.id)? {
            pending.push(s);
        }
        if pending.len() >= group || (flush && !pending.is_empty()) {
            f(std::mem::take(pending))?;
        }
        Ok(())
    };
    let streamed = pino_data::for_each_batch(path, Some(&refs), |table| {
        let ids = table.i64(schema::SAMPLE_ID)?;
        let cols: Vec<&[f64]> = names[1..]
            .iter()
            .map(|n| table.f64(n))
            .collect::<pino_data::Result<_>>()?;
        let mut lo = 0;
        while lo < ids.len() {
            let id = ids[lo];
            let hi = (lo..ids.len()).find(|&r| ids[r] != id).unwrap_or(ids.len());
            if current.as_ref().is_some_and(|c| c.id != id) {
                let done = current.take().expect("checked");
                if let Err(e) = close(done, &mut pending, false) {
                    failure = Some(e);
                    return Err(pino_data::Error::Parquet {
                        path: path.to_owned(),
                        message: "stopped".into(),
                    });
                }
            }
            let s = current.get_or_insert_with(|| SampleData {
                id,
                cols: vec![Vec::new(); cols.len()],
            });
            for (dst, src) in s.cols.iter_mut().zip(&cols) {
                dst.extend_from_slice(&src[lo..hi]);
            }
            lo = hi;
        }
        Ok(())
    });
    if let Some(e) = failure {
        return Err(e.context(path.display().to_string()));
    }
    streamed?;
    match current.take() {
        Some(last) => close(last, &mut pending, true),
        None => Ok(()),
    }
    .with_context(|| path.display().to_string())
}
