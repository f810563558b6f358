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
use pino_data::write_parquet;
use pino_learn::layout::Layout;
use pino_learn::weights::{sample_params, weigh_training_samples, weights_table, WeightConfig};
use std::path::Path;

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
    let samples = sample_params(&system, params)?;
    let files = ctx.input_files("dataset", SIMULATION_FILE)?;
    if files.is_empty() {
        bail!("input `dataset` has no {SIMULATION_FILE} (in {dirs:?})");
    }
    let dt = output_spacing(&dirs[0].join(PROVENANCE_FILE))?;
    let n_train = samples.values().filter(|(train, _)| *train).count();
    let progress = ctx.progress(n_train as u64);
    let tick = || progress.inc(1);
    let phi = weigh_training_samples(&cfg, &system, &layout, &samples, &files, dt, &tick)?;
    let table = weights_table(&system, &layout, &phi)?;
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

/// The spacing of the stored records (s): the solver's `dt` times `output_every`, from a
/// shard's provenance.
fn output_spacing(provenance: &Path) -> Result<f64> {
    let provenance = pino_data::provenance::read_provenance(provenance)?;
    let of = |key: &str| {
        provenance
            .get(key)
            .copied()
            .with_context(|| format!("provenance.parquet has no {key}"))
    };
    Ok(of("dt")? * of("output_every")?)
}

fn main() {
    stage_kit::finish(run())
}
