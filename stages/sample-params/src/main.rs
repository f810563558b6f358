//! Stage `sample-params`: draws every sample's sampled parameters of the system description
//! uniformly on their ranges (`mbd_dataset::sampling`) and writes
//! - `params.parquet`: `sample_id` (i64), `split` ("train"/"validation"/"test"/"calibration"), then the
//!   sampled parameters (f64, the description's order and units);
//! - `ranges.parquet`: `name`, `unit`, `min`, `max` of each sampled parameter's range;
//! - `system.json`: the description sampled from, with the run's overrides (every later stage
//!   reads it from here or from the dataset).
//!
//! Command: `sample-params DESCRIPTION.yaml`. Params: `seed`, `n_train`, `n_validation`,
//! `n_test`, `n_calibration` (default 0), `system_values` (parameter overrides of the
//! description). Ids `0..n_train` are training samples, the next `n_validation` ids validation
//! samples, the `n_test` ids after those test samples and the `n_calibration` ids after those
//! the calibration samples of the conformal intervals (`docs/uncertainty.md`), so a later
//! split leaves the earlier ones unchanged. In check mode it compiles the description and
//! checks the counts.

use anyhow::{Context, Result};
use mbd_dataset::{SamplingPlan, SplitSizes};
use std::collections::BTreeMap;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    seed: u64,
    n_train: u64,
    n_validation: u64,
    n_test: u64,
    #[serde(default)]
    n_calibration: u64,
    #[serde(default)]
    system_values: BTreeMap<String, mbd_system::Override>,
}

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    ctx.declare_origin()?;
    let p: Params = ctx.params()?;
    let (source, system) = stage_kit::load_description(&p.system_values)?;
    let sizes = SplitSizes {
        seed: p.seed,
        n_train: p.n_train,
        n_validation: p.n_validation,
        n_test: p.n_test,
        n_calibration: p.n_calibration,
    };
    let plan = SamplingPlan::new(sizes, &system)
        .with_context(|| format!("stage `{}`: bad sampling parameters", ctx.stage))?;
    if ctx.is_check() {
        return Ok(format!(
            "{}: {} sampled parameters",
            source.file,
            system.sampled().len()
        ));
    }
    let names = system.sampled_names();
    let n = plan.num_samples();
    let draws: Vec<Vec<f64>> = (0..n).map(|id| plan.draw(id)).collect();
    let splits: Vec<&str> = (0..n).map(|id| plan.split(id).as_str()).collect();
    pino_data::system::write_sample_params(&ctx.output, &system, &splits, &draws, plan.ranges())
        .with_context(|| format!("writing the sampled designs into {}", ctx.output.display()))?;
    pino_data::system::write_record(&ctx.output, &source)?;
    Ok(format!(
        "{}: {} train + {} validation + {} test + {} calibration samples of {} parameters",
        system.name,
        sizes.n_train,
        sizes.n_validation,
        sizes.n_test,
        sizes.n_calibration,
        names.len()
    ))
}

fn main() {
    stage_kit::finish(run())
}
