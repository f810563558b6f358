//! `predict`: what an engineer exploring designs runs (not a pipeline stage).
//!
//! ```text
//! predict --surrogate DIR | --model DIR [--calibration DIR|calibration.json]
//!         [--params sets.yaml | --sweep sweep.yaml] [--set NAME=VALUE ...]
//!         [--profile profiles.parquet [--profile-id ID] | --seed N [--profile-id ID]]
//!         [--out predictions.parquet] [--indices indices.parquet [--indices-only]]
//!         [--coverage 0.9] [--strict] [--batch 16] [--x0 X] [--device cpu]
//! ```
//! `--surrogate` reads the `surrogate` stage's output: every index and channel answered by the
//! model chosen for it, with that model's calibration; `--model` one trained model alone.
//! Works for the model of any system description: the design parameters are the sampled
//! parameters of the description stored in the model (the others keep its values), the outputs
//! its channels. Writes, for every design, the model's outputs (displacements and forces), the
//! rigid DOFs' first and second derivatives and the excitations at the model's time points
//! (`--out`), and/or the description's engineering indices of every design (`--indices`,
//! docs/indices.md); `--indices-only` skips the time histories. Designs come from `--params` (a
//! list), `--sweep` (a grid or a seeded random sample over ranges) and `--set` overrides; none:
//! the nominal design. A description with generated profiles needs their points: a profile file
//! (`--profile`, the `irregularity` artifact) or a seed to generate them with the dataset's
//! settings (`--seed`). Every design outside the model's training ranges is flagged (column
//! `outside_training_range`) and warned about on stderr; `--strict` refuses to predict any
//! (exit 2). With `--calibration` (the `calibrate` stage's output or one model's
//! `calibration.json`, docs/uncertainty.md) every answer carries its conformal interval at
//! `--coverage`: `<index>_lo`, `<index>_hi` and a three-valued verdict per limit
//! (`<index>_verdict`, `verdict`: pass, fail, or uncertain: ask the solver) in `--indices`,
//! `<channel>_lo`, `<channel>_hi` bands in `--out`; designs outside the training ranges are
//! `extrapolated` and never `pass`. A calibration of another model, a corrupt file or a level
//! the calibration cannot support is refused before anything is written (exit 2).
use anyhow::{Context, Result};
use clap::Parser;
use pino_learn::config::DeviceKind;
use pino_predict::{
    outside_message, DesignSource, DesignSpace, Predictor, ProfileChoice, ProfileSource,
    OUTSIDE_COLUMN,
};
use pino_surrogate::Surrogate;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "predict",
    about = "Predict the responses of designs with a trained PINO-MBD model"
)]
struct Args {
    /// Surrogate directory (the `surrogate` stage's output: surrogate.json and its models).
    #[arg(long, required_unless_present = "model", conflicts_with_all = ["model", "calibration"])]
    surrogate: Option<PathBuf>,
    /// Model directory (model.safetensors + model.json from `train`): one model alone.
    #[arg(long)]
    model: Option<PathBuf>,
    /// YAML designs: a list of maps (or `sets: [...]`) of parameter names to values; missing
    /// names take the nominal values of the model's system description.
    #[arg(long, conflicts_with = "sweep")]
    params: Option<PathBuf>,
    /// YAML sweep: `base: {..}` and `grid: {name: [values] | {from, to, steps}, ..}` (every
    /// combination) or `random: {seed, count, ranges: {name: [lo, hi], ..}}`.
    #[arg(long)]
    sweep: Option<PathBuf>,
    /// Override `name=value` for every set (repeatable); alone, it varies the nominal set.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    sets: Vec<String>,
    /// Profile Parquet with columns `x`, `eta` (m) (and `sample_id`, `profile` to choose
    /// rows), e.g. the `irregularity` artifact.
    #[arg(long, conflicts_with = "seed")]
    profile: Option<PathBuf>,
    /// Generate the profiles as `irregularity` does, with the model's dataset's spacing and
    /// length and this seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Sample id of the profile (the rows of a file, or the generated stream).
    #[arg(long)]
    profile_id: Option<i64>,
    /// Position of the moving frame at t = 0 (m); default: the model's simulation's.
    #[arg(long)]
    x0: Option<f64>,
    /// Time histories of every set (Parquet).
    #[arg(long, required_unless_present = "indices")]
    out: Option<PathBuf>,
    /// Engineering indices of every set (Parquet, one row per set).
    #[arg(long)]
    indices: Option<PathBuf>,
    /// Only the indices: no time histories.
    #[arg(long, requires = "indices", conflicts_with = "out")]
    indices_only: bool,
    /// The model's calibration: the `calibrate` stage's output directory (the model's own
    /// file is found in it) or a `calibration.json`.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Coverage of the intervals, in (0, 1) and at most n / (n + 1) for n calibration samples.
    #[arg(long)]
    coverage: Option<f64>,
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
    let (surrogate, coverage) = load(&args)?;
    let predictor = surrogate.primary();
    let sets = designs(&args, &predictor.space)?;
    if let Some(id) = args.profile_id.filter(|id| *id < 0) {
        anyhow::bail!("--profile-id {id}: sample ids are >= 0");
    }
    let choice = ProfileChoice::of(args.profile.as_deref(), args.seed, args.profile_id);
    let profiles = predictor.profiles(choice.as_ref())?;
    let run_config = predictor.run_config(args.x0)?;
    let meta = &predictor.meta;
    // Where the model was trained: flag, warn, or refuse under --strict.
    let outside = predictor.outside_training(&sets)?;
    if let Some(msg) = outside_message(&outside, &meta.training_ranges.source) {
        if args.strict {
            return Err(Refused(format!("--strict: refused: {msg}")).into());
        }
        eprintln!("predict: warning: {msg} (flagged in column `{OUTSIDE_COLUMN}`)");
    }
    pino_data::metadata::set_origin(origin(&args, predictor.space.names(), &sets, &run_config))?;
    let started = std::time::Instant::now();
    let mut wrote = Vec::new();
    let profiles = ProfileSource::Shared(&profiles);
    if let (Some(out), false) = (&args.out, args.indices_only) {
        let table =
            surrogate.histories_flagged(&sets, &profiles, &run_config, args.batch, coverage)?;
        pino_data::write_parquet(out, &table)?;
        wrote.push(out.display().to_string());
    }
    if let Some(path) = &args.indices {
        let cfg = predictor.index_config()?;
        let level = coverage.unwrap_or(pino_calibration::DEFAULT_COVERAGE);
        let answers = surrogate.answers(&sets, &profiles, &run_config, &cfg, args.batch, level)?;
        let table = surrogate.indices_table(&sets, &answers, &outside)?;
        pino_data::write_parquet(path, &table)?;
        wrote.push(path.display().to_string());
    }
    let wall = started.elapsed().as_secs_f64();
    println!(
        "predicted {} set(s) x {:.3} s with {} in {wall:.3} s ({} outside the training ranges) -> {}",
        sets.len(),
        meta.grid.t_points as f64 * meta.grid.dt,
        surrogate.member_names().join(" + "),
        outside.iter().filter(|o| !o.is_empty()).count(),
        wrote.join(", ")
    );
    Ok(())
}

/// The designs of `--params` or `--sweep` (else the nominal design) with every `--set`.
fn designs(args: &Args, space: &DesignSpace) -> Result<Vec<Vec<f64>>> {
    let read = |path: &PathBuf| {
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
    };
    let text;
    let source = match (&args.params, &args.sweep) {
        (Some(path), _) => {
            text = read(path)?;
            DesignSource::Sets(&text, path)
        }
        (None, Some(path)) => {
            text = read(path)?;
            DesignSource::Sweep(&text, path)
        }
        (None, None) => DesignSource::Nominal,
    };
    Ok(space.designs(source, &args.sets)?)
}

/// Loads `--surrogate`, or `--model` with its `--calibration`, and checks `--coverage` against
/// the calibrations, before anything is predicted or written: the surrogate and the level of
/// its intervals (`None`: the answers carry none, and stderr says why). Every refusal of a
/// file or level is [`Refused`] (exit 2).
fn load(args: &Args) -> Result<(Surrogate, Option<f64>)> {
    let device = &match args.device.as_str() {
        "cpu" => DeviceKind::Cpu,
        "cuda" => DeviceKind::Cuda,
        other => anyhow::bail!("--device {other}: allowed cpu or cuda"),
    }
    .device()?;
    let surrogate = match (&args.surrogate, &args.model) {
        (Some(dir), _) => Surrogate::load(dir, device)
            .map_err(|e| Refused(format!("--surrogate {}: {e}", dir.display())))?,
        (None, Some(dir)) => {
            let mut predictor = Predictor::load(dir, device)
                .map_err(|e| Refused(format!("--model {}: {e}", dir.display())))?;
            let Some(path) = &args.calibration else {
                eprintln!(
                    "predict: note: no --calibration: the answers are point values without an error bar (pass the `calibrate` stage's output, or a --surrogate; docs/uncertainty.md)"
                );
                return Ok((Surrogate::of_model(predictor), None));
            };
            let cal = predictor
                .load_calibration(path)
                .map_err(|e| Refused(format!("--calibration {}: {e}", path.display())))?;
            if let Some(why) = &cal.no_intervals {
                eprintln!("predict: note: {}: no intervals: {why}", path.display());
                return Ok((Surrogate::of_model(predictor), None));
            }
            Surrogate::of_model(predictor)
        }
        (None, None) => anyhow::bail!("give --surrogate DIR or --model DIR"),
    };
    let level = surrogate.interval_level(args.coverage).map_err(|e| {
        let level = args.coverage.unwrap_or(pino_calibration::DEFAULT_COVERAGE);
        Refused(format!("--coverage {level}: {e}"))
    })?;
    if level.is_none() {
        eprintln!(
            "predict: note: {} carries no intervals: the answers are point values without an error bar",
            surrogate.member_names().join(" + ")
        );
        if let Some(c) = args.coverage {
            return Err(Refused(format!(
                "--coverage {c}: the model has no calibration with intervals"
            ))
            .into());
        }
    }
    Ok((surrogate, level))
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
/// resolved designs and everything else that decides the numbers (the model directory as
/// given, the profile's source, the run controls, the device).
fn origin(
    args: &Args,
    names: &[String],
    sets: &[Vec<f64>],
    run: &mbd_engine::RunConfig,
) -> pino_data::metadata::Origin {
    let sets: Vec<serde_json::Value> = sets
        .iter()
        .map(|p| {
            serde_json::Value::Object(
                names
                    .iter()
                    .zip(p)
                    .map(|(name, v)| (name.clone(), serde_json::Value::from(*v)))
                    .collect(),
            )
        })
        .collect();
    let params = serde_json::json!({
        "model": args.model.as_ref().map(|p| p.display().to_string()),
        "surrogate": args.surrogate.as_ref().map(|p| p.display().to_string()),
        "sets": sets,
        "profile": args.profile.as_ref().map(|p| p.display().to_string()),
        "seed": args.seed,
        "profile_id": args.profile_id,
        "run": run,
        "device": args.device,
    });
    pino_data::metadata::Origin::stage_unit("predict", 0, 1, &params)
}
