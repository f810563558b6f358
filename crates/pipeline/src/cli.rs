//! The command line: `pipeline [-C DIR] [-f FILE] [--bin-dir DIR] [--set S.K=V]... COMMAND`.
//! `gc` needs only the workspace (`-C`); the other commands load the pipeline file.

use crate::executor::ExecutorKind;
use crate::gc::{gc, GcOptions};
use crate::run::{run, RunOptions};
use crate::spec::{LoadOptions, Pipeline};
use crate::status::{dag, show, status};
use crate::ui::Ui;
use crate::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// Content-hashed pipeline orchestrator: runs stale stages, reuses cached ones.
#[derive(Debug, Parser)]
#[command(name = "pipeline", version)]
pub struct Cli {
    /// Workspace root (default: the pipeline file's `workspace:`, relative to the file, else
    /// the file's directory).
    #[arg(short = 'C', long = "workspace", global = true, value_name = "DIR")]
    pub workspace: Option<PathBuf>,
    /// Pipeline file, relative to the workspace when -C is given, else to the current
    /// directory.
    #[arg(
        short = 'f',
        long = "file",
        global = true,
        default_value = "pipeline.yaml"
    )]
    pub file: PathBuf,
    /// Directory searched first for bare command names (overrides the file's `bin_dir`;
    /// default: env PINO_BIN_DIR, then the file's `bin_dir`).
    #[arg(long, global = true, value_name = "DIR")]
    pub bin_dir: Option<PathBuf>,
    /// Override a parameter for this invocation: STAGE.KEY=VALUE (VALUE is YAML).
    #[arg(long = "set", global = true, value_name = "STAGE.KEY=VALUE")]
    pub sets: Vec<String>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the targets (default: every stage) and whatever upstream of them is stale.
    Run {
        /// Stages (`train`) or single expansions (`train[algorithm=3]`).
        targets: Vec<String>,
        /// Rerun the targets even when fresh (upstream fresh stages are reused).
        #[arg(long)]
        force: bool,
        /// Units (stages, shards, expansions) run at once (default: the machine's cores; a
        /// training runs on one core, so the candidate models train side by side).
        #[arg(short = 'j', long = "jobs")]
        jobs: Option<usize>,
        /// Fail at once (exit 2) instead of waiting when another run holds the workspace.
        #[arg(long)]
        no_wait: bool,
        /// Where units run (overrides the pipeline file's `executor:`).
        #[arg(long, value_enum, value_name = "local|slurm")]
        executor: Option<ExecutorKind>,
    },
    /// Every unit as fresh, stale (with the reason) or never run.
    Status,
    /// The stage graph as text, or Graphviz with --dot.
    Dag {
        /// Graphviz dot output.
        #[arg(long)]
        dot: bool,
    },
    /// Paths of a stage's current output files, one per line.
    Show {
        /// A stage or one expansion.
        stage: String,
    },
    /// Remove the stored objects that no lock-record entry (of any pipeline file) points to,
    /// under the run lock.
    Gc {
        /// List what would be removed; remove nothing.
        #[arg(long)]
        dry_run: bool,
        /// Also keep, per unit, the N most recently committed objects the lock record does
        /// not point to (the run-cache of the last N changes).
        #[arg(long, value_name = "N", default_value_t = 0)]
        keep: usize,
        /// Fail at once (exit 2) instead of waiting when a `pipeline run` holds the workspace.
        #[arg(long)]
        no_wait: bool,
    },
}

fn execute(cli: Cli) -> Result<()> {
    // `gc` reads no pipeline file: its workspace is -C's, else the current directory.
    let (workspace, file) = match (&cli.command, &cli.workspace) {
        (Command::Gc { .. }, None) => (PathBuf::from("."), cli.file.clone()),
        _ => crate::spec::locate(&cli.file, cli.workspace.as_deref())?,
    };
    let opts = LoadOptions {
        bin_dir: cli.bin_dir.clone().or_else(|| {
            std::env::var_os("PINO_BIN_DIR")
                .filter(|v| !v.is_empty())
                .map(PathBuf::from)
        }),
        sets: cli.sets.clone(),
    };
    let load = || Pipeline::load(&workspace, &file, &opts);
    match cli.command {
        Command::Run {
            targets,
            force,
            jobs,
            no_wait,
            executor,
        } => {
            let p = load()?;
            let ui = Ui::new();
            run(
                &p,
                &RunOptions {
                    targets,
                    force,
                    jobs: jobs.unwrap_or_else(default_jobs),
                    wait: !no_wait,
                    executor,
                },
                &ui,
            )
        }
        Command::Status => {
            print!("{}", status(&load()?)?);
            Ok(())
        }
        Command::Dag { dot } => {
            print!("{}", dag(&load()?, dot));
            Ok(())
        }
        Command::Show { stage } => {
            print!("{}", show(&load()?, &stage)?);
            Ok(())
        }
        Command::Gc {
            dry_run,
            keep,
            no_wait,
        } => {
            // The store alone decides (the lock record holds every pipeline file's entries):
            // the pipeline file is not read.
            let opts = GcOptions {
                dry_run,
                keep,
                wait: !no_wait,
            };
            print!("{}", gc(&workspace, &opts, &Ui::new())?.render());
            Ok(())
        }
    }
}

/// Parses the command line, runs, and maps errors to exit codes (clap's usage errors exit 2).
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pipeline: error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

/// `run`'s units at once without `-j`: the machine's cores (1 when they cannot be read).
fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}
