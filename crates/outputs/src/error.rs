//! Errors of the evaluation library: the engine's (a model, a dataset, a design or a
//! calibration refused, each naming the file, field or tensor at fault) and a report file's
//! (CSV, Markdown, PNG), with the messages of their own crates.

/// What went wrong while evaluating a model or predicting with it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The learning engine, the data layer or a refused input ([`pino_learn::Error`]).
    #[error(transparent)]
    Learn(#[from] pino_learn::Error),
    /// Writing a report file (CSV, Markdown, PNG) failed.
    #[error(transparent)]
    Report(#[from] report::Error),
    /// A running study was asked to stop (`Progress::cancel` of `pino-study`).
    #[error("the study was cancelled")]
    Cancelled,
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// A file or directory whose content is not what it must be: `message` says what, `path`
    /// names it.
    pub fn format(path: &std::path::Path, message: String) -> Self {
        pino_learn::Error::Format {
            path: path.to_owned(),
            message,
        }
        .into()
    }
}

/// The data layer's errors, as the engine reports them.
impl From<pino_data::Error> for Error {
    fn from(e: pino_data::Error) -> Self {
        Error::Learn(e.into())
    }
}

/// candle's errors, as the engine reports them (`tensor: ...`).
impl From<candle_core::Error> for Error {
    fn from(e: candle_core::Error) -> Self {
        Error::Learn(e.into())
    }
}

/// A failed atomic write: an I/O error on its path, as the engine reports it.
impl From<atomic_file::Error> for Error {
    fn from(e: atomic_file::Error) -> Self {
        Error::Learn(e.into())
    }
}

/// A design that does not fit the model's system, as the engine reports it.
impl From<mbd_system::SampledError> for Error {
    fn from(e: mbd_system::SampledError) -> Self {
        Error::Learn(e.into())
    }
}
