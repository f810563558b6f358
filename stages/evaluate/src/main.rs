//! `evaluate` stage: Table 4 (with its truth row) on the test split for every trained model;
//! on the validation split, flagged in the table, when asked (`split: validation`, a
//! selection study) or when the dataset has no test split.
//!
//! Inputs: `params` (params.parquet), `dataset` (simulation.parquet shards with the system
//! description's record), `models` (one directory per expansion of `train`, each trained on
//! that description), `calibration` (optional: the `calibrate` stage's output; adds the
//! coverage of every model's intervals, `coverage.{parquet,csv,md}` and
//! `coverage_conditional.{parquet,csv}`), `surrogate` (optional: the `surrogate` stage's
//! output; adds its per-quantity errors, routes and coverage, `surrogate_errors.{parquet,csv}`
//! and `surrogate.md`). Writes `table4.{parquet,csv,md}`, `channel_errors.{parquet,csv}`, the
//! engineering indices of the description against the solver (`indices_*`), prediction and
//! training-curve PNGs and `plots.md`.
use anyhow::{bail, Context, Result};
use pino_eval::{evaluate, EvalOptions, EvalParams};
use pino_learn::data::DatasetInfo;
use pino_learn::spectral::Transform;
use pino_outputs::split::EvalData;
use stage_kit::StageContext;

fn run() -> Result<()> {
    pino_learn::tune_allocator();
    let ctx = StageContext::load()?;
    ctx.declare_origin()?;
    let p: EvalParams = ctx.params()?;
    if ctx.is_check() {
        // Before anything runs: the channels to plot against the description the command
        // names (the dataset does not exist yet).
        let (_, system) = stage_kit::load_description(&p.system_values)?;
        let layout = pino_learn::layout::Layout::of(&system);
        pino_eval::plot_channels(&p.plot_channels, &layout, &system)
            .with_context(|| format!("stage `{}`: parameter `plot_channels`", ctx.stage))?;
        stage_kit::summary("parameters valid");
        return Ok(());
    }
    let info = DatasetInfo::from_dirs(ctx.input_dirs("dataset")?)
        .with_context(|| format!("stage `{}`: input `dataset`", ctx.stage))?;
    let device = p.device.device()?;
    let params = &ctx.single_input_file("params", pino_data::artifacts::PARAMS_FILE)?;
    let sims = ctx.input_files("dataset", pino_data::artifacts::SIMULATION_FILE)?;
    let models = ctx.input_dirs("models")?.to_vec();
    if models.is_empty() {
        bail!("input `models` is empty: wire the `train` stage");
    }
    let opts = EvalOptions {
        plot_samples: p.plot_samples,
        plot_channels: p.plot_channels.clone(),
        batch_size: p.batch_size.max(1),
        transform: Transform::for_device(&device),
        compare_with_paper: p.compare_with_paper,
        // Optional: an uncalibrated pipeline is evaluated without coverage tables.
        calibration: ctx.optional_single_input_dir("calibration")?,
        split: p.split,
        // Optional: the surrogate's per-quantity errors and coverage beside Table 4.
        surrogate: ctx.optional_single_input_dir("surrogate")?,
    };
    let progress = ctx.progress(models.len() as u64);
    let data = EvalData {
        info: &info,
        params_file: params,
        simulation_files: &sims,
    };
    let ev = evaluate(
        &data,
        &models,
        &ctx.output,
        &opts,
        &device,
        &mut |done, msg| progress.set(done as u64, msg),
    )?;
    stage_kit::summary(&ev.summary());
    Ok(())
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    if let Err(e) = run() {
        eprintln!("evaluate: {e:#}");
        std::process::exit(1);
    }
}
