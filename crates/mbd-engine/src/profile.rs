//! Profiles under the moving points: the vertical level of the track or road (m, positive
//! downward: a dip), read by an element at its lower end's position `x`.
//!
//! A generated profile comes per sample as points `(x_n, eta_n)`, linearly interpolated
//! (clamped to its ends; coverage is checked before a run). A harmonic profile is analytic,
//! `eta(x) = a sin(2 pi x / lambda + phi)`, so a test can compare against a closed form without
//! the interpolation's loss of amplitude.

use crate::{Error, Result};

/// Sampled profile points.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    x: Vec<f64>,
    eta: Vec<f64>,
}

impl Profile {
    /// Checks lengths (equal, >= 2), strictly increasing finite `x` and finite `eta`.
    pub fn new(x: Vec<f64>, eta: Vec<f64>) -> Result<Self> {
        if x.len() != eta.len() || x.len() < 2 {
            return Err(Error::Shape {
                name: "eta".to_owned(),
                found: eta.len(),
                expected: x.len().max(2),
            });
        }
        if let Some(w) = x
            .windows(2)
            .find(|w| !(w[0].is_finite() && w[1].is_finite() && w[1] > w[0]))
        {
            return Err(Error::OutOfRange {
                name: "x".to_owned(),
                value: w[1],
                allowed: format!("finite and strictly increasing (after {})", w[0]),
            });
        }
        if let Some(e) = eta.iter().find(|e| !e.is_finite()) {
            return Err(Error::OutOfRange {
                name: "eta".to_owned(),
                value: *e,
                allowed: "finite".to_owned(),
            });
        }
        Ok(Self { x, eta })
    }

    /// Covered positions `[x_first, x_last]` (m).
    pub fn range(&self) -> [f64; 2] {
        [self.x[0], self.x[self.x.len() - 1]]
    }

    fn cell(&self, x: f64) -> usize {
        self.x
            .partition_point(|&p| p <= x)
            .clamp(1, self.x.len() - 1)
    }

    /// `eta` at `x` by linear interpolation (clamped to the ends).
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        let i = self.cell(x);
        let (x0, x1) = (self.x[i - 1], self.x[i]);
        let w = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        self.eta[i - 1] + w * (self.eta[i] - self.eta[i - 1])
    }

    /// `d eta / dx` at `x` (the slope of the interpolating segment; 0 beyond the ends).
    #[inline]
    pub fn slope(&self, x: f64) -> f64 {
        let [lo, hi] = self.range();
        if x < lo || x > hi {
            return 0.0;
        }
        let i = self.cell(x);
        (self.eta[i] - self.eta[i - 1]) / (self.x[i] - self.x[i - 1])
    }
}

/// A profile as the engine reads it.
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileSource {
    /// Sampled points.
    Points(Profile),
    /// `amplitude sin(2 pi x / wavelength + phase)`.
    Harmonic {
        /// m.
        amplitude: f64,
        /// m.
        wavelength: f64,
        /// rad.
        phase: f64,
    },
    /// A perfectly level track or road.
    Level,
}

impl ProfileSource {
    /// `eta(x)` (m).
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        match self {
            ProfileSource::Points(p) => p.at(x),
            ProfileSource::Harmonic {
                amplitude,
                wavelength,
                phase,
            } => amplitude * (std::f64::consts::TAU * x / wavelength + phase).sin(),
            ProfileSource::Level => 0.0,
        }
    }

    /// The excitation `r eta(x)` (m) with the start-up factor `r` of the run controls
    /// ([`crate::RunConfig::ramp`]): exactly 0 while the profile is off.
    #[inline]
    pub fn ramped(&self, ramp: f64, x: f64) -> f64 {
        if ramp > 0.0 {
            ramp * self.at(x)
        } else {
            0.0
        }
    }

    /// `d eta / dx` (1).
    #[inline]
    pub fn slope(&self, x: f64) -> f64 {
        match self {
            ProfileSource::Points(p) => p.slope(x),
            ProfileSource::Harmonic {
                amplitude,
                wavelength,
                phase,
            } => {
                let k = std::f64::consts::TAU / wavelength;
                amplitude * k * (k * x + phase).cos()
            }
            ProfileSource::Level => 0.0,
        }
    }
}
