//! Split conformal prediction (Vovk, Gammerman and Shafer 2005; Lei et al. 2018), the
//! mechanism behind every error bar of pino-mbd (`docs/uncertainty.md`).
//!
//! A model `f` is trained; `n` calibration samples `(x_i, y_i)`, never used for training or
//! for choosing settings, give nonconformity scores `s_i = |y_i - f(x_i)| / sigma(x_i)`, with
//! `sigma` a difficulty known without the truth (1 for plain scores). For a new `x`
//! exchangeable with them, `f(x) +- q sigma(x)` contains `y` with probability at least the
//! coverage `1 - alpha`, where `q` is the `k`-th smallest score, `k = ceil((n + 1)(1 - alpha))`
//! (at most `1 - alpha + 1 / (n + 1)` without ties). The guarantee is marginal: over the
//! distribution the calibration samples were drawn from, not for one fixed design.
//!
//! - [`scores`]: a set of calibration scores and its quantile at a coverage, with the levels
//!   `n` scores can support.
//! - [`verdict`]: intervals and the three-valued verdict against an upper limit.
//! - [`head`]: the log-linear error head, a difficulty `sigma(x)` fitted on held-out errors.
//!
//! A curve `y(t)` gets a simultaneous band from one score per sample,
//! `max_t |y(t) - f(t)| / (scale(t) sigma)` ([`scores::sup_score`]): the whole curve lies in
//! `f(t) +- q scale(t) sigma` with the same probability.
#![warn(missing_docs)]

pub mod head;
pub mod scores;
pub mod verdict;

pub use head::ErrorHead;
pub use scores::{check_coverage, sup_score, ScoreSet};
pub use verdict::{Interval, Verdict};

/// What can go wrong: every message names the value and what is allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A coverage outside (0, 1).
    #[error("coverage {value} is outside (0, 1): give a level such as 0.9")]
    Coverage {
        /// The level asked for.
        value: f64,
    },
    /// A level the number of calibration samples cannot support.
    #[error("coverage {value} needs more than the {n} calibration samples: with n samples a level above n / (n + 1) = {max:.4} has no finite interval (the rank ceil((n + 1) level) exceeds n); use a level <= {max:.4} or calibrate on more samples")]
    Unsupported {
        /// The level asked for.
        value: f64,
        /// Calibration samples.
        n: usize,
        /// The highest level they support, `n / (n + 1)`.
        max: f64,
    },
    /// A score that is not a finite number >= 0.
    #[error("score {index} is {value}: scores must be finite and >= 0")]
    BadScore {
        /// Its position.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// Inputs of mismatched shapes or too few to fit.
    #[error("{0}")]
    Shape(String),
}

/// Result with this crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
