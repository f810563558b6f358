//! The orchestrator's errors and their exit codes.
//!
//! Exit status contract: 0 success, 1 a stage failed (or the store could not be written),
//! 2 bad input (nothing was run). Every bad-input message names the pipeline file and, where
//! the YAML has one, the line.

use std::path::PathBuf;

/// Everything that can go wrong in the orchestrator.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The pipeline file is not valid YAML or does not match the format (unknown key, wrong
    /// type): serde_yaml's message with its position.
    #[error("{file}:{line}:{column}: {message}")]
    Yaml {
        /// The pipeline file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A semantic error in the pipeline file (missing dependency, cycle, bad path, missing
    /// executable, bad `--set`), located at a line of the file.
    #[error("{file}:{line}: {message}")]
    Spec {
        /// The pipeline file.
        file: String,
        /// 1-based line (the closest line the message is about).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A command-line problem not tied to a line (unknown target stage, malformed `--set`).
    #[error("{0}")]
    Usage(String),
    /// Another `pipeline run` holds the workspace's run lock and `--no-wait` was given.
    #[error("another `pipeline run` (pid {pid}) is running in this workspace ({lock}); not waiting because of --no-wait")]
    Busy {
        /// PID recorded by the holder (may be `?`).
        pid: String,
        /// The lock file.
        lock: PathBuf,
    },
    /// A stage's check refused a unit before anything ran ([`crate::check`]).
    #[error("check of `{unit}` failed, nothing was run:\n{message}")]
    Check {
        /// The unit (expansion) checked.
        unit: String,
        /// What the stage said.
        message: String,
    },
    /// One or more stages failed (their messages were already printed).
    #[error("{count} stage(s) failed: {names}")]
    StageFailed {
        /// Number of failed units.
        count: usize,
        /// Their names.
        names: String,
    },
    /// `pipeline show` on a stage that has no recorded outputs yet in the workspace.
    #[error("stage `{unit}` has no outputs yet in the workspace {}: `pipeline -C {} -f {file} run {stage}` makes them", .workspace.display(), .workspace.display())]
    NoOutputs {
        /// The unit shown.
        unit: String,
        /// Its stage, as `pipeline run` takes it.
        stage: String,
        /// The workspace looked in (absolute).
        workspace: PathBuf,
        /// The pipeline file, relative to the workspace (absolute when outside it).
        file: String,
    },
    /// An I/O error on a named path.
    #[error("{path}: {source}")]
    Io {
        /// The path involved.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// A store file (manifest, lock record) could not be parsed.
    #[error("{path}: malformed: {message}")]
    Store {
        /// The file.
        path: PathBuf,
        /// What serde said.
        message: String,
    },
}

/// A failed atomic write ([`atomic_file::write_atomic`]) is an I/O error on its path.
impl From<atomic_file::Error> for Error {
    fn from(e: atomic_file::Error) -> Self {
        Error::io(e.path, e.source)
    }
}

impl Error {
    /// The process exit status for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Yaml { .. }
            | Error::Spec { .. }
            | Error::Usage(_)
            | Error::Busy { .. }
            | Error::Check { .. } => 2,
            Error::StageFailed { .. }
            | Error::NoOutputs { .. }
            | Error::Io { .. }
            | Error::Store { .. } => 1,
        }
    }

    /// Wraps an I/O error with its path.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;
