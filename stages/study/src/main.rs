//! `study` stage: one design study through a trained model (`docs/studies.md`), the solver
//! beside it.
//!
//! Inputs: `surrogate` (the `surrogate` stage's output), or `models` (one directory per
//! expansion of `train`: the model of `algorithm` answers alone) with `calibration` (optional:
//! the `calibrate` stage's output; without it the answers carry no error bar and the files say
//! so). Params: `study` (the matrix value: the study's declaration, with `name` and `kind`),
//! `algorithm` (which model), `coverage`, `seed`, `batch_size`, `bootstrap`, `confidence`,
//! `device`, `system_values`. In check mode the declaration is checked against the
//! description named on the command line before anything runs. Writes the study's files
//! (`evaluations.parquet`, `solver.parquet`, `summary.{parquet,csv,md}`).
use anyhow::{bail, Context, Result};
use pino_study::StudyParams;
use stage_kit::StageContext;

fn run() -> Result<String> {
    pino_learn::tune_allocator();
    let ctx = StageContext::load()?;
    ctx.declare_origin()?;
    let p: StudyParams = ctx.params()?;
    if ctx.is_check() {
        let (_, system) = stage_kit::load_description(&p.system_values)?;
        let study = pino_study::check(&system, &p)
            .with_context(|| format!("stage `{}`: bad study", ctx.stage))?;
        return Ok(format!("study `{}` valid", study.name));
    }
    let surrogate = ctx.optional_single_input_dir("surrogate")?;
    let models = match surrogate {
        Some(_) => Vec::new(),
        None => ctx.input_dirs("models")?.to_vec(),
    };
    if surrogate.is_none() && models.is_empty() {
        bail!("input `models` is empty: wire the `surrogate` stage (or a `train` stage)");
    }
    // Optional: without it the answers carry no error bar and the files say so.
    let calibration = ctx.optional_single_input_dir("calibration")?;
    let device = p.device.device()?;
    let surrogate = pino_study::load_surrogate(
        surrogate.as_deref(),
        &models,
        calibration.as_deref(),
        &p,
        &device,
    )
    .with_context(|| format!("stage `{}`", ctx.stage))?;
    let summary = pino_study::run(&surrogate, &p, &ctx.output)
        .with_context(|| format!("stage `{}`", ctx.stage))?;
    Ok(summary)
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    stage_kit::finish(run())
}
