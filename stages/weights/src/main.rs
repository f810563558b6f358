//! Stage `weights`: the ODE magnitude weights `phi_ki = max_t |R_i|` (`vtcd::weights`) of
//! every training sample, written as `weights.parquet`: `sample_id` (i64), `phi_1..phi_10`
//! (N or N m, equation order of the vehicle DOFs), sorted by sample id.
//!
//! Inputs: `params` (`params.parquet`: split and the 14 parameters), `dataset` (the
//! `simulation.parquet` of every simulate shard, rows sorted by sample then time). Params:
//! `seed`, `noise_ratio`, `gravity`, `wheel_radius`, `window_start_fraction`. Shards are
//! streamed batch by batch (memory: one group of samples, not one shard's columns); samples
//! are weighted in parallel, each from its own noise stream, so the result does not depend on
//! threads, grouping or shard layout. Training samples
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
    pino_data::metadata::set_stage_origin(&ctx)?;
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
    // Samples in groups: weighted in parallel within a group, one group in memory.
    let group = 16 * rayon::current_num_threads().max(1);
    for file in &files {
        let keep = |id: i64| -> Result<bool> {
            match params.get(&id) {
                Some((train, _)) => Ok(*train),
                None => bail!("sample {id} is not in params.parquet (inputs from different runs?)"),
            }
        };
        dataset::for_each_group(file, group, &keep, &mut |samples| {
            let results: Vec<(i64, vtcd::Result<[f64; 10]>)> = samples
                .par_iter()
                .map(|s| {
                    let out = magnitude_weights(&cfg, &params[&s.id].1, s.id as u64, &s.signals());
                    progress.inc(1);
                    (s.id, out)
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
            Ok(())
        })?;
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
