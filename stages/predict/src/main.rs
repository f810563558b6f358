//! `predict`: what an engineer exploring designs runs (not a pipeline stage).
//!
//! ```text
//! predict --model DIR [--params sets.yaml] [--set k_s=4e5 ...]
//!         (--profile irregularity.parquet [--profile-id ID] | --seed N [--profile-id ID])
//!         --out predictions.parquet [--x0 20] [--device cpu]
//! ```
//! Writes, for every parameter set, the 14 responses, their first and second derivatives and
//! the irregularity under the wheels at the model's time points, from one forward pass.
use anyhow::{Context, Result};
use clap::Parser;
use pino_learn::config::DeviceKind;
use pino_learn::predict::{
    apply_override, generated_profile, parse_param_sets, predict, read_profile, Placement,
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
    #[arg(long)]
    params: Option<PathBuf>,
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
    /// Output Parquet file.
    #[arg(long)]
    out: PathBuf,
    /// "cpu" or "cuda".
    #[arg(long, default_value = "cpu")]
    device: String,
}

fn run() -> Result<()> {
    pino_learn::tune_allocator();
    let args = Args::parse();
    let device = match args.device.as_str() {
        "cpu" => DeviceKind::Cpu,
        "cuda" => DeviceKind::Cuda,
        other => anyhow::bail!("--device {other}: allowed cpu or cuda"),
    }
    .device()?;
    let mut sets = match &args.params {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            parse_param_sets(&text, path)?
        }
        None => vec![vtcd_nominal()],
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
    pino_data::metadata::set_origin(origin(&args, &sets))?;
    let started = std::time::Instant::now();
    let (table, meta) = predict(&args.model, &sets, &profile, &place, &device)?;
    let wall = started.elapsed().as_secs_f64();
    pino_data::write_parquet(&args.out, &table)?;
    println!(
        "predicted {} set(s) x {:.3} s with algorithm {} in {wall:.3} s -> {}",
        sets.len(),
        meta.grid.t_points as f64 * meta.grid.dt,
        meta.train.algorithm.id(),
        args.out.display()
    );
    Ok(())
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

fn vtcd_nominal() -> pino_learn::predict::NominalParams {
    pino_learn::predict::NominalParams::NOMINAL
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    if let Err(e) = run() {
        eprintln!("predict: {e:#}");
        std::process::exit(1);
    }
}
