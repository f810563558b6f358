//! Stage `sample-params`: draws every sample's 14 parameters uniformly on their ranges
//! (`vtcd::sampling`) and writes `params.parquet`: `sample_id` (i64), `split`
//! ("train"/"validation"/"test"), then the 14 parameters (f64, spec order and units), and
//! `ranges.parquet`: `name`, `unit`, `min`, `max` of each parameter's sampling range.
//!
//! Params: `seed`, `n_train`, `n_validation`, `n_test`, optional `ranges` (see
//! `vtcd::sampling`). Ids `0..n_train` are training samples, the next `n_validation` ids
//! validation samples and the `n_test` ids after those test samples (held out from every
//! choice of settings), so the test split leaves the other two unchanged.

use anyhow::{Context, Result};
use pino_data::{schema, write_parquet, Column, Table};
use vtcd::params::NUM_PARAMETERS;
use vtcd::sampling::SamplingParams;

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    pino_data::metadata::set_stage_origin(&ctx)?;
    let raw: SamplingParams = ctx.params()?;
    let plan = raw
        .validate()
        .with_context(|| format!("stage `{}`: bad sampling parameters", ctx.stage))?;
    let samples = plan.samples();

    let mut table = Table::default();
    let ids = samples.iter().map(|(id, _, _)| *id as i64).collect();
    table.push(schema::SAMPLE_ID, Column::I64(ids))?;
    let splits = samples
        .iter()
        .map(|(_, s, _)| s.as_str().to_owned())
        .collect();
    table.push(schema::SPLIT, Column::Str(splits))?;
    for j in 0..NUM_PARAMETERS {
        let values = samples.iter().map(|(_, _, p)| p.to_array()[j]).collect();
        table.push(schema::PARAMETERS[j], Column::F64(values))?;
    }
    let path = ctx.output_path("params.parquet");
    write_parquet(&path, &table).with_context(|| format!("writing {}", path.display()))?;
    // The configured ranges, stored by `train` with each model so that `predict` can flag
    // designs outside them.
    let mut ranges = Table::default();
    ranges.push(
        "name",
        Column::Str(schema::PARAMETERS.iter().map(|s| s.to_string()).collect()),
    )?;
    ranges.push(
        "unit",
        Column::Str(
            schema::PARAMETERS
                .iter()
                .map(|s| pino_data::units::unit(s).unwrap_or("-").to_string())
                .collect(),
        ),
    )?;
    ranges.push(
        "min",
        Column::F64(plan.ranges().iter().map(|r| r[0]).collect()),
    )?;
    ranges.push(
        "max",
        Column::F64(plan.ranges().iter().map(|r| r[1]).collect()),
    )?;
    let path = ctx.output_path("ranges.parquet");
    write_parquet(&path, &ranges).with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "{} train + {} validation + {} test samples",
        plan.n_train(),
        plan.n_validation(),
        plan.n_test()
    ))
}

fn main() {
    stage_kit::finish(run())
}
