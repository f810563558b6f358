//! Stage `simulate`: runs the generic engine (`mbd_engine`, Zhai's explicit method on the
//! assembled system description) for every sample this shard owns (`shard.owns(sample_id)`),
//! in parallel across samples (rayon), and writes
//! - `simulation.parquet`: `sample_id`, `t` and every stored channel of the description
//!   (`docs/systems.md`, naming rule and column order), rows sorted by `sample_id` then `t`, one
//!   row group per sample;
//! - `failures.parquet`: `sample_id`, `reason` of samples whose state became non-finite;
//! - `provenance.parquet`: the run controls used (`pino_data::provenance`);
//! - `system.json`: the description simulated (the learning stages read it from here);
//! - `run.json`: the run controls and the profile generator's controls (`profiles.json` of the
//!   irregularity input): how the data were made, recorded in every trained model.
//!
//! Command: `simulate DESCRIPTION.yaml`. Inputs: `params` (`params.parquet`, whose
//! `system.json` must be this description) and `irregularity` (`irregularity.parquet`: the
//! profile of every sample, for descriptions with a generated profile). Params: the run
//! controls of `mbd_engine::RunConfig` (`duration`, `dt`, `output_every`, `start`:
//! `equilibrium` or `rest`, `startup_zero_fraction`, `startup_ramp_fraction`, `x0`), all
//! required, and `system_values`. Everything is checked (the time step against each sample's
//! stability bound included) before the first sample runs. In check mode: the description,
//! the run controls, the moving points against the start of every generated profile they read
//! (`file:line:col` of the profile) and the time step against the bound, both over the whole
//! box of sampling ranges.

use anyhow::{bail, Context, Result};
use mbd_engine::{Profile, RunConfig, SampleInput, StartMode};
use mbd_system::system::Profile as DescribedProfile;
use mbd_system::{System, SystemSource};
use pino_data::artifacts::{FAILURES_FILE, IRREGULARITY_FILE, PARAMS_FILE, SIMULATION_FILE};
use pino_data::records::read_params_of;
use pino_data::{for_each_batch, schema, Column, StreamWriter, Table};
use stage_kit::StageContext;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    duration: f64,
    dt: f64,
    output_every: usize,
    start: StartMode,
    startup_zero_fraction: f64,
    startup_ramp_fraction: f64,
    x0: f64,
    #[serde(default)]
    system_values: BTreeMap<String, mbd_system::Override>,
}

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    ctx.declare_origin()?;
    let p: Params = ctx.params()?;
    let config = RunConfig {
        duration: p.duration,
        dt: p.dt,
        output_every: p.output_every,
        start: p.start,
        startup_zero_fraction: p.startup_zero_fraction,
        startup_ramp_fraction: p.startup_ramp_fraction,
        x0: p.x0,
    };
    config
        .validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    let (source, system) = stage_kit::load_description(&p.system_values)?;
    let system = Arc::new(system);
    if ctx.is_check() {
        return check(&ctx, &source, &system, &config);
    }
    let dirs = ctx.input_dirs("params")?.to_vec();
    // The params' record, compared with the description compiled above (not compiled again).
    let (record_path, record) = pino_data::system::read_source(&dirs)?;
    pino_data::system::same(&record_path, &record, Path::new(&source.file), &source)?;
    let generated: Vec<usize> = (0..system.profiles.len())
        .filter(|&i| matches!(system.profiles[i], DescribedProfile::Generated { .. }))
        .collect();
    let inputs = sample_inputs(&ctx, &system, &generated)?;
    let engines = mbd_engine::prepare(&system, &config, inputs)
        .map_err(|(id, e)| anyhow::anyhow!("sample {id}: {e}"))?;
    let progress = ctx.progress(engines.len() as u64);
    let (rows, n_failed) = simulate_to(&ctx, &system, &engines, &progress)?;
    write_records(&ctx, &source, &config, !generated.is_empty())?;
    let s = ctx.shard;
    Ok(format!(
        "{} ok, {n_failed} failed, {rows} rows (shard {}/{})",
        engines.len() - n_failed,
        s.index + 1,
        s.count
    ))
}

/// Check mode: the moving points against the start of every generated profile they read and
/// the time step against its bound, both over the box of sampling ranges.
fn check(
    ctx: &StageContext,
    source: &SystemSource,
    system: &Arc<System>,
    config: &RunConfig,
) -> Result<String> {
    mbd_engine::coverage::check_profile_starts_described(source, system, config)
        .with_context(|| format!("stage `{}`", ctx.stage))?;
    let (bound, corner) = mbd_engine::stability::parameter_box(system, config)
        .with_context(|| format!("stage `{}`: {}", ctx.stage, source.file))?;
    if let Err(e) = bound.check(config.dt) {
        let at: Vec<String> = corner.iter().map(|(n, v)| format!("{n} = {v}")).collect();
        bail!("stage `{}` ({}): {e}; the bound is taken over the box of sampling ranges, largest at {}", ctx.stage, source.file, at.join(", "));
    }
    Ok(format!(
        "dt {} s within the bound {:.3e} s over the parameter box",
        config.dt,
        bound.dt_limit()
    ))
}

/// The samples this shard owns, in id order: their parameters (`params`) and their profiles
/// of each `generated` profile of the description (`irregularity`).
fn sample_inputs(
    ctx: &StageContext,
    system: &System,
    generated: &[usize],
) -> Result<Vec<SampleInput>> {
    let params = read_params_of(&ctx.input_files("params", PARAMS_FILE)?, system)?;
    let mut profiles = if generated.is_empty() {
        BTreeMap::new()
    } else {
        let files = ctx.input_files("irregularity", IRREGULARITY_FILE)?;
        let labels: Vec<&str> = generated
            .iter()
            .map(|&i| system.profiles[i].name())
            .collect();
        owned_profiles(&files, ctx.shard, &labels)?
    };
    let mut inputs = Vec::new();
    for (id, _, values) in params.rows() {
        if id < 0 {
            bail!("{PARAMS_FILE}: sample_id {id} is negative");
        }
        if !ctx.shard.owns(id as u64) {
            continue;
        }
        let mut sample_profiles = vec![None; system.profiles.len()];
        for (k, &pi) in generated.iter().enumerate() {
            let Some((x, eta)) = profiles.remove(&(k, id)) else {
                bail!(
                    "{IRREGULARITY_FILE} has no profile `{}` for sample_id {id}",
                    system.profiles[pi].name()
                );
            };
            sample_profiles[pi] = Some(
                Profile::new(x, eta)
                    .with_context(|| format!("{IRREGULARITY_FILE}: sample {id}"))?,
            );
        }
        inputs.push(SampleInput {
            id: id as u64,
            params: system.sampled_values(values)?,
            profiles: sample_profiles,
        });
    }
    inputs.sort_by_key(|s| s.id);
    Ok(inputs)
}

/// Runs the `engines` (`mbd_engine::run_all`), writing `simulation.parquet` (one row group per
/// sample) and `failures.parquet`; returns the rows written and the number of failures.
fn simulate_to(
    ctx: &StageContext,
    system: &System,
    engines: &[(u64, mbd_engine::Engine)],
    progress: &stage_kit::Progress,
) -> Result<(usize, usize)> {
    let path = ctx.output_path(SIMULATION_FILE);
    let mut names = vec![schema::SAMPLE_ID.to_owned(), schema::TIME.to_owned()];
    names.extend(system.channels.iter().map(|c| c.name.clone()));
    let template = table(&names, 0, &[], &[]).with_units(pino_data::system::units_of(system)?);
    let mut writer = StreamWriter::create(&path, &template)?;
    let mut failures: (Vec<i64>, Vec<String>) = (Vec::new(), Vec::new());
    mbd_engine::run_all(engines, 64, &|| progress.inc(1), |id, out| -> Result<()> {
        match out {
            Ok(tr) => writer.write(&table(&names, id as i64, &tr.t, &tr.columns))?,
            Err(f) => {
                failures.0.push(id as i64);
                failures.1.push(f.reason);
            }
        }
        Ok(())
    })?;
    let rows = writer.rows();
    writer.finish()?;
    let mut failed = Table::default();
    let n_failed = failures.0.len();
    failed.push(schema::SAMPLE_ID, Column::I64(failures.0))?;
    failed.push("reason", Column::Str(failures.1))?;
    pino_data::write_parquet(&ctx.output_path(FAILURES_FILE), &failed)?;
    Ok((rows, n_failed))
}

/// How the data were made: `provenance.parquet` (the run controls), `system.json` (the
/// description) and `run.json` (the run controls and, when the description has `generated`
/// profiles, the generator's controls of the `irregularity` input).
fn write_records(
    ctx: &StageContext,
    source: &SystemSource,
    config: &RunConfig,
    generated: bool,
) -> Result<()> {
    pino_data::provenance::write_provenance(
        &ctx.output_path(pino_data::artifacts::PROVENANCE_FILE),
        &[
            ("dt", config.dt),
            ("duration", config.duration),
            ("output_every", config.output_every as f64),
            ("startup_zero_fraction", config.startup_zero_fraction),
            ("startup_ramp_fraction", config.startup_ramp_fraction),
            ("x0", config.x0),
        ],
    )?;
    pino_data::system::write_record(&ctx.output, source)?;
    let profiles = if generated {
        let dirs = ctx.input_dirs("irregularity")?;
        pino_data::system::read_json(&dirs[0].join(pino_data::artifacts::PROFILES_FILE))?
    } else {
        serde_json::Value::Null
    };
    pino_data::system::write_json(
        &ctx.output_path(pino_data::artifacts::RUN_FILE),
        &serde_json::json!({"run": config, "profiles": profiles}),
    )?;
    Ok(())
}

/// One profile's positions (m) and values (m).
type XEta = (Vec<f64>, Vec<f64>);

/// The profiles of the samples this shard owns, by (generated-profile index, sample id). The
/// files are streamed batch by batch (at paper scale they hold 119 M rows), keeping only this
/// shard's rows; the rows of one sample are consecutive and sorted by x (checked by
/// `Profile::new`). With several profiles the `profile` column names each row's.
fn owned_profiles(
    files: &[PathBuf],
    shard: stage_kit::Shard,
    labels: &[&str],
) -> Result<BTreeMap<(usize, i64), XEta>> {
    let mut profiles: BTreeMap<(usize, i64), XEta> = BTreeMap::new();
    let mut cols = vec![schema::SAMPLE_ID, schema::TRACK_X, schema::TRACK_ETA];
    if labels.len() > 1 {
        cols.push(schema::PROFILE);
    }
    for file in files {
        for_each_batch(file, Some(&cols), |t| {
            let (ids, xs, etas) = (t.i64(cols[0])?, t.f64(cols[1])?, t.f64(cols[2])?);
            let which = if labels.len() > 1 {
                Some(t.str(schema::PROFILE)?)
            } else {
                None
            };
            let mut start = 0;
            while start < ids.len() {
                let id = ids[start];
                let label = which.map(|w| w[start].as_str());
                let same = |r: usize| ids[r] == id && which.is_none_or(|w| w[r] == w[start]);
                let end = (start + 1..ids.len())
                    .find(|&r| !same(r))
                    .unwrap_or(ids.len());
                let k = match label {
                    None => 0,
                    Some(l) => labels.iter().position(|x| *x == l).ok_or_else(|| {
                        pino_data::Error::System(format!(
                            "{}: unknown profile `{l}` (the description's: {})",
                            file.display(),
                            labels.join(", ")
                        ))
                    })?,
                };
                if id >= 0 && shard.owns(id as u64) {
                    let p = profiles.entry((k, id)).or_default();
                    p.0.extend_from_slice(&xs[start..end]);
                    p.1.extend_from_slice(&etas[start..end]);
                }
                start = end;
            }
            Ok(())
        })?;
    }
    Ok(profiles)
}

/// One sample's rows in schema order: `sample_id`, `t`, then the channels.
fn table(names: &[String], id: i64, t: &[f64], signals: &[Vec<f64>]) -> Table {
    let mut table = Table::default();
    let mut push = |name: &str, col| table.push(name, col).expect("equal lengths, unique names");
    push(&names[0], Column::I64(vec![id; t.len()]));
    push(&names[1], Column::F64(t.to_vec()));
    for (j, name) in names[2..].iter().enumerate() {
        push(
            name,
            Column::F64(signals.get(j).cloned().unwrap_or_default()),
        );
    }
    table
}

fn main() {
    stage_kit::finish(run())
}
