//! `explore`: the design explorer (docs/explore.md), a web page on which an engineer moves a
//! trained model's parameters and sees its responses, indices and the exact solver's verdict.
//!
//! ```text
//! explore [-C DIR] [-f pipeline.yaml] [--algorithm N]     # the workspace's current surrogate
//! explore --surrogate DIR [--params params.parquet --profiles irregularity.parquet]
//! explore --model DIR [--params ... --profiles ...] [--calibration calibration.json|DIR]
//!         [--bind 127.0.0.1:8750] [--token T] [--allow-host NAME]...
//!         [--solve-workers 1] [--solve-queue 4] [--solve-max-duration 30] [--sweep-max 400]
//!         [--header-timeout 10] [--body-timeout 10] [--max-connections 512]
//!         [--study-dir explore-studies] [--study-threads N]
//! ```
//! Prints `explore: serving ... on http://ADDR/` (the real port for `--bind HOST:0`) and serves
//! until interrupted. Without `--model` or `--surrogate` it serves the pipeline's surrogate
//! (the output of its `surrogate` stage, each member with its calibration), or with
//! `--algorithm N` (or when the pipeline builds no surrogate) the model of that algorithm with
//! the pipeline's `calibrate` output; a surrogate or calibration that is missing, corrupt, changed
//! or of another model is refused at startup, naming the file (exit 2).
use anyhow::{bail, Context, Result};
use clap::Parser;
use orchestrator::spec::Pipeline;
use pino_explore::access::is_loopback;
use pino_explore::glance::{locate, locate_surrogate, DEFAULT_ALGORITHM};
use pino_explore::serve::{serve, ConnectionLimits};
use pino_explore::server::{router, Access, App, SolveGate, MIN_TOKEN_CHARS};
use pino_explore::session::{DatasetFiles, Explorer, Limits};
use pino_explore::studies::Studies;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

/// The default directory of the studies started from the sweep view, in the workspace.
const STUDY_DIR: &str = "explore-studies";

#[derive(Parser)]
#[command(
    name = "explore",
    about = "Serve the design explorer of a trained PINO-MBD model"
)]
struct Args {
    /// Workspace root (default: the current directory).
    #[arg(short = 'C', long = "workspace", value_name = "DIR")]
    workspace: Option<PathBuf>,
    /// Pipeline file whose model (and pipeline at a glance) to serve, relative to the workspace.
    #[arg(short = 'f', long = "file", default_value = "pipeline.yaml")]
    file: PathBuf,
    /// Directory of the stage binaries (as `pipeline --bin-dir`; identities hash them).
    #[arg(long, value_name = "DIR")]
    bin_dir: Option<PathBuf>,
    /// Override a pipeline parameter as `pipeline --set` does (STAGE.KEY=VALUE): the same
    /// overrides the run was made with find its units fresh.
    #[arg(long = "set", value_name = "STAGE.KEY=VALUE")]
    sets: Vec<String>,
    /// Serve the pipeline's model of this algorithm instead of its surrogate (the default
    /// when the pipeline builds no surrogate: 5).
    #[arg(long)]
    algorithm: Option<i64>,
    /// A surrogate directory (the `surrogate` stage's output) instead of the pipeline's.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["model", "calibration", "algorithm"])]
    surrogate: Option<PathBuf>,
    /// A model directory (model.safetensors + model.json) instead of the pipeline's.
    #[arg(long, value_name = "DIR", conflicts_with = "algorithm")]
    model: Option<PathBuf>,
    /// With --model or --surrogate: the dataset's `params.parquet` (test samples and their
    /// designs).
    #[arg(long, value_name = "FILE")]
    params: Vec<PathBuf>,
    /// With --model or --surrogate: the dataset's `irregularity.parquet` (the test samples'
    /// profiles).
    #[arg(long, value_name = "FILE")]
    profiles: Vec<PathBuf>,
    /// The model's calibration (a `calibration.json`, or the `calibrate` stage's output
    /// directory): the answers' intervals and verdicts (default without --model: the
    /// pipeline's `calibrate` output).
    #[arg(long, value_name = "FILE|DIR")]
    calibration: Option<PathBuf>,
    /// Address to serve on; port 0 takes any free port.
    #[arg(long, default_value = "127.0.0.1:8750")]
    bind: SocketAddr,
    /// Token required on every request, at least 16 characters (default: none on a loopback
    /// address, beyond it a random one of 32, printed in the URL).
    #[arg(long)]
    token: Option<String>,
    /// More `Host` names to answer to (DNS-rebinding protection answers only the bound
    /// address and localhost otherwise).
    #[arg(long = "allow-host", value_name = "NAME")]
    allow_hosts: Vec<String>,
    /// Solves run at once.
    #[arg(long, default_value_t = 1)]
    solve_workers: usize,
    /// Solves waiting beyond those; more are answered 429.
    #[arg(long, default_value_t = 4)]
    solve_queue: usize,
    /// Longest simulated run a solve may take (s).
    #[arg(long, default_value_t = Limits::default().solve_max_duration_s)]
    solve_max_duration: f64,
    /// Most designs in one sweep.
    #[arg(long, default_value_t = Limits::default().sweep_max_designs)]
    sweep_max: usize,
    /// Longest wait for a request's head, and the idle time after which a kept-alive
    /// connection is closed (s).
    #[arg(long, default_value_t = ConnectionLimits::default().header_timeout.as_secs_f64())]
    header_timeout: f64,
    /// Longest wait for a request's body after its head (s); a body later is answered 408
    /// and its connection closed.
    #[arg(long, default_value_t = ConnectionLimits::default().body_timeout.as_secs_f64())]
    body_timeout: f64,
    /// Most open connections; a new one beyond is closed at once.
    #[arg(long, default_value_t = ConnectionLimits::default().max_connections)]
    max_connections: usize,
    /// Where studies started from the sweep view are written (default: `explore-studies`
    /// in the workspace); the Studies page lists those of earlier sessions too.
    #[arg(long, value_name = "DIR")]
    study_dir: Option<PathBuf>,
    /// Threads a started study runs on (default: the machine's cores but one, at least one),
    /// at a lower CPU priority: predictions and solves never wait for it.
    #[arg(long, value_name = "N")]
    study_threads: Option<usize>,
}

/// A refusal of the command line's inputs (a calibration missing, corrupt or of another
/// model): exit 2.
#[derive(Debug)]
struct Refused(String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Refused {}

fn random_token() -> Result<String> {
    use std::io::Read;
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .context("reading /dev/urandom for a token (give one with --token)")?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Refuses flags out of their ranges (a token too short: exit 2) and returns the connection
/// limits they set.
fn checked_limits(args: &Args) -> Result<ConnectionLimits> {
    if !(args.solve_max_duration.is_finite() && args.solve_max_duration > 0.0) {
        bail!(
            "--solve-max-duration {}: allowed a positive number of seconds",
            args.solve_max_duration
        );
    }
    if !(2..=100_000).contains(&args.sweep_max) {
        bail!("--sweep-max {}: allowed 2..=100000", args.sweep_max);
    }
    for (flag, s) in [
        ("--header-timeout", args.header_timeout),
        ("--body-timeout", args.body_timeout),
    ] {
        if !(s.is_finite() && (0.1..=3600.0).contains(&s)) {
            bail!("{flag} {s}: allowed 0.1 to 3600 seconds");
        }
    }
    if args.study_threads.is_some_and(|n| !(1..=1024).contains(&n)) {
        bail!(
            "--study-threads {}: allowed 1..=1024",
            args.study_threads.unwrap_or(0)
        );
    }
    if !(1..=1_000_000).contains(&args.max_connections) {
        bail!(
            "--max-connections {}: allowed 1..=1000000",
            args.max_connections
        );
    }
    if let Some(t) = &args.token {
        if t.chars().count() < MIN_TOKEN_CHARS {
            return Err(Refused(format!(
                "--token: {} characters; allowed: at least {MIN_TOKEN_CHARS} (or leave it out for a random one)",
                t.chars().count()
            ))
            .into());
        }
    }
    Ok(ConnectionLimits {
        header_timeout: std::time::Duration::from_secs_f64(args.header_timeout),
        max_connections: args.max_connections,
        body_timeout: std::time::Duration::from_secs_f64(args.body_timeout),
    })
}

/// The token of a server bound at `addr`: the one given, required on every request whatever
/// the address; else none on a loopback address and a random one beyond (with a warning).
fn token_for(args: &Args, addr: SocketAddr) -> Result<Option<String>> {
    let loopback = is_loopback(addr.ip());
    if !loopback {
        eprintln!(
            "explore: warning: serving on {addr}, beyond this machine's loopback: anyone who can reach it and has the token can use the model and the solver"
        );
    }
    Ok(match (&args.token, loopback) {
        (Some(t), _) => Some(t.clone()),
        (None, true) => None,
        (None, false) => Some(random_token()?),
    })
}

/// The studies started from the page: in `--study-dir` (default: `explore-studies` in the
/// workspace), each on `--study-threads` threads (default: the machine's cores but one, so a
/// core is always free for the page's requests; BENCHMARKS.md, "Explorer").
fn studies(args: &Args, workspace: &std::path::Path) -> Studies {
    Studies::open(
        args.study_dir
            .clone()
            .unwrap_or_else(|| workspace.join(STUDY_DIR)),
        args.study_threads.unwrap_or_else(|| {
            std::thread::available_parallelism()
                .map_or(1, |n| n.get().saturating_sub(1))
                .max(1)
        }),
    )
}

/// The URL printed for a server bound at `addr` (`localhost` for every interface), with the
/// token when there is one.
fn url_of(addr: SocketAddr, token: Option<&str>) -> String {
    let shown = if addr.ip().is_unspecified() {
        format!("localhost:{}", addr.port())
    } else {
        addr.to_string()
    };
    match token {
        Some(t) => format!("http://{shown}/?token={t}"),
        None => format!("http://{shown}/"),
    }
}

/// Opens what the command line names: `--surrogate`, `--model` (with `--calibration`), else
/// the pipeline's surrogate, or its model of `--algorithm` with its calibration.
fn open(args: &Args, pipeline: Option<&Pipeline>, limits: Limits) -> Result<Explorer> {
    let given = DatasetFiles {
        params: args.params.clone(),
        profiles: args.profiles.clone(),
    };
    if let Some(dir) = &args.surrogate {
        eprintln!("explore: opening the surrogate {} ...", dir.display());
        return Explorer::open_surrogate(dir, given, limits)
            .map_err(|e| Refused(format!("surrogate {}: {e}", dir.display())).into());
    }
    let (model_dir, dataset, what, calibration) = match (&args.model, pipeline) {
        (Some(dir), _) => (
            dir.clone(),
            given,
            dir.display().to_string(),
            Err(pino_explore::session::NO_CALIBRATION.to_owned()),
        ),
        (None, Some(p)) => {
            if args.algorithm.is_none() {
                if let Some(found) = locate_surrogate(p) {
                    let (dir, dataset) = found.map_err(anyhow::Error::msg)?;
                    eprintln!("explore: opening the surrogate of {} ...", p.file);
                    return Explorer::open_surrogate(&dir, dataset, limits)
                        .map_err(|e| Refused(format!("surrogate {}: {e}", dir.display())).into());
                }
            }
            let found = locate(p, args.algorithm.unwrap_or(DEFAULT_ALGORITHM))
                .map_err(anyhow::Error::msg)?;
            (
                found.model_dir,
                found.dataset,
                format!("{} of {}", found.unit, p.file),
                found.calibration,
            )
        }
        (None, None) => {
            bail!("no model: give --surrogate DIR, --model DIR or a pipeline file with -f")
        }
    };
    let calibration = match &args.calibration {
        Some(path) => Ok(path.clone()),
        None => calibration,
    };
    eprintln!("explore: opening {what} ...");
    let mut explorer = Explorer::open(&model_dir, dataset, limits)
        .with_context(|| format!("opening the model {}", model_dir.display()))?;
    attach_calibration(&mut explorer, calibration)?;
    Ok(explorer)
}

/// Loads the model's calibration into `explorer` (a refusal is [`Refused`]), or records why
/// there is none; says on stderr which.
fn attach_calibration(explorer: &mut Explorer, calibration: Result<PathBuf, String>) -> Result<()> {
    match calibration {
        Ok(path) => {
            explorer
                .load_calibration(&path)
                .map_err(|e| Refused(e.to_string()))?;
            match explorer.calibration_note() {
                Some(note) => eprintln!("explore: note: {note}"),
                None => eprintln!("explore: intervals from the calibration {}", path.display()),
            }
        }
        Err(why) => {
            eprintln!("explore: note: {why}");
            explorer.no_calibration(why);
        }
    }
    Ok(())
}

async fn run(args: Args) -> Result<()> {
    let connections = checked_limits(&args)?;
    let workspace = args.workspace.clone().unwrap_or_else(|| PathBuf::from("."));
    let file = workspace.join(&args.file);
    let opts = orchestrator::spec::LoadOptions {
        bin_dir: args.bin_dir.clone().or_else(|| {
            std::env::var_os("PINO_BIN_DIR")
                .filter(|v| !v.is_empty())
                .map(PathBuf::from)
        }),
        sets: args.sets.clone(),
    };
    // The pipeline file: where the model comes from (without --model) and the glance page.
    let given = args.model.is_some() || args.surrogate.is_some();
    if !given && (!args.params.is_empty() || !args.profiles.is_empty()) {
        bail!("--params and --profiles go with --model or --surrogate (the pipeline's dataset is found by itself)");
    }
    let pipeline = if !given || file.is_file() {
        Some(
            orchestrator::spec::Pipeline::load(&workspace, &file, &opts)
                .with_context(|| format!("loading {}", file.display()))?,
        )
    } else {
        None
    };
    let limits = Limits {
        solve_max_duration_s: args.solve_max_duration,
        sweep_max_designs: args.sweep_max,
        ..Limits::default()
    };
    let explorer = open(&args, pipeline.as_ref(), limits)?;
    let listener = tokio::net::TcpListener::bind(args.bind)
        .await
        .with_context(|| format!("binding {}", args.bind))?;
    let addr = listener.local_addr().context("reading the bound address")?;
    let token = token_for(&args, addr)?;
    let access = Access::new(addr, token.clone(), &args.allow_hosts);
    let app = Arc::new(App {
        explorer: Arc::new(explorer),
        pipeline: pipeline.map(Arc::new),
        access,
        solves: Arc::new(SolveGate::new(args.solve_workers, args.solve_queue)),
        studies: Arc::new(studies(&args, &workspace)),
        body_timeout: connections.body_timeout,
    });
    let url = url_of(addr, token.as_deref());
    println!(
        "explore: serving the {} model ({}) on {url}",
        app.explorer.identity().system,
        app.explorer.model_dir().display()
    );
    use std::io::Write;
    std::io::stdout().flush().ok();
    serve(listener, router(app), connections, async {
        let _ = tokio::signal::ctrl_c().await;
    })
    .await;
    Ok(())
}

fn main() {
    pino_learn::candle_single_threaded_by_default();
    pino_learn::tune_allocator();
    let args = Args::parse();
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("explore: starting the runtime: {e}");
            std::process::exit(1);
        }
    };
    if let Err(e) = rt.block_on(run(args)) {
        eprintln!("explore: {e:#}");
        std::process::exit(if e.downcast_ref::<Refused>().is_some() {
            2
        } else {
            1
        });
    }
}
