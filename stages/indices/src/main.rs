//! Stage `indices`: the engineering indices of every simulated sample (`docs/indices.md`),
//! written as `indices.parquet` (`sample_id`, `split`, the 14 parameters, the 14 indices,
//! `window_s`, `pass`, `failed`; sorted by sample id) and `indices.json` (the settings used,
//! every column's unit and definition).
//!
//! Inputs: `params` (`params.parquet`), `dataset` (the `simulation.parquet` of every simulate
//! shard). Params ([`indices::IndexParams`]): `window_start_fraction`, `gravity`, `sperling`
//! (`segment_s`, `taper`, `f_min_hz`), `limits` (`peak_wheel_rail_force_kn`,
//! `wheel_load_reduction_rate`, `sperling_wz`). The work is `indices_scan::compute_all`:
//! a streamed spectral pass, then a streaming polars group-by on every core.

use anyhow::{Context, Result};
use pino_indices as indices;

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    pino_data::metadata::set_stage_origin(&ctx)?;
    let raw: indices::IndexParams = ctx.params()?;
    let cfg = raw
        .validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    let params = ctx.single_input_file("params", "params.parquet")?;
    let files = ctx.input_files("dataset", "simulation.parquet")?;
    let total = indices_scan::read_params(&params)?.len() as u64;
    let progress = ctx.progress(total);
    let out = indices_scan::compute_all(&params, &files, &cfg, &|n| progress.inc(n))?;
    indices_scan::write_outputs(&ctx.output, &out.rows, &cfg)?;
    let failing = out.rows.iter().filter(|r| !r.failed.is_empty()).count();
    let worst = |index: &dyn Fn(&indices::Indices) -> f64| {
        out.rows
            .iter()
            .map(|r| index(&r.indices))
            .fold(f64::NEG_INFINITY, f64::max)
    };
    Ok(format!(
        "indices of {} samples ({} absent from the dataset); {failing} exceed a limit; worst: peak force {:.1} kN, wheel load reduction {:.3}, W_z {:.2}",
        out.rows.len(),
        out.absent,
        worst(&|i| i.peak_wheel_rail_force_kn),
        worst(&|i| i.wheel_load_reduction_rate),
        worst(&|i| i.sperling_wz.into_iter().fold(f64::NEG_INFINITY, f64::max)),
    ))
}

fn main() {
    stage_kit::finish(run())
}
