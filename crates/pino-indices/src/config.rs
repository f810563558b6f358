//! Parameters of the indices (parse with serde, then [`IndexParams::validate`]): the start-up
//! exclusion, the Sperling window, and the pass/fail limits, each with its default and where
//! that default comes from. The description adds one setting of its own, the time its indices
//! read from (`indices_from`, [`IndexConfig::of_system`]): a record's evaluation window starts
//! at the later of the start-up fraction's first point and that time.

use crate::{Error, Indices, Result};
use mbd_system::System;
use serde::{Deserialize, Serialize};

/// Taper applied to each Sperling segment before its spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Taper {
    /// Rectangular (no taper): a sinusoid on a spectral line keeps its exact amplitude, so the
    /// closed form of the definition holds.
    #[default]
    None,
    /// Hann window, amplitudes divided by its coherent gain (sum of the weights); less leakage
    /// between lines, at the cost of spreading a line over its two neighbours.
    Hann,
}

impl Taper {
    /// Its name as written in the parameters.
    pub fn label(self) -> &'static str {
        match self {
            Taper::None => "none",
            Taper::Hann => "hann",
        }
    }
}

fn d_f_min() -> f64 {
    0.5
}

/// How the Sperling index is computed (`docs/indices.md`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SperlingParams {
    /// Segment length (s). `null` (default): one spectrum over the whole evaluation window.
    /// A length: consecutive segments of that length (a shorter remainder is dropped), `W_z`
    /// of each, and the index is the largest (the worst section).
    #[serde(default)]
    pub segment_s: Option<f64>,
    /// Taper of each segment (default `none`).
    #[serde(default)]
    pub taper: Taper,
    /// Lowest frequency counted (Hz); default 0.5, where the weighting `F(f)` of the
    /// definition starts.
    #[serde(default = "d_f_min")]
    pub f_min_hz: f64,
}

impl Default for SperlingParams {
    fn default() -> Self {
        Self {
            segment_s: None,
            taper: Taper::None,
            f_min_hz: d_f_min(),
        }
    }
}

fn d_peak_force() -> Option<f64> {
    Some(170.0)
}
fn d_wlrr() -> Option<f64> {
    Some(0.6)
}
fn d_wz() -> Option<f64> {
    Some(2.5)
}

/// Pass/fail limits; `null` switches a check off. A sample passes when every index is at or
/// below its limit. The defaults are the figures commonly quoted for Chinese high-speed
/// vehicle-track dynamics assessment (see `docs/indices.md` for the sources); set your own.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Peak wheel-rail vertical force (kN); default 170 (TB 10621, high-speed track design).
    #[serde(default = "d_peak_force")]
    pub peak_wheel_rail_force_kn: Option<f64>,
    /// Wheel load reduction rate (-); default 0.6 (GB 5599-85, the preferred value; 0.65 its
    /// limit).
    #[serde(default = "d_wlrr")]
    pub wheel_load_reduction_rate: Option<f64>,
    /// Sperling ride index `W_z` at any of the three car-body points (-); default 2.5 (GB 5599
    /// passenger-vehicle grade "excellent"; 2.75 "good", 3.0 "acceptable").
    #[serde(default = "d_wz")]
    pub sperling_wz: Option<f64>,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            peak_wheel_rail_force_kn: d_peak_force(),
            wheel_load_reduction_rate: d_wlrr(),
            sperling_wz: d_wz(),
        }
    }
}

impl Limits {
    /// The names of the limits `ix` exceeds (empty: it passes).
    pub fn failed(&self, ix: &Indices) -> Vec<&'static str> {
        let mut out = Vec::new();
        // NaN fails every check.
        let over = |v: f64, lim: Option<f64>| lim.is_some_and(|l| v > l || v.is_nan());
        if over(ix.peak_wheel_rail_force_kn, self.peak_wheel_rail_force_kn) {
            out.push("peak_wheel_rail_force_kn");
        }
        if over(ix.wheel_load_reduction_rate, self.wheel_load_reduction_rate) {
            out.push("wheel_load_reduction_rate");
        }
        let wz = ix
            .sperling_wz
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        if over(wz, self.sperling_wz) {
            out.push("sperling_wz");
        }
        out
    }
}

/// The indices' parameters as written in a pipeline file (unchecked).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexParams {
    /// Fraction of each record dropped at its start (start-up), `[0, 1)`; the first kept
    /// point is `floor(f n)` of a record of `n` points, as the learning window. Default 0:
    /// the equilibrium start of `simulate` has no transient (the pipeline passes
    /// `${constants.window_start_fraction}`).
    #[serde(default)]
    pub window_start_fraction: f64,
    /// Sperling settings.
    #[serde(default)]
    pub sperling: SperlingParams,
    /// Pass/fail limits.
    #[serde(default)]
    pub limits: Limits,
}

impl Default for IndexParams {
    fn default() -> Self {
        Self {
            window_start_fraction: 0.0,
            sperling: SperlingParams::default(),
            limits: Limits::default(),
        }
    }
}

/// Checked [`IndexParams`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexConfig {
    /// Start-up fraction dropped, in `[0, 1)`.
    pub window_start_fraction: f64,
    /// Time (s) before which no point is read: the description's `indices_from`
    /// ([`IndexConfig::of_system`]); 0 until then.
    pub from_s: f64,
    /// Sperling settings (segment > 0 when given, `f_min_hz` > 0).
    pub sperling: SperlingParams,
    /// Limits (each > 0 when given).
    pub limits: Limits,
}

fn out_of_range(field: &str, value: impl std::fmt::Display, allowed: &str) -> Error {
    Error::OutOfRange {
        field: field.to_owned(),
        value: value.to_string(),
        allowed: allowed.to_owned(),
    }
}

impl IndexParams {
    /// Checks every field; the error names the field, its value and the allowed range.
    pub fn validate(&self) -> Result<IndexConfig> {
        let f = self.window_start_fraction;
        if !(f.is_finite() && (0.0..1.0).contains(&f)) {
            return Err(out_of_range("window_start_fraction", f, "[0, 1)"));
        }
        if let Some(s) = self.sperling.segment_s {
            if !(s.is_finite() && s > 0.0) {
                return Err(out_of_range("sperling.segment_s", s, "null or > 0 (s)"));
            }
        }
        let fm = self.sperling.f_min_hz;
        if !(fm.is_finite() && fm > 0.0) {
            return Err(out_of_range("sperling.f_min_hz", fm, "finite and > 0 (Hz)"));
        }
        for (name, v) in [
            (
                "limits.peak_wheel_rail_force_kn",
                self.limits.peak_wheel_rail_force_kn,
            ),
            (
                "limits.wheel_load_reduction_rate",
                self.limits.wheel_load_reduction_rate,
            ),
            ("limits.sperling_wz", self.limits.sperling_wz),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return Err(out_of_range(name, v, "null or finite and > 0"));
                }
            }
        }
        Ok(IndexConfig {
            window_start_fraction: f,
            from_s: 0.0,
            sperling: self.sperling,
            limits: self.limits,
        })
    }
}

impl IndexConfig {
    /// These settings for the indices of `system`: its `indices_from` applied.
    pub fn of_system(self, system: &System) -> Self {
        Self {
            from_s: system.indices_from,
            ..self
        }
    }

    /// Index of the first point the start-up fraction keeps of a record of `n` points.
    pub fn first_index(&self, n: usize) -> usize {
        (self.window_start_fraction * n as f64).floor() as usize
    }

    /// Index of the first point at or after `from_s` of the grid `t0 + k dt` (0 when `t0`
    /// already is; a point within a millionth of a step before it counts as on it).
    pub fn first_at(&self, t0: f64, dt: f64) -> usize {
        ((self.from_s - t0) / dt - 1e-6).ceil().max(0.0) as usize
    }

    /// Index of the first point of the evaluation window of the record sampled at times `t`
    /// (a uniform grid): the later of [`IndexConfig::first_index`] and
    /// [`IndexConfig::first_at`].
    pub fn first_row(&self, t: &[f64]) -> usize {
        let by_time = match t {
            [a, b, ..] => self.first_at(*a, b - a),
            _ => 0,
        };
        self.first_index(t.len()).max(by_time)
    }

    /// The settings as `(name, value)` text pairs, for the artifacts that state them.
    pub fn describe(&self) -> Vec<(&'static str, String)> {
        let opt = |v: Option<f64>| v.map_or("null".to_owned(), |v| v.to_string());
        vec![
            (
                "window_start_fraction",
                self.window_start_fraction.to_string(),
            ),
            ("indices_from_s", self.from_s.to_string()),
            (
                "sperling.segment_s",
                self.sperling
                    .segment_s
                    .map_or("whole window".to_owned(), |v| v.to_string()),
            ),
            ("sperling.taper", self.sperling.taper.label().to_owned()),
            ("sperling.f_min_hz", self.sperling.f_min_hz.to_string()),
            (
                "limits.peak_wheel_rail_force_kn",
                opt(self.limits.peak_wheel_rail_force_kn),
            ),
            (
                "limits.wheel_load_reduction_rate",
                opt(self.limits.wheel_load_reduction_rate),
            ),
            ("limits.sperling_wz", opt(self.limits.sperling_wz)),
        ]
    }
}
