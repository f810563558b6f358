//! Stage `indices`: the indices of every simulated sample that the system description defines
//! (`docs/indices.md`): the railway indices when its `railway:` section binds them to its
//! columns (the vehicle-track description), then its own simple indices (`indices:`). Written
//! as `indices.parquet` (`sample_id`, `split`, the sampled parameters, the index columns,
//! `window_s`, `pass`, `failed`; sorted by sample id) and `indices.json` (the description's
//! name, the settings used, every column's unit and definition). A description with no index
//! still gets both files, with the keys only.
//!
//! Inputs: `params` (`params.parquet` and `system.json`), `dataset` (the `simulation.parquet`
//! and `system.json` of every simulate shard; all the `system.json` must be one description).
//! Params ([`indices::IndexParams`]): `window_start_fraction`, `sperling` (`segment_s`,
//! `taper`, `f_min_hz`), `limits` of the railway family (`peak_wheel_rail_force_kn`,
//! `wheel_load_reduction_rate`, `sperling_wz`; a simple index carries its own `limit` in the
//! description). The work is `indices_scan::compute_all`: a streamed record pass, then, for
//! the railway family, a streaming polars group-by on every core.

use anyhow::{Context, Result};
use pino_data::artifacts::{PARAMS_FILE, SIMULATION_FILE};
use pino_indices as indices;

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    ctx.declare_origin()?;
    let raw: indices::IndexParams = ctx.params()?;
    let cfg = raw
        .validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    if ctx.is_check() {
        return Ok("parameters valid".into());
    }
    let mut dirs = ctx.input_dirs("dataset")?.to_vec();
    dirs.extend_from_slice(ctx.input_dirs("params")?);
    let (_, system) = pino_data::system::read_record(&dirs)?;
    let params = indices_scan::read_params(&system, &ctx.input_files("params", PARAMS_FILE)?)?;
    let files = ctx.input_files("dataset", SIMULATION_FILE)?;
    let progress = ctx.progress(params.len() as u64);
    let out = indices_scan::compute_all(&system, &params, &files, &cfg, &|n| progress.inc(n))?;
    indices_scan::write_outputs(&ctx.output, &system, &out, &cfg)?;
    Ok(indices_scan::summary(&out))
}

fn main() {
    stage_kit::finish(run())
}
