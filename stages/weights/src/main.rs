//! Stage `weights`: the ODE magnitude weights `phi_ki = max_t |R_i|` (`pino_learn::weights`) of
//! every training sample, for each DOF of the system description that has an equation,
//! written as `weights.parquet`: `sample_id` (i64), `phi_<dof>` (N, or N m for a pitch) in DOF
//! order, sorted by sample id.
//!
//! Inputs: `params` (`params.parquet`: split and the sampled parameters), `dataset` (the
//! `simulation.parquet` and `system.json` of every simulate shard). Params: `seed`,
//! `noise_ratio`, `window_start_fraction`. Shards are streamed record by record
//! (`pino_data::records`: memory holds a group of samples); samples are weighted in parallel,
//! each from its own noise stream, so the result does not depend on threads, grouping or
//! shard layout. Training samples absent from the dataset (failed simulations) are counted in
//! the summary. A description without any equation is refused.

use anyhow::{bail, Context, Result};
use pino_data::artifacts::{PARAMS_FILE, PROVENANCE_FILE, SIMULATION_FILE, WEIGHTS_FILE};
use pino_data::records::read_params_of;
use pino_data::{schema, write_parquet, Column, Table};
use pino_learn::layout::Layout;
use pino_learn::weights::{columns, magnitude_weights, WeightConfig};
use rayon::prelude::*;
use std::collections::BTreeMap;

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    ctx.declare_origin()?;
    let cfg: WeightConfig = ctx.params()?;
    cfg.validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    if ctx.is_check() {
        return Ok("parameters valid".into());
    }
    let dirs = ctx.input_dirs("dataset")?.to_vec();
    let (_, system) = pino_data::system::read_record(&dirs)?;
    let layout = Layout::of(&system);
    if layout.equations.is_empty() {
        bail!(
            "stage `{}`: no DOF of `{}` has an equation with its stored outputs (every element acting on a DOF must have both ends among the outputs or the excitations), so there is nothing to weigh",
            ctx.stage,
            system.name
        );
    }
    let params = read_params_of(&ctx.input_files("params", PARAMS_FILE)?, &system)?;
    let by_id: BTreeMap<i64, (bool, _)> = params
        .rows()
        .map(|(id, s, v)| {
            let train = s == pino_learn::data::Split::Train.as_str();
            Ok((id, (train, system.sampled_values(v)?)))
        })
        .collect::<Result<_>>()?;
    let files = ctx.input_files("dataset", SIMULATION_FILE)?;
    if files.is_empty() {
        bail!("input `dataset` has no {SIMULATION_FILE} (in {dirs:?})");
    }
    let provenance = pino_data::provenance::read_provenance(&dirs[0].join(PROVENANCE_FILE))?;
    let dt = provenance
        .get("dt")
        .copied()
        .context("provenance.parquet has no dt")?
        * provenance
            .get("output_every")
            .copied()
            .context("provenance.parquet has no output_every")?;
    let n_train = by_id.values().filter(|(train, _)| *train).count();
    let progress = ctx.progress(n_train as u64);
    let cols = columns(&layout);
    let col_refs: Vec<&str> = cols.iter().map(String::as_str).collect();
    let mut phi: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
    // Samples in groups: weighted in parallel within a group, one group in memory.
    let group = 16 * rayon::current_num_threads().max(1);
    let mut pending: Vec<pino_data::records::Record> = Vec::new();
    let flush = |pending: &mut Vec<pino_data::records::Record>,
                 phi: &mut BTreeMap<i64, Vec<f64>>|
     -> Result<()> {
        let results: Vec<(i64, pino_learn::Result<Vec<f64>>)> = pending
            .par_iter()
            .map(|r| {
                let out = magnitude_weights(
                    &cfg,
                    &system,
                    &layout,
                    &by_id[&r.id].1,
                    r.id as u64,
                    &r.columns,
                    dt,
                );
                progress.inc(1);
                (r.id, out)
            })
            .collect();
        pending.clear();
        for (id, out) in results {
            let w = out.with_context(|| format!("sample {id}"))?;
            if phi.insert(id, w).is_some() {
                bail!("sample {id} appears in more than one dataset file");
            }
        }
        Ok(())
    };
    pino_data::records::for_each_record::<anyhow::Error>(&files, &col_refs, &mut |file, rec| {
        match by_id.get(&rec.id) {
            Some((true, _)) => pending.push(rec),
            Some((false, _)) => {}
            None => bail!(
                "{}: sample {} is not in params.parquet (inputs from different runs?)",
                file.display(),
                rec.id
            ),
        }
        if pending.len() >= group {
            flush(&mut pending, &mut phi)?;
        }
        Ok(())
    })?;
    flush(&mut pending, &mut phi)?;

    let mut table = Table::default().with_units(pino_data::system::units_of(&system)?);
    table.push(
        schema::SAMPLE_ID,
        Column::I64(phi.keys().copied().collect()),
    )?;
    for (i, name) in layout.phi_columns().iter().enumerate() {
        table.push(name, Column::F64(phi.values().map(|w| w[i]).collect()))?;
    }
    let path = ctx.output_path(WEIGHTS_FILE);
    write_parquet(&path, &table).with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "phi of {} equations for {} training samples (r = {}); {} training samples absent from the dataset",
        layout.equations.len(),
        phi.len(),
        cfg.noise_ratio,
        n_train - phi.len()
    ))
}

fn main() {
    stage_kit::finish(run())
}
