//! `calibrate` stage: the conformal calibration of every trained model (`docs/uncertainty.md`),
//! from the dataset's calibration split (solver runs no model has seen).
//!
//! Inputs: `params` (params.parquet), `dataset` (simulation.parquet shards with the system
//! description's record), `models` (one directory per expansion of `train`). Writes, per
//! model, `algorithm-<A>/calibration.json` (the model's identity, the dataset design, the
//! sorted scores of every index and channel under each normaliser, the channels' time scales,
//! the error heads, the quantiles at 0.8 / 0.9 / 0.95), which `predict --calibration`,
//! `explore` and `evaluate` read. With no calibration split (`sample-params.n_calibration: 0`)
//! each file says so and answers carry no interval. Params: `normaliser` (`none`, `residual`,
//! `error_head`), `ridge` (the error heads' penalty), `batch_size`, `device`.
use anyhow::{bail, Context, Result};
use pino_calibration::build::{calibrate, CalibrateParams};
use pino_learn::data::DatasetInfo;
use pino_outputs::split::EvalData;
use stage_kit::StageContext;

fn run() -> Result<String> {
    pino_learn::tune_allocator();
    let ctx = StageContext::load()?;
    ctx.declare_origin()?;
    let p: CalibrateParams = ctx.params()?;
    p.validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    if ctx.is_check() {
        return Ok("parameters valid".into());
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
    let progress = ctx.progress(models.len() as u64);
    let data = EvalData {
        info: &info,
        params_file: params,
        simulation_files: &sims,
    };
    let done = calibrate(&data, &models, &ctx.output, &p, &device, &mut |k, msg| {
        progress.set(k as u64, msg)
    })?;
    let rows: Vec<String> = done
        .iter()
        .map(|c| {
            let force = c
                .indices
                .first()
                .and_then(|q| {
                    q.quantiles
                        .get("0.9")
                        .map(|v| format!(", {} q0.9 {v:.4}", q.name))
                })
                .unwrap_or_default();
            format!("algorithm {}{force}", c.model.algorithm)
        })
        .collect();
    let n = done.first().map_or(0, |c| c.n);
    Ok(match done.first().and_then(|c| c.no_intervals.clone()) {
        Some(why) => format!("no intervals: {why}"),
        None => format!(
            "{n} calibration samples, normaliser {}: {}",
            p.normaliser.as_str(),
            rows.join("; ")
        ),
    })
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    stage_kit::finish(run())
}
