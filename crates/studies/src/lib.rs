//! The estimators behind pino-mbd's design studies (`docs/studies.md`), free of any model:
//! they take numbers (unit-cube points, index values, intervals) and return numbers, so each
//! is tested against closed forms here and the `study` stage only wires a surrogate (or the
//! solver) to them.
//!
//! - [`distribution`]: a study's parameter distributions (uniform, normal and lognormal
//!   truncated at a range, fixed), mapped from unit-cube coordinates by their inverse CDF.
//! - [`stats`]: means, standard deviations, quantiles, percentile-bootstrap intervals, the
//!   Wilson interval of a proportion, and exceedance probabilities with the bounds that
//!   calibrated intervals give.
//! - [`sobol`]: Saltelli's design on an Owen-scrambled Sobol' sequence, first-order (Saltelli
//!   2010) and total (Jansen 1999) indices with grouped factors, bootstrap intervals, a
//!   convergence record.
//! - [`optimise`]: derivative-free minimisation on a box under upper limits (Nelder-Mead from
//!   `argmin`, restarted from several starting points, an exact L1 penalty).
//!
//! Every random draw comes from a ChaCha stream keyed by (seed, purpose, id)
//! ([`mbd_dataset::SampleStream`]): results do not depend on the thread count.

pub mod distribution;
pub mod optimise;
pub mod sobol;
pub mod stats;

pub use distribution::Distribution;

/// Errors of the estimators: inputs they cannot work on.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum Error {
    /// A value outside what an estimator accepts.
    #[error("{field} = {value}: allowed {allowed}")]
    OutOfRange {
        /// What was given.
        field: String,
        /// Its value.
        value: String,
        /// What is accepted.
        allowed: String,
    },
    /// The optimiser failed (a non-finite cost everywhere, or argmin's own error).
    #[error("optimisation: {0}")]
    Optimiser(String),
}

/// Result of the estimators.
pub type Result<T> = std::result::Result<T, Error>;

pub(crate) fn out_of_range(
    field: impl Into<String>,
    value: impl std::fmt::Display,
    allowed: impl Into<String>,
) -> Error {
    Error::OutOfRange {
        field: field.into(),
        value: value.to_string(),
        allowed: allowed.into(),
    }
}
