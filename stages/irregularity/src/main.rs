//! Stage `irregularity`: one vertical profile per sample (train and validation) by the
//! spectral random-phase method of `vtcd::irregularity`, written as `irregularity.parquet`:
//! `sample_id` (i64), `x` (m, `n dx`), `eta` (m, positive downward), sorted by sample then x.
//!
//! Input `params` (the sample ids of `params.parquet`). Params: `seed`, `dx`, `length`,
//! `wavelength_min`, `wavelength_max`, `psd` (see `vtcd::irregularity::IrregularityParams`).
//! Samples are generated in parallel; each depends only on `(seed, sample_id)`.

use anyhow::{bail, Context, Result};
use pino_data::{read_parquet_files, schema, write_parquet, Column, Table};
use rayon::prelude::*;
use vtcd::irregularity::IrregularityParams;

fn run() -> Result<String> {
    let ctx = stage_kit::StageContext::load()?;
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

    // Profiles are written straight into the `eta` column, one chunk per sample.
    let n = generator.len();
    let progress = ctx.progress(ids.len() as u64);
    let mut eta = vec![0.0; n * ids.len()];
    eta.par_chunks_mut(n).zip(&ids).for_each(|(chunk, &id)| {
        generator.profile_into(id as u64, chunk);
        progress.inc(1);
    });

    let mut table = Table::default();
    let sample_col = ids
        .iter()
        .flat_map(|&id| std::iter::repeat_n(id, n))
        .collect();
    table.push(schema::SAMPLE_ID, Column::I64(sample_col))?;
    table.push(
        schema::TRACK_X,
        Column::F64(generator.positions().repeat(ids.len())),
    )?;
    table.push(schema::TRACK_ETA, Column::F64(eta))?;
    let path = ctx.output_path("irregularity.parquet");
    write_parquet(&path, &table).with_context(|| format!("writing {}", path.display()))?;
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
    match run() {
        Ok(summary) => stage_kit::summary(&summary),
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::exit(1);
        }
    }
}
