//! Run controls of a simulation: time stepping, start, the start-up of the profiles and where
//! the moving frame starts. Physics values live in the system description; these are the
//! `simulate` stage's parameters (`pipeline.yaml`), every one required (their home is the
//! pipeline file) and unknown names refused.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// How a run starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", try_from = "String")]
pub enum StartMode {
    /// The static equilibrium under the loads at `t = 0`, zero velocities.
    Equilibrium,
    /// The zero state: every displacement and velocity zero (the paper's protocol).
    Rest,
}

impl TryFrom<String> for StartMode {
    type Error = String;
    fn try_from(s: String) -> std::result::Result<Self, String> {
        match s.as_str() {
            "equilibrium" => Ok(Self::Equilibrium),
            "rest" => Ok(Self::Rest),
            other => Err(format!(
                "`start` = \"{other}\" is not a start mode; allowed: \"equilibrium\" (static \
                 solution under the loads) or \"rest\" (zero state, the paper's protocol)"
            )),
        }
    }
}

/// The run controls.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// Simulated time `T` (s).
    pub duration: f64,
    /// Time step (s), refused above the stability limit.
    pub dt: f64,
    /// Steps between stored rows.
    pub output_every: usize,
    /// Initial state.
    pub start: StartMode,
    /// Fraction of `T` with every profile off.
    pub startup_zero_fraction: f64,
    /// Fraction of `T` over which the profiles fade in linearly.
    pub startup_ramp_fraction: f64,
    /// Position of the moving frame's origin at `t = 0` (m).
    pub x0: f64,
}

fn out_of_range(name: &str, value: f64, allowed: impl Into<String>) -> Error {
    Error::OutOfRange {
        name: name.to_owned(),
        value,
        allowed: allowed.into(),
    }
}

impl RunConfig {
    /// Number of time steps `round(T / dt)`.
    pub fn steps(&self) -> usize {
        (self.duration / self.dt).round() as usize
    }

    /// Number of stored rows per sample.
    pub fn n_outputs(&self) -> usize {
        self.steps() / self.output_every.max(1)
    }

    /// Time of the last stored row (s).
    pub fn t_end(&self) -> f64 {
        self.n_outputs().saturating_sub(1) as f64 * self.output_every as f64 * self.dt
    }

    /// Checks every field, naming it and its allowed range.
    pub fn validate(&self) -> Result<()> {
        for (name, value) in [("duration", self.duration), ("dt", self.dt)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(out_of_range(name, value, "finite and > 0 (s)"));
            }
        }
        if self.output_every == 0 {
            return Err(out_of_range(
                "output_every",
                0.0,
                "an integer >= 1 (steps between stored rows)",
            ));
        }
        if self.steps() > 1 << 32 {
            return Err(out_of_range(
                "duration",
                self.duration,
                format!("at most 2^32 steps of dt = {} s", self.dt),
            ));
        }
        if self.n_outputs() < 1 {
            let allowed = format!(
                "at least output_every * dt = {} s",
                self.output_every as f64 * self.dt
            );
            return Err(out_of_range("duration", self.duration, allowed));
        }
        for (name, value) in [
            ("startup_zero_fraction", self.startup_zero_fraction),
            ("startup_ramp_fraction", self.startup_ramp_fraction),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(out_of_range(name, value, "in [0, 1]"));
            }
        }
        if self.startup_zero_fraction + self.startup_ramp_fraction > 1.0 {
            return Err(out_of_range(
                "startup_ramp_fraction",
                self.startup_ramp_fraction,
                format!(
                    "<= 1 - startup_zero_fraction = {}",
                    1.0 - self.startup_zero_fraction
                ),
            ));
        }
        if !self.x0.is_finite() {
            return Err(out_of_range("x0", self.x0, "finite (m)"));
        }
        Ok(())
    }

    /// Profile factor `r(t)`: 0 for `t < z T`, rising linearly to 1 over the next `r T`.
    pub fn ramp(&self, t: f64) -> f64 {
        let start = self.startup_zero_fraction * self.duration;
        let width = self.startup_ramp_fraction * self.duration;
        if t < start {
            0.0
        } else if width <= 0.0 || t >= start + width {
            1.0
        } else {
            (t - start) / width
        }
    }

    /// `dr/dt` (1/s).
    pub fn ramp_rate(&self, t: f64) -> f64 {
        let start = self.startup_zero_fraction * self.duration;
        let width = self.startup_ramp_fraction * self.duration;
        if width > 0.0 && t >= start && t < start + width {
            1.0 / width
        } else {
            0.0
        }
    }

    /// The time at which the profiles switch on (s).
    pub fn profile_on(&self) -> f64 {
        self.startup_zero_fraction * self.duration
    }
}
