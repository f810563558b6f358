//! The generic multibody engine: a described system ([`mbd_system::System`]), one sample's
//! numbers ([`mbd_system::model::Model`]) and the run controls ([`RunConfig`]) become an
//! [`Engine`] that integrates the coupled equations with Zhai's explicit method and yields every
//! stored channel with exact velocities and accelerations.
//!
//! Conventions: SI units; vertical displacements positive downward, measured from the static
//! equilibrium on rigid supports; pitch positive nose-up; `x` forward.
//!
//! - [`engine`]: state layout, force evaluation, time loop; [`run`]: engines built with their
//!   checks, started, run to their stored rows, many samples in parallel.
//! - `assembly`: the rigid DOFs' coefficient groups, compiled to flat lists;
//! - [`beam`]: modal simply supported beams; [`dst`]: the sine transform of uniform supports;
//!   [`supports`]: the support chains.
//! - [`statics`]: the static-equilibrium start; [`stability`]: the time-step bound.
//! - [`corners`]: the corners of the box of sampling ranges the box checks visit;
//! - [`coverage`]: whether a run stays on its beams and profiles, per sample and over the box
//!   of sampling ranges;
//! - [`residual`]: the ODE residuals of the rigid DOFs for learning, by the same element code;
//! - [`integrator`]: Zhai's two-step method; [`profile`]: profiles under moving points;
//!   [`excitation`]: those profiles over a run without running it (inputs of a surrogate);
//!   [`config`]: run controls; [`wheel`]: the wheel-rail creep, normal and flange forces of a
//!   wheelset on two rails.
//!
//! The engine recognises structure and takes a fast path where it exists (uniform supports:
//! sine transforms; a statically determinate vehicle: the equilibrium in closed form), with a
//! general route beside it ([`Route::General`]) that the tests hold it equal to.
#![warn(missing_docs)]

mod assembly;
pub mod beam;
pub mod config;
pub mod corners;
pub mod coverage;
pub mod dst;
pub mod engine;
pub mod excitation;
pub mod integrator;
pub mod profile;
mod reads;
pub mod residual;
pub mod run;
pub mod stability;
pub mod statics;
pub mod supports;
pub mod wheel;

pub use config::{RunConfig, StartMode};
pub use engine::{Engine, Failure, Route, StepView};
pub use excitation::Excitations;
pub use profile::{Profile, ProfileSource};
pub use run::{prepare, run_all, SampleInput, Trajectory};

/// Errors of the engine; variants carry the offending values.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A run control or input out of its range.
    #[error("`{name}` = {value} is out of range: {allowed}")]
    OutOfRange {
        /// The field.
        name: String,
        /// Its value.
        value: f64,
        /// What is allowed.
        allowed: String,
    },
    /// A field of the instantiated model out of its domain.
    #[error(transparent)]
    Field(#[from] mbd_system::model::FieldError),
    /// Signals of unequal or too short lengths.
    #[error("signal `{name}` has {found} points, expected {expected}")]
    Shape {
        /// The signal.
        name: String,
        /// Its length.
        found: usize,
        /// The length required.
        expected: usize,
    },
    /// The time step is beyond the stability limit.
    #[error("time step `dt` = {dt} s is beyond the stability limit {limit:.3e} s of Zhai's method for this model (highest-frequency bound {omega_max:.0} rad/s); use dt <= {limit:.3e}")]
    StepTooLarge {
        /// The step asked for (s).
        dt: f64,
        /// The largest stable step (s).
        limit: f64,
        /// The frequency bound (rad/s).
        omega_max: f64,
    },
    /// Points would leave their beam or profile during the run.
    #[error("{what} covers x in [{have_lo}, {have_hi}] m but the points run over [{need_lo}, {need_hi}] m: {hint}")]
    TooShort {
        /// What is too short.
        what: String,
        /// Covered start (m).
        have_lo: f64,
        /// Covered end (m).
        have_hi: f64,
        /// Needed start (m).
        need_lo: f64,
        /// Needed end (m).
        need_hi: f64,
        /// How to fix it.
        hint: String,
    },
    /// A moving point reads a generated profile before its start somewhere in the box of
    /// sampling ranges ([`coverage::check_profile_starts`]).
    #[error("{0}")]
    BeforeProfile(Box<coverage::EarlyRead>),
    /// Problems placed in the system description, `file:line:col: message` each (a refusal
    /// of [`coverage::check_profile_starts_described`]).
    #[error("{0}")]
    Described(mbd_system::Diagnostics),
    /// An iterative solve did not reach its tolerance.
    #[error(
        "{what} did not converge: relative residual {residual:e} after {iterations} iterations"
    )]
    NoConvergence {
        /// What was solved.
        what: String,
        /// Iterations taken.
        iterations: usize,
        /// Final relative residual.
        residual: f64,
    },
    /// The static problem cannot be solved.
    #[error("static equilibrium: {what}")]
    Statics {
        /// Why.
        what: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;
