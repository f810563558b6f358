//! The error head: a difficulty `sigma(x)` for normalised scores, fitted on held-out errors
//! (Lei et al. 2018, locally adaptive conformal prediction).
//!
//! A log-linear ridge regression of the absolute error on features known without the solver
//! (the design's parameters, the prediction's own physics residual):
//! ```text
//! ln(|e| + eps) ~ w_0 + sum_j w_j (x_j - mean_j) / std_j,   eps = 1e-3 mean |e|
//! sigma(x)      = exp(clamp(w . x~, lo, hi))
//! ```
//! fitted on samples that are neither training nor calibration samples (the validation
//! split), so the calibration scores stay exchangeable with new designs. The ridge penalty
//! (not on the intercept) keeps a few dozen samples from overfitting many features; the clamp
//! to the fitted values' range widened by a factor 2 each way keeps an extrapolated design
//! from an absurdly narrow or wide band (its verdict is never better than uncertain anyway).

use crate::{Error, Result};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Relative floor added to the absolute errors before the logarithm.
const EPS_OF_MEAN: f64 = 1e-3;

/// Penalty per sample that every weight gets on top of the ridge (see [`ErrorHead::fit`]).
const CONSTANT_FEATURE_PENALTY: f64 = 1e-9;

/// A fitted error head.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ErrorHead {
    /// Feature means of the fit.
    pub mean: Vec<f64>,
    /// Feature standard deviations of the fit (1 where a feature was constant).
    pub std: Vec<f64>,
    /// Intercept, then one weight per feature (on standardised features).
    pub weights: Vec<f64>,
    /// Range `[lo, hi]` the fitted `ln sigma` is clamped to.
    pub log_range: [f64; 2],
}

impl ErrorHead {
    /// Fits `ln(|errors| + eps)` on `features` (one row per sample) with ridge penalty
    /// `ridge` (>= 0) on the standardised weights.
    pub fn fit(features: &[Vec<f64>], errors: &[f64], ridge: f64) -> Result<Self> {
        let n = features.len();
        let p = features.first().map_or(0, Vec::len);
        if n != errors.len() || n < 2 || features.iter().any(|r| r.len() != p) {
            return Err(Error::Shape(format!(
                "an error head needs at least 2 samples with one row of {p} features and one error each: {n} rows, {} errors",
                errors.len()
            )));
        }
        if !(ridge >= 0.0 && ridge.is_finite()) {
            return Err(Error::Shape(format!(
                "ridge penalty {ridge} must be finite and >= 0"
            )));
        }
        let bad = |what: &str, v: f64| Error::Shape(format!("{what} {v} is not finite"));
        for &v in features.iter().flatten() {
            if !v.is_finite() {
                return Err(bad("feature", v));
            }
        }
        for &e in errors {
            if !e.is_finite() {
                return Err(bad("error", e));
            }
        }
        let (mean, std) = standardisation(features, p);
        let abs_mean = errors.iter().map(|e| e.abs()).sum::<f64>() / n as f64;
        let eps = (EPS_OF_MEAN * abs_mean).max(f64::MIN_POSITIVE);
        let y = DVector::from_iterator(n, errors.iter().map(|e| (e.abs() + eps).ln()));
        let x = DMatrix::from_fn(n, p + 1, |r, c| {
            if c == 0 {
                1.0
            } else {
                (features[r][c - 1] - mean[c - 1]) / std[c - 1]
            }
        });
        let mut gram = x.transpose() * &x;
        // A constant feature standardises to a column of zeros: the tiny extra penalty keeps
        // its weight at 0 instead of making the system singular.
        for c in 1..=p {
            gram[(c, c)] += ridge + CONSTANT_FEATURE_PENALTY * n as f64;
        }
        let rhs = x.transpose() * &y;
        let w = gram
            .cholesky()
            .ok_or_else(|| Error::Shape("the error head's normal equations are singular".into()))?
            .solve(&rhs);
        let fitted = &x * &w;
        let (lo, hi) = fitted
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let widen = 2f64.ln();
        Ok(Self {
            mean,
            std,
            weights: w.iter().copied().collect(),
            log_range: [lo - widen, hi + widen],
        })
    }

    /// `sigma(x) > 0` of one sample's features.
    pub fn sigma(&self, features: &[f64]) -> Result<f64> {
        if features.len() != self.mean.len() {
            return Err(Error::Shape(format!(
                "the error head takes {} features, given {}",
                self.mean.len(),
                features.len()
            )));
        }
        let mut z = self.weights[0];
        for (j, &x) in features.iter().enumerate() {
            z += self.weights[j + 1] * (x - self.mean[j]) / self.std[j];
        }
        if !z.is_finite() {
            return Err(Error::Shape(format!(
                "the error head's output {z} is not finite (features {features:?})"
            )));
        }
        Ok(z.clamp(self.log_range[0], self.log_range[1]).exp())
    }
}

/// Mean and population standard deviation of each feature (1 for a constant feature).
fn standardisation(features: &[Vec<f64>], p: usize) -> (Vec<f64>, Vec<f64>) {
    let n = features.len() as f64;
    let mean: Vec<f64> = (0..p)
        .map(|j| features.iter().map(|r| r[j]).sum::<f64>() / n)
        .collect();
    let std = (0..p)
        .map(|j| {
            let v = features
                .iter()
                .map(|r| (r[j] - mean[j]).powi(2))
                .sum::<f64>()
                / n;
            if v > 0.0 {
                v.sqrt()
            } else {
                1.0
            }
        })
        .collect();
    (mean, std)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Errors `exp(0.5 + 0.8 x) |xi|`: the head recovers the slope on the standardised feature
    /// (0.8 std(x)); ln|xi| only shifts the intercept.
    #[test]
    fn the_head_recovers_a_log_linear_error_law() {
        let mut s = mbd_dataset::SampleStream::with_code(3, 901, 0);
        let mut feats = Vec::new();
        let mut errs = Vec::new();
        for _ in 0..4000 {
            let x = s.uniform_in(-1.0, 1.0);
            let noise = s.normal();
            feats.push(vec![x, s.uniform()]);
            errs.push((0.5 + 0.8 * x).exp() * noise);
        }
        let head = ErrorHead::fit(&feats, &errs, 1.0).unwrap();
        let slope = head.weights[1] / head.std[0];
        assert!((slope - 0.8).abs() < 0.05, "slope {slope}");
        assert!(
            head.weights[2].abs() < 0.05,
            "the irrelevant feature's weight {}",
            head.weights[2]
        );
        // ln|N(0,1)| has mean -0.635: the intercept is 0.5 - 0.635 at x = mean.
        let at_zero = head.sigma(&[0.0, head.mean[1]]).unwrap().ln();
        assert!((at_zero - (0.5 - 0.635)).abs() < 0.06, "{at_zero}");
        // Clamped far outside the fitted range.
        let far = head.sigma(&[1e6, 0.5]).unwrap().ln();
        assert!((far - head.log_range[1]).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs_are_refused_with_the_reason() {
        assert!(ErrorHead::fit(&[vec![1.0]], &[1.0], 1.0).is_err());
        assert!(ErrorHead::fit(&[vec![1.0], vec![2.0]], &[1.0], 1.0).is_err());
        assert!(ErrorHead::fit(&[vec![1.0], vec![f64::NAN]], &[1.0, 2.0], 1.0).is_err());
        assert!(ErrorHead::fit(&[vec![1.0], vec![2.0]], &[1.0, 2.0], -1.0).is_err());
        let head =
            ErrorHead::fit(&[vec![1.0], vec![2.0], vec![3.0]], &[1.0, 2.0, 3.0], 0.1).unwrap();
        assert!(head
            .sigma(&[1.0, 2.0])
            .unwrap_err()
            .to_string()
            .contains("takes 1 features"));
        // A constant feature is harmless.
        let c = ErrorHead::fit(&[vec![5.0], vec![5.0], vec![5.0]], &[1.0, 2.0, 3.0], 0.0).unwrap();
        assert_eq!(c.std, [1.0]);
    }
}
