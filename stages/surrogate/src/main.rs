//! `surrogate` stage: one surrogate from several trained models (`docs/uncertainty.md`,
//! "One surrogate"). Per index and per predicted channel, the candidate with the lowest error
//! on the validation split answers it, with its calibration.
//!
//! Inputs: `candidates` (model directories: one or several training stages, in order of
//! preference on ties), `calibration` (the `calibrate` stage's output over the same models:
//! their intervals and the validation errors it recorded). Writes `surrogate.json` (members,
//! routes, every candidate's identity), `members/<name>/` (each chosen model's `model.json`,
//! `model.safetensors`, `calibration.json`), `routes.{csv,md}`.
use anyhow::{Context, Result};
use stage_kit::StageContext;

fn run() -> Result<String> {
    let ctx = StageContext::load()?;
    ctx.declare_origin()?;
    let candidates = ctx.input_dirs("candidates")?.to_vec();
    let calibration = ctx.optional_single_input_dir("calibration")?.context(
        "input `calibration` is not wired: wire the `calibrate` stage of the candidates",
    )?;
    let m = pino_surrogate::build::build(&candidates, &calibration, &ctx.output)
        .with_context(|| format!("stage `{}`", ctx.stage))?;
    let routes: Vec<String> = m
        .members
        .iter()
        .map(|x| {
            let n = m.indices.iter().filter(|r| r.member == x.name).count();
            let c = m.channels.iter().filter(|r| r.member == x.name).count();
            format!("{} ({n} indices, {c} channels)", x.name)
        })
        .collect();
    Ok(format!(
        "{} of {} candidates answer: {}",
        m.members.len(),
        m.candidates.len(),
        routes.join(", ")
    ))
}

fn main() {
    stage_kit::finish(run())
}
