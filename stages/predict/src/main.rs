//! `predict`: what an engineer exploring designs runs (not a pipeline stage).
//!
//! ```text
//! predict --model DIR [--params sets.yaml | --sweep sweep.yaml] [--set k_s=4e5 ...]
//!         (--profile irregularity.parquet [--profile-id ID] | --seed N [--profile-id ID])
//!         [--out predictions.parquet] [--indices indices.parquet [--indices-only]]
//!         [--strict] [--batch 16] [--x0 20] [--device cpu]
//! ```
//! Writes, for every parameter set, the 14 responses, the contact forces, their first and
//! second derivatives and the irregularity under the wheels at the model's time points
//! (`--out`), and/or the engineering indices of every set (`--indices`, docs/indices.md);
//! `--indices-only` skips the time histories. Sets come from `--params` (a list), `--sweep` (a
//! grid or a seeded random sample over ranges) and `--set` overrides. Every set outside the
//! model's training ranges is flagged (column `outside_training_range`) and warned about on
//! stderr; `--strict` refuses to predict any (exit 2).
use anyhow::{Context, Result};
use clap::Parser;
use pino_learn::config::DeviceKind;
use pino_learn::predict::{
    apply_override, generated_profile, indices_table, parse_param_sets, parse_sweep, read_profile,
    Placement, Predictor, OUTSIDE_COLUMN,
};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "predict",
    about = "Predict vehicle responses with a trained PINO-MBD model"
)]
struct Args {
    /// Model directory (model.safetensors + model.json from `train`).
    #[arg(long)]
    model: PathBuf,
    /// YAML parameter sets: a list of maps (or `sets: [...]`) of parameter names to values;
    /// missing names take the CRH380 nominal values.
    #[arg(long, conflicts_with = "sweep")]
    params: Option<PathBuf>,
    /// YAML sweep: `base: {..}` and `grid: {name: [values] | {from, to, steps}, ..}` (every
    /// combination) or `random: {seed, count, ranges: {name: [lo, hi], ..}}`.
    #[arg(long)]
    sweep: Option<PathBuf>,
    /// Override `name=value` for every set (repeatable); alone, it varies the nominal set.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    sets: Vec<String>,
    /// Irregularity profile Parquet with columns `x`, `eta` (m), e.g. the `irregularity` artifact.
    #[arg(long, conflicts_with = "seed")]
    profile: Option<PathBuf>,
    /// Generate the profile with the `irregularity` stage's defaults and this seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Sample id of the profile (in a multi-profile file, or of the generated stream).
    #[arg(long)]
    profile_id: Option<i64>,
    /// Rear-wheel position at t = 0 (m), as in `simulate`.
    #[arg(long, default_value_t = 20.0)]
    x0: f64,
    /// Time histories of every set (Parquet).
    #[arg(long, required_unless_present = "indices")]
    out: Option<PathBuf>,
    /// Engineering indices of every set (Parquet, one row per set).
    #[arg(long)]
    indices: Option<PathBuf>,
    /// Only the indices: no time histories.
    #[arg(long, requires = "indices", conflicts_with = "out")]
    indices_only: bool,
    /// Refuse (exit 2) any set outside the model's training ranges.
    #[arg(long)]
    strict: bool,
    /// Sets per forward pass (batches run side by side on the CPU).
    #[arg(long, default_value_t = 16)]
    batch: usize,
    /// "cpu" or "cuda".
    #[arg(long, default_value = "cpu")]
    device: String,
}

/// A refusal under `--strict` (exit 2).
#[derive(Debug)]
struct Refused(String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Refused {}

fn run() -> Result<()> {
    pino_learn::tune_allocator();
    let args = Args::parse();
    let device = match args.device.as_str() {
        "cpu" => DeviceKind::Cpu,
        "cuda" => DeviceKind::Cuda,
        other => anyhow::bail!("--device {other}: allowed cpu or cuda"),
    }
    .device()?;
    let read = |path: &PathBuf| {
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
    };
    let mut sets = match (&args.params, &args.sweep) {
        (Some(path), _) => parse_param_sets(&read(path)?, path)?,
        (None, Some(path)) => parse_sweep(&read(path)?, path)?,
        (None, None) => vec![vtcd_nominal()],
    };
    for s in &args.sets {
        apply_override(&mut sets, s)?;
    }
    let profile = match (&args.profile, args.seed) {
        (Some(path), _) => read_profile(path, args.profile_id)?,
        (None, Some(seed)) => generated_profile(seed, args.profile_id.unwrap_or(0).max(0) as u64)?,
        (None, None) => anyhow::bail!("give an irregularity: --profile FILE or --seed N"),
    };
    let place = Placement {
        x0: args.x0,
        ..Placement::default()
    };
    let predictor = Predictor::load(&args.model, &device)?;
    let meta = &predictor.meta;
    // Where the model was trained: flag, warn, or refuse under --strict.
    let outside = predictor.outside_training(&sets);
    let flagged: Vec<usize> = (0..sets.len())
        .filter(|&k| !outside[k].is_empty())
        .collect();
    let ranges = meta.training_ranges.as_ref();
    if ranges.is_none() {
        let msg = format!(
            "{}: the model records no training ranges (trained before they were stored): its designs cannot be checked",
            args.model.join("model.json").display()
        );
        if args.strict {
            return Err(Refused(format!("--strict: {msg}")).into());
        }
        eprintln!("predict: warning: {msg}");
    }
    if !flagged.is_empty() {
        let shown: Vec<String> = flagged
            .iter()
            .take(5)
            .map(|&k| {
                let what: Vec<String> = outside[k].iter().map(|o| o.to_string()).collect();
                format!("set {k}: {}", what.join(", "))
            })
            .collect();
        let msg = format!(
            "{} of {} set(s) outside the model's training ranges (from {}), where its predictions are extrapolations: {}{}",
            flagged.len(),
            sets.len(),
            ranges.map_or("-", |r| r.source.as_str()),
            shown.join("; "),
            if flagged.len() > 5 { "; ..." } else { "" }
        );
        if args.strict {
            return Err(Refused(format!("--strict: refused: {msg}")).into());
        }
        eprintln!("predict: warning: {msg} (flagged in column `{OUTSIDE_COLUMN}`)");
    }
    let flags: Vec<String> = outside
        .iter()
        .map(|o| pino_learn::predict::outside_flag(o))
        .collect();
    pino_data::metadata::set_origin(origin(&args, &sets))?;
    let started = std::time::Instant::now();
    let mut wrote = Vec::new();
    if let (Some(out), false) = (&args.out, args.indices_only) {
        let mut table = predictor.histories(&sets, &profile, &place, args.batch)?;
        let per_row = (table.num_rows() / sets.len().max(1)).max(1);
        let rows: Vec<String> = flags
            .iter()
            .flat_map(|f| std::iter::repeat_n(f.clone(), per_row))
            .collect();
        table.push(OUTSIDE_COLUMN, pino_data::Column::Str(rows))?;
        pino_data::write_parquet(out, &table)?;
        wrote.push(out.display().to_string());
    }
    if let Some(path) = &args.indices {
        let cfg = predictor.index_config()?;
        let ix = predictor.indices(&sets, &profile, &place, &cfg, args.batch)?;
        let table = indices_table(&sets, &ix, &outside, &cfg)?;
        pino_data::write_parquet(path, &table)?;
        wrote.push(path.display().to_string());
    }
    let wall = started.elapsed().as_secs_f64();
    println!(
        "predicted {} set(s) x {:.3} s with algorithm {} in {wall:.3} s ({} outside the training ranges) -> {}",
        sets.len(),
        meta.grid.t_points as f64 * meta.grid.dt,
        meta.train.algorithm.id(),
        flagged.len(),
        wrote.join(", ")
    );
    Ok(())
}

fn vtcd_nominal() -> pino_learn::predict::NominalParams {
    pino_learn::predict::NominalParams::NOMINAL
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    if let Err(e) = run() {
        eprintln!("predict: {e:#}");
        let code = if e.downcast_ref::<Refused>().is_some() {
            2
        } else {
            1
        };
        std::process::exit(code);
    }
}

/// The origin written into the output: stage and unit `predict`, and as parameters the
/// resolved parameter sets and everything else that decides the numbers (the model directory
/// as given, the profile's source, the placement, the device).
fn origin(args: &Args, sets: &[pino_learn::predict::NominalParams]) -> pino_data::metadata::Origin {
    let sets: Vec<serde_json::Value> = sets
        .iter()
        .map(|p| {
            let values = p.to_array();
            serde_json::Value::Object(
                pino_data::schema::PARAMETERS
                    .iter()
                    .zip(values)
                    .map(|(name, v)| (name.to_string(), serde_json::Value::from(v)))
                    .collect(),
            )
        })
        .collect();
    let params = serde_json::json!({
        "model": args.model.display().to_string(),
        "sets": sets,
        "profile": args.profile.as_ref().map(|p| p.display().to_string()),
        "seed": args.seed,
        "profile_id": args.profile_id,
        "x0": args.x0,
        "device": args.device,
    });
    pino_data::metadata::Origin::stage_unit("predict", 0, 1, &params)
}
