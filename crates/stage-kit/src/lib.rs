//! The stage side of the pino-mbd **stage protocol** (the contract itself, shared with the
//! orchestrator, is the `stage-protocol` crate; this crate gives stage code typed access).
//!
//! The orchestrator (`pipeline`) knows nothing about physics or learning: it starts a stage
//! executable with an argument list (no shell) and one environment variable,
//! `PINO_STAGE_CONTEXT`, holding the path of a JSON context file:
//!
//! ```json
//! {
//!   "protocol": 1,
//!   "stage": "train[algorithm=3]",
//!   "params": { "epochs": 40, "algorithm": 3 },
//!   "inputs": { "dataset": ["/ws/artifacts/objects/ab12/out", "/ws/artifacts/objects/cd34/out"] },
//!   "output": "/ws/artifacts/tmp/ef56/out",
//!   "scratch": "/ws/artifacts/scratch/ef56",
//!   "shard": { "index": 0, "count": 1 }
//! }
//! ```
//!
//! - `params`: the stage's resolved parameters (pipeline defaults, matrix values and `--set`
//!   overrides applied).
//! - `inputs`: for each declared input, the list of directories that together form that
//!   upstream artifact: one for a plain stage, one per shard (in shard order) for a sharded
//!   stage, one per expansion for a matrix stage.
//! - `output`: an existing, empty directory. The stage writes its files there; the
//!   orchestrator verifies, hashes and moves it into the content-addressed store only after
//!   the stage exits 0. A nonzero exit discards it.
//! - `scratch` (optional): a directory kept across failed or killed attempts of the same unit
//!   (same identity) and deleted after a successful commit; resumable state (checkpoints)
//!   goes there, so `pipeline run` after a crash resumes instead of starting over.
//! - `shard`: this process's shard index and the shard count (0 of 1 when unsharded).
//!
//! A stage reports progress by printing `::progress DONE TOTAL [MESSAGE]` lines on stdout and a
//! one-line result by printing `::summary TEXT`; every other line is plain log. Any executable
//! that follows this contract is a stage, a user's script included. A stage can also be run by
//! hand with `--context FILE` as its first two arguments.
//!
//! A stage that reads a system description loads the one its command names with
//! [`load_description`], and declares itself as the origin of the Parquet files it writes with
//! [`StageContext::declare_origin`], first thing. In check mode it may announce its unit's work
//! with [`work`].
//!
//! ```no_run
//! # fn main() -> Result<(), stage_kit::Error> {
//! #[derive(serde::Deserialize)]
//! #[serde(deny_unknown_fields)]
//! struct Params { seed: u64 }
//! let ctx = stage_kit::StageContext::load()?;
//! let params: Params = ctx.params()?;
//! let progress = ctx.progress(100);
//! progress.inc(1);
//! # Ok(()) }
//! ```
#![warn(missing_docs)]

mod context;
mod description;
mod progress;

pub use context::{Shard, StageContext, CONTEXT_ENV, PROTOCOL_VERSION};
pub use description::load_description;
pub use progress::{finish, summary, work, Progress, PROGRESS_PREFIX, SUMMARY_PREFIX};

use std::path::PathBuf;

/// Errors of the stage side of the protocol. Each names the file and the field at fault.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Neither `--context FILE` nor `PINO_STAGE_CONTEXT` was given.
    #[error("no stage context: run this stage through `pipeline run`, or pass `--context FILE` (or set {CONTEXT_ENV})")]
    NoContext,
    /// The context file could not be read.
    #[error("cannot read stage context {path}: {source}")]
    Read {
        /// The context file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The context file is not valid protocol JSON.
    #[error("malformed stage context {path}: {source}")]
    Malformed {
        /// The context file.
        path: PathBuf,
        /// The JSON error (with line and column).
        source: serde_json::Error,
    },
    /// The context was written for another protocol version.
    #[error("stage context {path} has protocol {found}, this stage speaks {expected}")]
    Protocol {
        /// The context file.
        path: PathBuf,
        /// Version found.
        found: u32,
        /// Version supported.
        expected: u32,
    },
    /// A parameter is unknown, missing, or of the wrong type.
    #[error("stage `{stage}` (context {path}): bad parameters: {message}")]
    Params {
        /// The stage name.
        stage: String,
        /// The context file.
        path: PathBuf,
        /// What serde said (names the field and the expected type).
        message: String,
    },
    /// A parameter is well-typed but outside its allowed range.
    #[error("stage `{stage}`: parameter `{field}` = {value} is out of range: {allowed}")]
    OutOfRange {
        /// The stage name.
        stage: String,
        /// The parameter name.
        field: String,
        /// The offending value, as text.
        value: String,
        /// The allowed range, as text.
        allowed: String,
    },
    /// An input that must be one artifact holds no file or several.
    #[error("stage `{stage}`: input `{name}` must hold exactly one {file_name}, found {found}")]
    InputCount {
        /// The stage name.
        stage: String,
        /// The input.
        name: String,
        /// The file looked for.
        file_name: String,
        /// How many were found.
        found: usize,
    },
    /// The system description the command names is missing or does not compile (every
    /// problem with its file and line).
    #[error("{0}")]
    Description(String),
    /// Writing the process's origin into the data layer failed.
    #[error(transparent)]
    Data(#[from] pino_data::Error),
    /// The stage needs an input the pipeline did not wire.
    #[error("stage `{stage}` needs input `{name}`, but the pipeline gives it only [{available}]")]
    MissingInput {
        /// The stage name.
        stage: String,
        /// The missing input.
        name: String,
        /// The inputs that were given.
        available: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;
