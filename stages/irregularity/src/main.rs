//! Stage `irregularity`: one random-phase profile per sample (every split) for each profile of
//! kind `generated` in the system description (the track irregularity, a road's roughness),
//! by the spectral method of `mbd_dataset::profile`, written as `irregularity.parquet`:
//! `sample_id` (i64), `x` (m, `n dx`), `eta` (m, positive downward), sorted by sample then x.
//! With several generated profiles a leading `profile` column (the profile's name) tells them
//! apart, profiles in description order. `profiles.json` records the generator's controls
//! (seed, dx, length), which `simulate` passes on to the models.
//!
//! Command: `irregularity DESCRIPTION.yaml`. Input `params` (the sample ids of
//! `params.parquet`, and its `system.json`, which must be this description). Params: `seed`,
//! `dx` (m), `length` (m, from x = 0; must cover every point's path), `system_values`. The
//! spectrum and the wavelength band come from the description. A profile the description reads
//! by a cubic (`interpolation: cubic`) needs at least 4 points: fewer are refused, in check mode
//! too, at the line of its `interpolation:`. Samples are generated in parallel; each depends
//! only on `(seed, profile, sample_id)`.

use anyhow::{bail, Context, Result};
use mbd_dataset::{ProfileGenerator, ProfileParams};
use pino_data::artifacts::{IRREGULARITY_FILE, PARAMS_FILE, PROFILES_FILE};
use pino_data::{schema, Column, StreamWriter, Table};
use stage_kit::Progress;
use std::collections::BTreeMap;
use std::path::Path;

/// Samples per Parquet row group (64 x 5400 points at the defaults: 2.8 MB per column).
const SAMPLES_PER_GROUP: usize = 64;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    seed: u64,
    dx: f64,
    length: f64,
    #[serde(default)]
    system_values: BTreeMap<String, mbd_system::Override>,
}

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    ctx.declare_origin()?;
    let p: Params = ctx.params()?;
    let (source, system) = stage_kit::load_description(&p.system_values)?;
    let controls = ProfileParams {
        seed: p.seed,
        dx: p.dx,
        length: p.length,
    };
    let generated = mbd_dataset::generated_profiles(&system, &controls).map_err(|e| {
        let context = format!(
            "stage `{}`: bad profile parameters for {}",
            ctx.stage, source.file
        );
        match &e {
            // A profile's own requirement, placed at its line: `file:line:col: profiles...`.
            mbd_dataset::Error::TooFewPoints { profile, .. } => anyhow::anyhow!(
                "{}",
                source.problem_at(&format!("profiles.{profile}.interpolation"), e.to_string())
            )
            .context(context),
            _ => anyhow::Error::new(e).context(context),
        }
    })?;
    if ctx.is_check() {
        return Ok(format!("{} generated profile(s)", generated.len()));
    }
    let dirs = ctx.input_dirs("params")?.to_vec();
    // The params' record, compared with the description compiled above (not compiled again).
    let (record_path, record) = pino_data::system::read_source(&dirs)?;
    pino_data::system::same(&record_path, &record, Path::new(&source.file), &source)?;
    let files = ctx.input_files("params", PARAMS_FILE)?;
    if files.is_empty() {
        bail!("input `params` has no {PARAMS_FILE} (in {dirs:?})");
    }
    // The reader refuses a sample id seen twice.
    let mut ids = pino_data::records::read_params(&files, &[])?.ids;
    ids.sort_unstable();
    if let Some(bad) = ids.iter().find(|&&id| id < 0) {
        bail!("{}: negative sample_id {bad}", files[0].display());
    }
    let progress = ctx.progress((ids.len() * generated.len()) as u64);
    let summary = write_profiles(
        &ctx.output_path(IRREGULARITY_FILE),
        &generated,
        &ids,
        &progress,
    )?;
    pino_data::system::write_json(
        &ctx.output_path(PROFILES_FILE),
        &serde_json::to_value(controls)?,
    )?;
    Ok(summary)
}

/// Writes the profiles of every sample `ids` for each of the `generated` profiles to `path`,
/// in row groups of [`SAMPLES_PER_GROUP`] samples (a fixed layout: same bytes for any thread
/// count), or an empty table of the same columns when there is no generated profile. Returns
/// the summary.
fn write_profiles(
    path: &Path,
    generated: &[(&str, ProfileGenerator)],
    ids: &[i64],
    progress: &Progress,
) -> Result<String> {
    let labelled = generated.len() > 1;
    let tick = || progress.inc(1);
    let mut writer: Option<StreamWriter> = None;
    let mut summary = Vec::new();
    for (name, generator) in generated {
        let x = generator.positions();
        for group in ids.chunks(SAMPLES_PER_GROUP) {
            let eta = generator.profiles_of(group, &tick);
            let table = group_table(labelled.then_some(*name), group, &x, eta)?;
            let w = match &mut writer {
                Some(w) => w,
                None => writer.insert(StreamWriter::create(path, &table)?),
            };
            w.write(&table)?;
        }
        summary.push(generator.describe(name, ids.len()));
    }
    match writer {
        Some(w) => w
            .finish()
            .with_context(|| format!("writing {}", path.display()))?,
        None => {
            // No generated profile: an empty table of the same columns.
            pino_data::write_parquet(path, &group_table(None, &[], &[], Vec::new())?)?;
            summary.push("no generated profile in the description".to_owned());
        }
    }
    Ok(summary.join("; "))
}

/// The rows of one group of samples: (`profile`, when `label`led,) `sample_id`, `x`, `eta`.
fn group_table(label: Option<&str>, group: &[i64], x: &[f64], eta: Vec<f64>) -> Result<Table> {
    let n = x.len();
    let mut table = Table::default();
    if let Some(name) = label {
        table.push(
            schema::PROFILE,
            Column::Str(vec![name.to_string(); n * group.len()]),
        )?;
    }
    let sample_col = group
        .iter()
        .flat_map(|&id| std::iter::repeat_n(id, n))
        .collect();
    table.push(schema::SAMPLE_ID, Column::I64(sample_col))?;
    table.push(schema::TRACK_X, Column::F64(x.repeat(group.len())))?;
    table.push(schema::TRACK_ETA, Column::F64(eta))?;
    Ok(table)
}

fn main() {
    stage_kit::finish(run())
}
