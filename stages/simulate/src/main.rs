//! Stage `simulate`: runs `vtcd::simulation` (Zhai's explicit method on the coupled
//! vehicle-track model) for every sample this shard owns (`shard.owns(sample_id)`), in
//! parallel across samples (rayon), and writes
//! - `simulation.parquet`: every column of `pino_data::schema::simulation_columns()`, rows
//!   sorted by `sample_id` then `t`, one row group per sample;
//! - `failures.parquet`: `sample_id`, `reason` of samples whose state became non-finite;
//! - `provenance.parquet`: the physical constants used (`pino_data::provenance`), which the
//!   learning stages check against their own.
//!
//! Inputs: `params` (`params.parquet`) and `irregularity` (`irregularity.parquet`: `sample_id`,
//! `x` m, `eta` m). Params: `vtcd::simulation::SimulationConfig` (every field optional, spec
//! defaults, unknown names refused), among them `start`: `equilibrium` (default: each run
//! begins at the static solution of vehicle and track under the wheel loads) or `rest` (the
//! paper's zero state, the vehicle dropping onto the track), and the irregularity start-up
//! fractions. Everything is checked (time-step limit included) before the first sample runs.

use anyhow::{bail, Context, Result};
use pino_data::{for_each_batch, read_parquet_files, schema, Column, StreamWriter, Table};
use std::collections::BTreeMap;
use std::path::PathBuf;
use vtcd::params::SampleParams;
use vtcd::simulation::{self, Profile, SampleInput, SimulationConfig};

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    pino_data::metadata::set_stage_origin(&ctx)?;
    let config: SimulationConfig = ctx.params()?;
    config
        .validate()
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;

    let mut cols = vec![schema::SAMPLE_ID];
    cols.extend(schema::PARAMETERS);
    let params = read_parquet_files(&ctx.input_files("params", "params.parquet")?, Some(&cols))?;
    let irr_files = ctx.input_files("irregularity", "irregularity.parquet")?;
    let mut profiles = owned_profiles(&irr_files, ctx.shard)?;
    let mut inputs = Vec::new();
    let values: Vec<&[f64]> = schema::PARAMETERS
        .iter()
        .map(|n| params.f64(n))
        .collect::<Result<_, _>>()?;
    for (row, &id) in params.i64(schema::SAMPLE_ID)?.iter().enumerate() {
        if id < 0 {
            bail!("params.parquet: sample_id {id} is negative");
        }
        if !ctx.shard.owns(id as u64) {
            continue;
        }
        let p = SampleParams::from_array(std::array::from_fn(|j| values[j][row]));
        p.validate()
            .with_context(|| format!("params.parquet: sample {id}"))?;
        let Some((x, eta)) = profiles.remove(&id) else {
            bail!(
                "irregularity.parquet ({} files) has no profile for sample_id {id}",
                irr_files.len()
            );
        };
        let profile =
            Profile::new(x, eta).with_context(|| format!("irregularity.parquet: sample {id}"))?;
        inputs.push(SampleInput {
            id: id as u64,
            params: p,
            profile: Some(profile),
        });
    }
    inputs.sort_by_key(|s| s.id);
    let sims = simulation::prepare(&config, inputs)
        .map_err(|(id, e)| anyhow::anyhow!("sample {id}: {e}"))?;

    let progress = ctx.progress(sims.len() as u64);
    let path = ctx.output_path("simulation.parquet");
    let names = schema::simulation_columns();
    let mut writer = StreamWriter::create(&path, &table(&names, 0, &[], &[]))?;
    let mut failures: (Vec<i64>, Vec<String>) = (Vec::new(), Vec::new());
    simulation::run_all(&sims, 64, &|| progress.inc(1), |id, out| -> Result<()> {
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
    pino_data::write_parquet(&ctx.output_path("failures.parquet"), &failed)?;
    pino_data::provenance::write_provenance(
        &ctx.output_path(pino_data::provenance::PROVENANCE_FILE),
        &[
            ("gravity", config.gravity),
            ("wheel_radius", config.wheel_radius),
            ("dt", config.dt),
            ("startup_zero_fraction", config.startup_zero_fraction),
            ("startup_ramp_fraction", config.startup_ramp_fraction),
        ],
    )?;
    let s = ctx.shard;
    Ok(format!(
        "{} ok, {n_failed} failed, {rows} rows (shard {}/{})",
        sims.len() - n_failed,
        s.index + 1,
        s.count
    ))
}

/// One profile's positions (m) and values (m).
type XEta = (Vec<f64>, Vec<f64>);

/// The profiles of the samples this shard owns, grouped by sample id. The files are streamed
/// batch by batch (at paper scale they hold 119 M rows), keeping only this shard's rows; the
/// rows of one sample are consecutive and sorted by x (checked by `Profile::new`).
fn owned_profiles(files: &[PathBuf], shard: stage_kit::Shard) -> Result<BTreeMap<i64, XEta>> {
    let mut profiles: BTreeMap<i64, XEta> = BTreeMap::new();
    let cols = [schema::SAMPLE_ID, schema::TRACK_X, schema::TRACK_ETA];
    for file in files {
        for_each_batch(file, Some(&cols), |t| {
            let (ids, xs, etas) = (t.i64(cols[0])?, t.f64(cols[1])?, t.f64(cols[2])?);
            let mut start = 0;
            while start < ids.len() {
                let id = ids[start];
                let end = start + ids[start..].iter().take_while(|&&i| i == id).count();
                if id >= 0 && shard.owns(id as u64) {
                    let p = profiles.entry(id).or_default();
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

/// One sample's rows in schema order: `sample_id`, `t`, then the 42 signals.
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
