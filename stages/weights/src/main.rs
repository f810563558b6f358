//! Stage `weights`: the ODE magnitude weights `phi_ki = max_t |R_i|` (`vtcd::weights`) of
//! every training sample, written as `weights.parquet`: `sample_id` (i64), `phi_1..phi_10`
//! (N or N m, equation order of the vehicle DOFs), sorted by sample id.
//!
//! Inputs: `params` (`params.parquet`: split and the 14 parameters), `dataset` (the
//! `simulation.parquet` of every simulate shard, rows sorted by sample then time). Params:
//! `seed`, `noise_ratio`, `gravity`, `wheel_radius`, `window_start_fraction`. Shards are read
//! one at a time (memory: one shard's columns); samples are weighted in parallel, each from its
//! own noise stream, so the result does not depend on threads or shard layout. Training samples
//! absent from the dataset (failed simulations) are counted in the summary. `gravity` and
//! `wheel_radius` must equal the dataset's own (`provenance.parquet`), else nothing runs.

mod dataset;

use anyhow::{bail, Context, Result};
use pino_data::{schema, write_parquet, Column, Table};
use rayon::prelude::*;
use std::collections::BTreeMap;
use vtcd::weights::{magnitude_weights, WeightParams};

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    let raw: WeightParams = ctx.params()?;
    let cfg = raw
        .validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    pino_data::provenance::check_constants(
        ctx.input_dirs("dataset")?,
        &[("gravity", raw.gravity), ("wheel_radius", raw.wheel_radius)],
    )
    .with_context(|| format!("stage `{}`: input `dataset`", ctx.stage))?;
    let params = dataset::read_params(&ctx.input_files("params", "params.parquet")?)?;
    let files = ctx.input_files("dataset", "simulation.parquet")?;
    if files.is_empty() {
        bail!(
            "input `dataset` has no simulation.parquet (in {:?})",
            ctx.input_dirs("dataset")?
        );
    }
    let n_train = params.values().filter(|(train, _)| *train).count();
    let progress = ctx.progress(n_train as u64);
    let mut phi: BTreeMap<i64, [f64; 10]> = BTreeMap::new();
    for file in &files {
        let shard = dataset::ShardData::read(file)?;
        if let Some((id, _)) = shard.runs.iter().find(|(id, _)| !params.contains_key(id)) {
            bail!(
                "{}: sample {id} is not in params.parquet (inputs from different runs?)",
                file.display()
            );
        }
        let results: Vec<(i64, vtcd::Result<[f64; 10]>)> = shard
            .runs
            .par_iter()
            .filter(|(id, _)| params[id].0)
            .map(|(id, rows)| {
                let out = magnitude_weights(&cfg, &params[id].1, *id as u64, &shard.signals(rows));
                progress.inc(1);
                (*id, out)
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
        "phi for {} training samples (r = {}); {} training samples absent from the dataset",
        phi.len(),
        raw.noise_ratio,
        n_train - phi.len()
    ))
}

fn main() {
    stage_kit::finish(run())
}
