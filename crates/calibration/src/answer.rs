//! A calibration applied to one answer: the interval of every index, the band of every
//! channel, and the three-valued verdict of every limit, at one coverage.
//!
//! `sigma` of a quantity under the calibration's normaliser: 1 (`none`), the relative physics
//! residual `g` (`residual`), or the quantity's error head over the design's parameters and
//! `ln g` (`error_head`). An index's interval is `f +- q sigma`; a channel's band
//! `f(t) +- q sigma scale(t)`. A design outside the training ranges is `extrapolated`: its
//! intervals carry no coverage claim and its verdicts are never better than `uncertain`.

use super::difficulty::{relative_residual, ResidualProbe};
use super::{Calibration, HeadInput, Normaliser, QuantityScores};
use crate::Result;
use mbd_system::System;
use pino_conformal::{Interval, Verdict};
use pino_learn::Error as LearnError;
use pino_outputs::physical::Physical;

/// Smallest relative residual used as a difficulty (a prediction satisfying its equations to
/// round-off must not get a zero-width interval).
const MIN_RELATIVE_RESIDUAL: f64 = 1e-12;

/// A calibration at one coverage: the quantile of every quantity.
#[derive(Debug, Clone)]
pub struct Calibrated<'a> {
    cal: &'a Calibration,
    /// The coverage.
    pub coverage: f64,
    index_q: Vec<f64>,
    channel_q: Vec<f64>,
}

/// One design's difficulty: the error heads' features and the relative residual.
#[derive(Debug, Clone, PartialEq)]
pub struct Difficulty {
    /// The error heads' features ([`Calibration::head_inputs`]).
    pub features: Vec<f64>,
    /// `g`, when the model has equations.
    pub relative_residual: Option<f64>,
}

/// What a calibration adds to one answer.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibratedAnswer {
    /// The coverage of the intervals.
    pub coverage: f64,
    /// The design lies outside the training ranges: no coverage claim.
    pub extrapolated: bool,
    /// The relative physics residual of the prediction, when it has one.
    pub relative_residual: Option<f64>,
    /// Per index (the calibration's order, the description's index order).
    pub indices: Vec<Interval>,
    /// Per index: its verdict against its limit (`None` without a limit).
    pub verdicts: Vec<Option<Verdict>>,
    /// The verdicts together (fail if any fails, else uncertain if any is); `None` without
    /// limits.
    pub verdict: Option<Verdict>,
    /// Per band channel: the band's half-width at each interior point (empty unless asked).
    pub bands: Vec<Vec<f64>>,
}

impl Calibration {
    /// The calibration at `coverage`: refused when it has no intervals, or when the level is
    /// outside (0, 1) or above what its `n` samples support.
    pub fn at(&self, coverage: f64) -> Result<Calibrated<'_>> {
        let level = |e: pino_conformal::Error| -> crate::Error {
            LearnError::OutOfRange {
                field: "coverage".into(),
                value: coverage.to_string(),
                allowed: e.to_string(),
            }
            .into()
        };
        pino_conformal::check_coverage(coverage).map_err(level)?;
        if let Some(why) = &self.no_intervals {
            return Err(LearnError::OutOfRange {
                field: "calibration".into(),
                value: format!("{} samples", self.n),
                allowed: format!("a calibration with samples: {why}"),
            }
            .into());
        }
        let q = |s: &QuantityScores| -> Result<f64> {
            s.scores
                .get(&self.normaliser)
                .ok_or_else(|| LearnError::OutOfRange {
                    field: format!("calibration: `{}`", s.name),
                    value: self.normaliser.as_str().into(),
                    allowed: "a normaliser with scores".into(),
                })?
                .quantile(coverage)
                .map_err(level)
        };
        Ok(Calibrated {
            cal: self,
            coverage,
            index_q: self.indices.iter().map(q).collect::<Result<_>>()?,
            channel_q: self
                .channels
                .iter()
                .map(|c| q(&c.quantity))
                .collect::<Result<_>>()?,
        })
    }

    /// The difficulty of one prediction `side` of a design with parameters `params` under
    /// excitations `eta [T, E]` at spacing `dt` (`probe`: the model's residual probe).
    pub fn difficulty(
        &self,
        system: &System,
        probe: Option<&ResidualProbe>,
        params: &[f64],
        side: &Physical,
        eta: &[f64],
        dt: f64,
    ) -> Result<Difficulty> {
        let g = match (&self.residual_reference, probe) {
            (Some(reference), Some(p)) => {
                let rms = p.rms(system, params, side, eta, dt)?;
                Some(relative_residual(&rms, reference))
            }
            _ => None,
        };
        Ok(self.difficulty_of(params, g))
    }

    /// The difficulty from the parameters and the relative residual `g` (a head reading the
    /// residual of a model without one gets no feature for it, and its `sigma` is refused).
    pub fn difficulty_of(&self, params: &[f64], g: Option<f64>) -> Difficulty {
        let mut features = Vec::with_capacity(params.len() + 1);
        for input in &self.head_inputs {
            match input {
                HeadInput::Parameters => features.extend_from_slice(params),
                HeadInput::Residual => {
                    features.extend(g.map(|g| g.max(MIN_RELATIVE_RESIDUAL).ln()))
                }
            }
        }
        Difficulty {
            features,
            relative_residual: g,
        }
    }

    /// `sigma` of quantity `q` for a design of difficulty `d` under normaliser `normaliser`.
    pub fn sigma(&self, normaliser: Normaliser, q: &QuantityScores, d: &Difficulty) -> Result<f64> {
        match normaliser {
            Normaliser::None => Ok(1.0),
            Normaliser::Residual => d
                .relative_residual
                .map(|g| g.max(MIN_RELATIVE_RESIDUAL))
                .ok_or_else(|| LearnError::OutOfRange {
                    field: "normaliser".into(),
                    value: "residual".into(),
                    allowed: "`none` or `error_head`: the model's predictions have no physics residual (no DOF has an equation with its outputs)".into(),
                }.into()),
            Normaliser::ErrorHead => {
                let head = q.head.as_ref().ok_or_else(|| LearnError::OutOfRange {
                    field: format!("calibration: `{}`", q.name),
                    value: "error_head".into(),
                    allowed: "a quantity with an error head".into(),
                })?;
                Ok(head.sigma(&d.features).map_err(|e| LearnError::OutOfRange {
                    field: format!("calibration: `{}`", q.name),
                    value: "error_head".into(),
                    allowed: e.to_string(),
                })?)
            }
        }
    }
}

impl Calibrated<'_> {
    /// The calibrated answer of one design of difficulty `d` with predicted index values
    /// `indices` (calibration order; empty: no index intervals), the indices' `limits`, and its
    /// `extrapolated` flag; with `bands`, every channel's band too.
    pub fn answer(
        &self,
        d: &Difficulty,
        indices: &[f64],
        limits: &[Option<f64>],
        extrapolated: bool,
        bands: bool,
    ) -> Result<CalibratedAnswer> {
        let cal = self.cal;
        let with_indices = !indices.is_empty();
        if with_indices && (indices.len() != cal.indices.len() || limits.len() != cal.indices.len())
        {
            return Err(LearnError::OutOfRange {
                field: "calibration: indices".into(),
                value: format!("{} values, {} limits", indices.len(), limits.len()),
                allowed: format!("the calibration's {} indices", cal.indices.len()),
            }
            .into());
        }
        let mut intervals = Vec::with_capacity(indices.len());
        for ((q, s), &f) in self.index_q.iter().zip(&cal.indices).zip(indices) {
            intervals.push(Interval::around(f, q * cal.sigma(cal.normaliser, s, d)?));
        }
        let verdicts: Vec<Option<Verdict>> = intervals
            .iter()
            .zip(limits)
            .map(|(i, l)| l.map(|l| Verdict::judge(*i, l, extrapolated)))
            .collect();
        let mut half = Vec::new();
        if bands {
            for (q, c) in self.channel_q.iter().zip(&cal.channels) {
                let w = q * cal.sigma(cal.normaliser, &c.quantity, d)?;
                half.push(c.scale.iter().map(|&s| w * s as f64).collect());
            }
        }
        Ok(CalibratedAnswer {
            coverage: self.coverage,
            extrapolated,
            relative_residual: d.relative_residual,
            verdict: Verdict::combine(verdicts.iter().flatten().copied()),
            indices: intervals,
            verdicts,
            bands: half,
        })
    }
}
