//! `train` stage: one algorithm of the paper's Table 3 (the pipeline's `algorithm` matrix key).
//!
//! Inputs: `params` (params.parquet), `dataset` (simulation.parquet shards), `weights`
//! (weights.parquet, used by algorithm 3). Writes `model.safetensors`, `model.json` and
//! `history.parquet`; checkpoints after every epoch in the unit's scratch directory (kept by
//! `pipeline` across killed runs of the same configuration; the output directory when run by
//! hand), from which the next run resumes. The tensors' channels, the residuals of algorithms 2
//! and 3 and the force scale come from the dataset's system description (`system.json`);
//! algorithms 2 and 3 are refused, naming why, for a description without equations. With
//! `rate_outputs`, the command names the description (`cmd: [train, "${constants.system}"]`)
//! so that a column it does not store is refused at planning.
use anyhow::{Context, Result};
use pino_data::artifacts::{PARAMS_FILE, SIMULATION_FILE, WEIGHTS_FILE};
use pino_learn::config::{ModelConfig, TrainConfig, TrainParams, WindowConfig};
use pino_learn::data::{load_dataset_subset, Dataset, DatasetInfo};
use pino_learn::spectral::Transform;
use pino_learn::train::train_to_dir;
use stage_kit::StageContext;

/// The model, training and window configurations of a training.
type Configs = (ModelConfig, TrainConfig, WindowConfig);

fn run() -> Result<()> {
    pino_learn::tune_allocator();
    let ctx = StageContext::load()?;
    ctx.declare_origin()?;
    let p: TrainParams = ctx.params()?;
    if ctx.is_check() {
        check(&p)?;
        stage_kit::summary("parameters valid");
        return Ok(());
    }
    let (info, configs) = configure(&ctx, &p)?;
    let (_, train, window) = configs;
    let device = p.device.device()?;
    let ds = load(&ctx, &p, &info, train.algorithm.needs_phi(), &window)?;
    let progress = ctx.progress(train.epochs as u64);
    let outcome = train_to_dir(
        &ds,
        configs,
        Transform::for_device(&device),
        &ctx.output,
        // The orchestrator's scratch survives a killed run of this very unit, so the next
        // `pipeline run` resumes from the last epoch; by hand, checkpoints live in the output.
        ctx.scratch.as_deref().unwrap_or(&ctx.output),
        &device,
        &mut |r| progress.set(r.row.epoch as u64, &r.progress_line()),
    )?;
    let last = outcome.history.last().context("no epoch was trained")?;
    stage_kit::summary(&format!(
        "algorithm {} ({}), {} params, {} epochs on {} samples x {} points: validation {:.2}% / {:.2}% / {:.2}%{}",
        train.algorithm.id(),
        train.algorithm.name(),
        outcome.model.num_parameters(),
        last.epoch,
        outcome.meta.train_samples,
        ds.t_points(),
        100.0 * last.val_solution,
        100.0 * last.val_first,
        100.0 * last.val_second,
        outcome.resumed_after.map(|e| format!(" (resumed after epoch {e})")).unwrap_or_default()
    ));
    Ok(())
}

/// Check mode: the algorithm, the rate outputs against the description the command names, and
/// the relative work of the training (which of the matrix's trainings starts first when none
/// has run here before).
fn check(p: &TrainParams) -> Result<()> {
    pino_learn::config::Algorithm::from_id(p.algorithm)?;
    if !p.rate_outputs.is_empty() {
        // The outputs asked for must be stored rates of the description the command names.
        let (_, system) = stage_kit::load_description(&Default::default()).map_err(|e| {
            anyhow::anyhow!("params.rate_outputs: checked against the system description, which the stage's command must name (`cmd: [train, \"${{constants.system}}\"]`): {e}")
        })?;
        pino_learn::layout::Layout::of(&system).with_rate_outputs(&system, &p.rate_outputs)?;
    }
    let work = p.relative_work()?;
    if work > 0.0 {
        stage_kit::work(work);
    }
    Ok(())
}

/// The dataset's description (with the rate outputs of `p`) and the configurations of `p`
/// over its layout.
fn configure(ctx: &StageContext, p: &TrainParams) -> Result<(DatasetInfo, Configs)> {
    let info = DatasetInfo::from_dirs(ctx.input_dirs("dataset")?)
        .and_then(|info| info.with_rate_outputs(&p.rate_outputs))
        .with_context(|| format!("stage `{}`: input `dataset`", ctx.stage))?;
    let configs = p
        .configs(info.layout())
        .with_context(|| format!("stage `{}`", ctx.stage))?;
    Ok((info, configs))
}

/// The training set: params, the simulation shards and, when the algorithm `needs_phi`, the
/// weights.
fn load(
    ctx: &StageContext,
    p: &TrainParams,
    info: &DatasetInfo,
    needs_phi: bool,
    window: &WindowConfig,
) -> Result<Dataset> {
    let params = &ctx.single_input_file("params", PARAMS_FILE)?;
    let sims = ctx.input_files("dataset", SIMULATION_FILE)?;
    let weights = if needs_phi {
        let w = ctx.input_files("weights", WEIGHTS_FILE)?;
        Some(
            w.first()
                .cloned()
                .context("algorithm 3 needs weights.parquet from the `weights` stage")?,
        )
    } else {
        None
    };
    Ok(load_dataset_subset(
        info,
        params,
        &sims,
        weights.as_deref(),
        window,
        p.train_samples,
    )?)
}

fn main() {
    pino_learn::single_threaded_by_default();
    if let Err(e) = run() {
        eprintln!("train: {e:#}");
        std::process::exit(1);
    }
}
