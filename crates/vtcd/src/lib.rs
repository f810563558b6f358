//! Vertical vehicle-track coupled dynamics (VTCD) after Zhai, as specified in
//! `shared/design/vtcd-model.md`.
//!
//! Conventions (everywhere in this crate): SI units (m, kg, s, N, rad); vertical displacements
//! `Z` positive **downward**, measured from the static equilibrium on a rigid track; pitch
//! angles `beta` positive **nose-up**; wheels numbered 1..4 from the front.
//!
//! - [`params`]: the 14 per-sample parameters and their ranges.
//! - [`vehicle`]: the 10-DOF half vehicle: suspension forces, equations of motion, residuals.
//! - [`contact`]: Hertz wheel-rail contact.
//! - [`rng`]: the seeded ChaCha stream keyed by (seed, purpose, sample id).
#![warn(missing_docs)]

pub mod contact;
pub mod params;
pub mod rng;
pub mod vehicle;

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
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;
