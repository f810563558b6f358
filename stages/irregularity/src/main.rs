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
use rayon::prelude::*;
use std::collections::BTreeMap;

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
    let generators = mbd_dataset::profile_generators(&system, &controls).map_err(|e| {
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
    let generated: Vec<(&str, ProfileGenerator)> = system
        .profiles
        .iter()
        .zip(generators)
        .filter_map(|(prof, g)| g.map(|g| (prof.name(), g)))
        .collect();
    if ctx.is_check() {
        return Ok(format!("{} generated profile(s)", generated.len()));
    }
    let dirs = ctx.input_dirs("params")?.to_vec();
    let (record, _) = pino_data::system::read_record(&dirs)?;
    pino_data::system::same(
        &dirs[0].join(mbd_system::SYSTEM_FILE),
        &record,
        std::path::Path::new(&source.file),
        &source,
    )?;
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
    // Row groups of SAMPLES_PER_GROUP samples (a fixed layout: same bytes for any thread
    // count); within a group the profiles are generated in parallel straight into `eta`.
    let labelled = generated.len() > 1;
    let progress = ctx.progress((ids.len() * generated.len()) as u64);
    let path = ctx.output_path(IRREGULARITY_FILE);
    let mut writer: Option<StreamWriter> = None;
    let mut summary = Vec::new();
    for (name, generator) in &generated {
        let n = generator.len();
        let x = generator.positions();
        for group in ids.chunks(SAMPLES_PER_GROUP) {
            let mut eta = vec![0.0; n * group.len()];
            eta.par_chunks_mut(n).zip(group).for_each(|(chunk, &id)| {
                generator.profile_into(id as u64, chunk);
                progress.inc(1);
            });
            let mut table = Table::default();
            if labelled {
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
            let w = match &mut writer {
                Some(w) => w,
                None => writer.insert(StreamWriter::create(&path, &table)?),
            };
            w.write(&table)?;
        }
        let band = generator.band();
        summary.push(format!(
            "{} profiles `{name}` x {n} points ({:.1} m at dx {} m), RMS {:.3} mm over {}-{} m wavelengths",
            ids.len(),
            n as f64 * generator.dx(),
            generator.dx(),
            generator.variance().sqrt() * 1e3,
            1.0 / band[1],
            1.0 / band[0],
        ));
    }
    pino_data::system::write_json(
        &ctx.output_path(PROFILES_FILE),
        &serde_json::to_value(controls)?,
    )?;
    match writer {
        Some(w) => w
            .finish()
            .with_context(|| format!("writing {}", path.display()))?,
        None => {
            // No generated profile: an empty table of the same columns.
            let mut t = Table::default();
            t.push(schema::SAMPLE_ID, Column::I64(Vec::new()))?;
            t.push(schema::TRACK_X, Column::F64(Vec::new()))?;
            t.push(schema::TRACK_ETA, Column::F64(Vec::new()))?;
            pino_data::write_parquet(&path, &t)?;
            summary.push("no generated profile in the description".to_owned());
        }
    }
    Ok(summary.join("; "))
}

fn main() {
    stage_kit::finish(run())
}
