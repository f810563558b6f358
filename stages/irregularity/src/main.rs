//! Stage `irregularity`: one vertical profile per sample (every split) by the
//! spectral random-phase method of `vtcd::irregularity`, written as `irregularity.parquet`:
//! `sample_id` (i64), `x` (m, `n dx`), `eta` (m, positive downward), sorted by sample then x.
//!
//! Input `params` (the sample ids of `params.parquet`). Params: `seed`, `dx`, `length`,
//! `wavelength_min`, `wavelength_max`, `psd` (see `vtcd::irregularity::IrregularityParams`).
//! Samples are generated in parallel; each depends only on `(seed, sample_id)`.

use anyhow::{bail, Context, Result};
use pino_data::{read_parquet_files, schema, Column, StreamWriter, Table};
use rayon::prelude::*;
use vtcd::irregularity::IrregularityParams;

/// Samples per Parquet row group (64 x 5400 points at the defaults: 2.8 MB per column).
const SAMPLES_PER_GROUP: usize = 64;

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
    pino_data::metadata::set_stage_origin(&ctx)?;
    let raw: IrregularityParams = ctx.params()?;
    let generator = raw
        .validate()
        .with_context(|| format!("stage `{}`: bad irregularity parameters", ctx.stage))?;
    let files = ctx.input_files("params", "params.parquet")?;
    if files.is_empty() {
        bail!(
            "input `params` has no params.parquet (in {:?})",
            ctx.input_dirs("params")?
        );
    }
    let params = read_parquet_files(&files, Some(&[schema::SAMPLE_ID]))?;
    let mut ids = params.i64(schema::SAMPLE_ID)?.to_vec();
    ids.sort_unstable();
    if let Some(bad) = ids.iter().find(|&&id| id < 0) {
        bail!("{}: negative sample_id {bad}", files[0].display());
    }
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        bail!("{}: sample_id {} appears twice", files[0].display(), w[0]);
    }

    // Row groups of SAMPLES_PER_GROUP samples (a fixed layout: same bytes for any thread
    // count); within a group the profiles are generated in parallel straight into `eta`.
    let n = generator.len();
    let progress = ctx.progress(ids.len() as u64);
    let path = ctx.output_path("irregularity.parquet");
    let x = generator.positions();
    let mut writer = None;
    for group in ids.chunks(SAMPLES_PER_GROUP) {
        let mut eta = vec![0.0; n * group.len()];
        eta.par_chunks_mut(n).zip(group).for_each(|(chunk, &id)| {
            generator.profile_into(id as u64, chunk);
            progress.inc(1);
        });
        let mut table = Table::default();
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
    writer
        .context("no samples in params.parquet")?
        .finish()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(format!(
        "{} profiles x {n} points ({:.1} m at dx {} m), RMS {:.3} mm over {}-{} m wavelengths",
        ids.len(),
        n as f64 * generator.dx(),
        generator.dx(),
        generator.variance().sqrt() * 1e3,
        raw.wavelength_min,
        raw.wavelength_max,
    ))
}

fn main() {
    stage_kit::finish(run())
}
