//! Stage `weights`: the ODE magnitude weights `phi_ki = max_t |R_i|` (`vtcd::weights`) of
//! every training sample, written as `weights.parquet`: `sample_id` (i64), `phi_1..phi_10`
//! (N or N m, equation order of the vehicle DOFs), sorted by sample id.
//!
//! Inputs: `params` (`params.parquet`: split and the 14 parameters), `dataset` (the
//! `simulation.parquet` of every simulate shard, rows sorted by sample then time). Params:
//! `seed`, `noise_ratio`, `gravity`, `wheel_radius`, `window_start_fraction`. Shards are read
//! one at a time (memory: one shard's columns); samples are weighted in parallel, each from its
//! own noise stream, so the result does not depend on threads or shard layout. Training samples
//! absent from the dataset (failed simulations) are counted in the summary.

use anyhow::{bail, Context, Result};
use pino_data::{read_parquet, read_parquet_files, schema, write_parquet, Column, Table};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::ops::Range;
use vtcd::params::SampleParams;
use vtcd::weights::{magnitude_weights, SampleSignals, WeightParams};

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    let raw: WeightParams = ctx.params()?;
    let cfg = raw
        .validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;

    // Training samples and their parameters.
    let params_files = ctx.input_files("params", "params.parquet")?;
    let mut cols = vec![schema::SAMPLE_ID, schema::SPLIT];
    cols.extend(schema::PARAMETERS);
    let table = read_parquet_files(&params_files, Some(&cols))?;
    let values: Vec<&[f64]> = schema::PARAMETERS
        .iter()
        .map(|c| table.f64(c))
        .collect::<Result<_, _>>()?;
    let mut train: BTreeMap<i64, SampleParams> = BTreeMap::new();
    for (row, (id, split)) in table
        .i64(schema::SAMPLE_ID)?
        .iter()
        .zip(table.str(schema::SPLIT)?)
        .enumerate()
    {
        if split == schema::SPLIT_TRAIN {
            train.insert(
                *id,
                SampleParams::from_array(std::array::from_fn(|j| values[j][row])),
            );
        }
    }

    let files = ctx.input_files("dataset", "simulation.parquet")?;
    if files.is_empty() {
        bail!(
            "input `dataset` has no simulation.parquet (in {:?})",
            ctx.input_dirs("dataset")?
        );
    }
    let dofs = schema::VEHICLE_DOFS;
    let names: Vec<String> = std::iter::once(schema::SAMPLE_ID.to_owned())
        .chain(dofs.iter().map(|s| s.to_string()))
        .chain(schema::RAIL_UNDER_WHEEL.iter().map(|s| s.to_string()))
        .chain(dofs.iter().map(|s| schema::velocity(s)))
        .chain(dofs.iter().map(|s| schema::acceleration(s)))
        .chain(schema::ETA_UNDER_WHEEL.iter().map(|s| s.to_string()))
        .collect();
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();

    let progress = ctx.progress(train.len() as u64);
    let mut phi: BTreeMap<i64, [f64; 10]> = BTreeMap::new();
    for file in &files {
        let t = read_parquet(file, Some(&refs))?;
        let f: Vec<&[f64]> = refs[1..]
            .iter()
            .map(|c| t.f64(c))
            .collect::<Result<_, _>>()?;
        let runs =
            sample_runs(t.i64(schema::SAMPLE_ID)?).with_context(|| file.display().to_string())?;
        let results: Vec<(i64, vtcd::Result<[f64; 10]>)> = runs
            .par_iter()
            .filter_map(|(id, r)| train.get(id).map(|p| (*id, r.clone(), p)))
            .map(|(id, r, p)| {
                let s = SampleSignals {
                    z: std::array::from_fn(|i| &f[i][r.clone()]),
                    z_r: std::array::from_fn(|j| &f[10 + j][r.clone()]),
                    v: std::array::from_fn(|i| &f[14 + i][r.clone()]),
                    a: std::array::from_fn(|i| &f[24 + i][r.clone()]),
                    eta: std::array::from_fn(|j| &f[34 + j][r.clone()]),
                };
                let out = magnitude_weights(&cfg, p, id as u64, &s);
                progress.inc(1);
                (id, out)
            })
            .collect();
        for (id, out) in results {
            let w = out.with_context(|| format!("{}: sample {id}", file.display()))?;
            if phi.insert(id, w).is_some() {
                bail!(
                    "sample {id} appears in more than one dataset file ({})",
                    file.display()
                );
            }
        }
    }

    let missing = train.len() - phi.len();
    let mut table = Table::default();
    table.push(
        schema::SAMPLE_ID,
        Column::I64(phi.keys().copied().collect()),
    )?;
    for (i, name) in schema::phi_columns().iter().enumerate() {
        table.push(name, Column::F64(phi.values().map(|w| w[i]).collect()))?;
    }
    let path = ctx.output_path("weights.parquet");
    write_parquet(&path, &table).with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "phi for {} training samples (r = {}); {missing} training samples absent from the dataset",
        phi.len(),
        raw.noise_ratio
    ))
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

fn main() {
    match run() {
        Ok(summary) => stage_kit::summary(&summary),
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::exit(1);
        }
    }
}
