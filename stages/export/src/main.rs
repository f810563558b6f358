//! `export`: a surrogate (or one trained model) with its calibration as one self-contained ONNX file
//! (`docs/export.md`), as a pipeline stage or from the command line.
//!
//! ```text
//! export [--context FILE]                         (a stage: input `surrogate`, or `models`
//!                                                  and `calibration`;
//!                                                  the context from PINO_STAGE_CONTEXT too)
//! export --surrogate DIR --out model.onnx
//! export --model DIR [--calibration DIR|calibration.json] --out model.onnx
//!        [--spectral matmul|dft] [--normaliser none|error_head] [--levels 0.8,0.9]
//!        [--indices NAME,NAME]
//! ```
//! The stage writes `model.onnx` into its output directory; its parameters are those of the
//! command line (`spectral`, `normaliser`, `levels`, `indices`) and `algorithm` (which model
//! when the input holds several). The file is written atomically; on the command line any
//! refusal (a model or calibration that does not load, a layer, index, normaliser or level
//! the graph cannot carry, a path that cannot be written) exits 2 and leaves no file.
use anyhow::{Context, Result};
use clap::Parser;
use onnx_export::{export, ExportParams, Summary};
use std::path::PathBuf;

/// The file the stage writes.
const FILE: &str = "model.onnx";

#[derive(Parser)]
#[command(
    name = "export",
    about = "Export a trained model with its intervals to ONNX"
)]
struct Args {
    /// The stage context (pipeline mode; without it and without --model, the context named
    /// by the environment, as the orchestrator starts a stage).
    #[arg(long, conflicts_with_all = ["model", "surrogate", "out"])]
    context: Option<PathBuf>,
    /// Surrogate directory (the `surrogate` stage's output).
    #[arg(long, requires = "out", conflicts_with_all = ["model", "calibration"])]
    surrogate: Option<PathBuf>,
    /// Model directory (model.safetensors + model.json from `train`): one model alone.
    #[arg(long, requires = "out")]
    model: Option<PathBuf>,
    /// Its calibration (the `calibrate` stage's output or a calibration.json); without it the
    /// file carries no interval and says so.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// The ONNX file to write.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Spectral layers: `matmul` (opset 13) or `dft` (opset 17).
    #[arg(long, default_value = "matmul")]
    spectral: String,
    /// Intervals' normaliser: `none` or `error_head` (heads on the parameters only).
    #[arg(long)]
    normaliser: Option<String>,
    /// Interval levels, comma-separated.
    #[arg(long, value_delimiter = ',')]
    levels: Option<Vec<f64>>,
    /// Only these indices, comma-separated.
    #[arg(long, value_delimiter = ',')]
    indices: Option<Vec<String>>,
}

fn line(s: &Summary, path: &std::path::Path) -> String {
    let intervals = match &s.no_intervals {
        Some(why) => format!("no intervals ({why})"),
        None => format!(
            "intervals at {:?} ({})",
            s.levels,
            s.normaliser.map_or("-", |n| n.as_str())
        ),
    };
    let left = if s.left_out.is_empty() {
        String::new()
    } else {
        let names: Vec<&str> = s.left_out.iter().map(|(n, _)| n.as_str()).collect();
        format!("; left out: {}", names.join(", "))
    };
    format!(
        "{}: {} channels, {} indices, {intervals}, {} nodes ({}){left}",
        path.display(),
        s.channels.len(),
        s.indices.len(),
        s.nodes,
        s.spectral.as_str()
    )
}

fn stage(context: Option<&std::path::Path>) -> Result<String> {
    let ctx = match context {
        Some(c) => stage_kit::StageContext::from_file(c)?,
        None => stage_kit::StageContext::load()?,
    };
    let p: ExportParams = ctx.params()?;
    onnx_export::Spectral::parse(&p.spectral)
        .with_context(|| format!("stage `{}`: bad parameters", ctx.stage))?;
    if ctx.is_check() {
        return Ok("parameters valid".into());
    }
    let spec = match ctx.optional_single_input_dir("surrogate")? {
        Some(dir) => p.surrogate_spec(&dir)?,
        None => {
            let models = ctx.input_dirs("models")?.to_vec();
            let calibration = ctx.optional_single_input_dir("calibration")?;
            p.spec(&models, calibration.as_deref())?
        }
    };
    let summary = export(&spec, &ctx.output_path(FILE))?;
    Ok(line(&summary, std::path::Path::new(FILE)))
}

fn command_line(args: &Args, out: &std::path::Path) -> Result<String> {
    let normaliser = args
        .normaliser
        .as_ref()
        .map(|n| serde_json::from_value(serde_json::Value::String(n.clone())))
        .transpose()
        .with_context(|| "--normaliser: allowed `none` or `error_head`")?;
    let p = ExportParams {
        spectral: args.spectral.clone(),
        normaliser,
        levels: args.levels.clone(),
        indices: args.indices.clone(),
        algorithm: None,
    };
    let spec = match (&args.surrogate, &args.model) {
        (Some(dir), _) => p.surrogate_spec(dir)?,
        (None, Some(model)) => p.spec(&[model.to_owned()], args.calibration.as_deref())?,
        (None, None) => anyhow::bail!("give --surrogate DIR or --model DIR"),
    };
    Ok(line(&export(&spec, out)?, out))
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    let args = Args::parse();
    match (args.model.is_some() || args.surrogate.is_some(), &args.out) {
        (true, Some(out)) => match command_line(&args, out) {
            Ok(text) => println!("{text}"),
            Err(e) => {
                eprintln!("export: {e:#}");
                std::process::exit(2);
            }
        },
        _ => stage_kit::finish(stage(args.context.as_deref())),
    }
}
