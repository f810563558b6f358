//! The dataset design of pino-mbd: what is drawn, from which random stream, for which split.
//!
//! - [`rng`]: the ChaCha20 streams keyed by (seed, purpose, sample id): results never depend
//!   on thread count, shard layout or processing order.
//! - [`sampling`]: the train / validation / test splits by id and the uniform draws of a
//!   description's sampled parameters.
//! - [`profile`]: random-phase profiles from a piecewise power-law spectrum (the description's
//!   `profiles` of kind `generated`), and the Welch PSD that checks them.
//!
//! This crate knows the system description (for its parameter ranges and spectra) but no
//! physics, Parquet or learning.
#![warn(missing_docs)]

pub mod profile;
pub mod rng;
pub mod sampling;

pub use profile::{ProfileGenerator, ProfileParams, Psd, PsdSegment};
pub use rng::{Purpose, SampleStream};
pub use sampling::{SamplingPlan, Split, SplitSizes};

/// Errors of the dataset design; variants carry the offending values.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A value outside its allowed range.
    #[error("`{name}` = {value} is out of range: {allowed}")]
    OutOfRange {
        /// The field.
        name: String,
        /// Its value.
        value: f64,
        /// What is allowed.
        allowed: String,
    },
    /// A `[lo, hi]` range that is empty or outside what the field allows.
    #[error("range of `{name}` = [{lo}, {hi}] is invalid: {allowed}")]
    InvalidRange {
        /// The field.
        name: String,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
        /// What is allowed.
        allowed: String,
    },
    /// A signal of the wrong length.
    #[error("signal `{name}` has {found} points, expected {expected}")]
    Shape {
        /// The signal.
        name: String,
        /// Its length.
        found: usize,
        /// The length required.
        expected: usize,
    },
    /// A profile whose interpolation needs more points than its controls give.
    #[error(
        "profiles.{profile}.interpolation: {interpolation} needs at least {min} profile points, \
         dx = {dx} m and length = {length} m give {points}; allowed: length >= {min} dx = {} m",
        *min as f64 * dx
    )]
    TooFewPoints {
        /// The profile.
        profile: String,
        /// The interpolation's keyword.
        interpolation: &'static str,
        /// Points it needs.
        min: usize,
        /// Points the controls give.
        points: usize,
        /// Spacing (m).
        dx: f64,
        /// Length (m).
        length: f64,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// The profile generators of a description, one per profile (`None` for analytic ones), with
/// the run controls `params`. Refuses first controls that give a profile fewer points than its
/// interpolation needs ([`Error::TooFewPoints`]).
pub fn profile_generators(
    system: &mbd_system::System,
    params: &ProfileParams,
) -> Result<Vec<Option<ProfileGenerator>>> {
    system
        .profiles
        .iter()
        .enumerate()
        .map(|(i, p)| match p {
            mbd_system::system::Profile::Generated {
                name,
                psd,
                wavelengths,
                interpolation,
                ..
            } => {
                let min = interpolation.min_points();
                if let Some(points) = params.points().filter(|&n| n < min) {
                    return Err(Error::TooFewPoints {
                        profile: name.clone(),
                        interpolation: interpolation.keyword(),
                        min,
                        points,
                        dx: params.dx,
                        length: params.length,
                    });
                }
                let psd = Psd::from_description(psd)?;
                params
                    .generator(psd, *wavelengths, rng::profile_code(i))
                    .map(Some)
            }
            mbd_system::system::Profile::Harmonic { .. }
            | mbd_system::system::Profile::Combination { .. } => Ok(None),
        })
        .collect()
}

/// The generated profiles of `system` (kind `generated`), each with its name, in description
/// order ([`profile_generators`] without the others).
pub fn generated_profiles<'a>(
    system: &'a mbd_system::System,
    params: &ProfileParams,
) -> Result<Vec<(&'a str, ProfileGenerator)>> {
    Ok(system
        .profiles
        .iter()
        .zip(profile_generators(system, params)?)
        .filter_map(|(prof, g)| g.map(|g| (prof.name(), g)))
        .collect())
}
