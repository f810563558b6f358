//! Vertical vehicle-track coupled dynamics (VTCD) after Zhai, as specified in
//! `docs/model.md`.
//!
//! Conventions (everywhere in this crate): SI units (m, kg, s, N, rad); vertical displacements
//! `Z` positive **downward**, measured from the static equilibrium on a rigid track; pitch
//! angles `beta` positive **nose-up**; wheels numbered 1..4 from the front.
//!
//! - [`params`]: the 14 per-sample parameters and their ranges.
//! - [`vehicle`]: the 10-DOF half vehicle: suspension forces, equations of motion, residuals.
//! - [`contact`]: Hertz wheel-rail contact.
//! - [`rng`]: the seeded ChaCha stream keyed by (seed, purpose, sample id).
//! - [`sampling`]: the checked parameter-sampling configuration and the per-sample draws.
//! - [`irregularity`]: the TB/T 3352-2014 track spectrum, random-phase profiles, Welch PSD.
//! - [`weights`]: the PINO-MBD ODE magnitude weights `phi_ki = max_t |R_i|` on noised data.
//! - [`track`]: fixed track constants and the sleeper-ballast-subgrade substructure.
//! - [`rail`]: the modal simply supported rail and its fast sine transform.
//! - [`integrator`]: Zhai's explicit two-step method.
//! - [`stability`]: the pre-run time-step check.
//! - [`statics`]: the static track deflection under the wheel loads (equilibrium start).
//! - [`simulation`]: the coupled vehicle-track model and its time loop.
#![warn(missing_docs)]

pub mod contact;
pub mod irregularity;
pub mod params;
pub mod rng;
pub mod sampling;
pub mod vehicle;
pub mod weights;

pub mod integrator;
pub mod rail;
pub mod simulation;
pub mod stability;
pub mod statics;
pub mod track;

/// Errors of the physics library; variants carry the offending values.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A parameter is outside its allowed range.
    #[error("parameter `{name}` = {value} is out of range: {allowed}")]
    OutOfRange {
        /// Parameter name (spec name).
        name: String,
        /// Its value.
        value: f64,
        /// The allowed range, as text.
        allowed: String,
    },
    /// A `[lo, hi]` range (a parameter range, a wavelength band) is empty, inverted or has a
    /// bound outside what the field allows.
    #[error("range of `{name}` = [{lo}, {hi}] is invalid: {allowed}")]
    InvalidRange {
        /// The field (spec name).
        name: String,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
        /// What is allowed, as text.
        allowed: String,
    },
    /// A name that is not one of the known parameters.
    #[error("unknown parameter `{name}`; allowed: {allowed}")]
    UnknownParameter {
        /// The name given.
        name: String,
        /// The known names, comma separated.
        allowed: String,
    },
    /// Signals of one sample that must have equal lengths do not, or are too short.
    #[error("signal `{name}` has {found} points, expected {expected}")]
    Shape {
        /// The signal (column name).
        name: String,
        /// Its length.
        found: usize,
        /// The length required.
        expected: usize,
    },
    /// The time step is beyond the stability limit of Zhai's method for this model.
    #[error("time step `dt` = {dt} s is beyond the stability limit {limit:.3e} s of Zhai's method for this model (highest-frequency bound {omega_max:.0} rad/s); use dt <= {limit:.3e}")]
    StepTooLarge {
        /// The step asked for (s).
        dt: f64,
        /// The largest stable step (s).
        limit: f64,
        /// The bound of the highest circular frequency used (rad/s).
        omega_max: f64,
    },
    /// The wheels would leave the rail (or its irregularity profile) during the run.
    #[error("{what} covers x in [{have_lo}, {have_hi}] m but the wheels run over [{need_lo}, {need_hi}] m: {hint}")]
    TooShort {
        /// What is too short (the rail, the irregularity profile of a sample).
        what: String,
        /// Covered range start (m).
        have_lo: f64,
        /// Covered range end (m).
        have_hi: f64,
        /// Needed range start (m).
        need_lo: f64,
        /// Needed range end (m).
        need_hi: f64,
        /// How to fix it.
        hint: String,
    },
    /// An iterative solve did not reach its tolerance.
    #[error(
        "{what} did not converge: relative residual {residual:e} after {iterations} iterations"
    )]
    NoConvergence {
        /// What was being solved.
        what: String,
        /// Iterations taken.
        iterations: usize,
        /// Final relative residual.
        residual: f64,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;
