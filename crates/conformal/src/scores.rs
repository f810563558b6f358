//! Calibration scores and their conformal quantile.
//!
//! With `n` scores sorted `s_(1) <= ... <= s_(n)`, the quantile at coverage `c` is `s_(k)`,
//! `k = ceil((n + 1) c)`. When `k > n` no finite quantile exists: a level above `n / (n + 1)`
//! is refused ([`crate::Error::Unsupported`]), never silently capped.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Tolerance of the rank's ceiling: `(n + 1) c` computed in floating point may land a hair
/// above an integer it equals exactly (`10 * 0.9`), which must not raise the rank.
const RANK_TOLERANCE: f64 = 1e-9;

/// Checks that `coverage` is a level in (0, 1).
pub fn check_coverage(coverage: f64) -> Result<()> {
    if coverage > 0.0 && coverage < 1.0 {
        Ok(())
    } else {
        Err(Error::Coverage { value: coverage })
    }
}

/// The sorted nonconformity scores of one quantity (an index, a channel's band).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<f64>", into = "Vec<f64>")]
pub struct ScoreSet {
    sorted: Vec<f64>,
}

impl TryFrom<Vec<f64>> for ScoreSet {
    type Error = Error;
    fn try_from(scores: Vec<f64>) -> Result<Self> {
        Self::new(scores)
    }
}

impl From<ScoreSet> for Vec<f64> {
    fn from(s: ScoreSet) -> Vec<f64> {
        s.sorted
    }
}

impl ScoreSet {
    /// The scores of the calibration samples (any order); each finite and >= 0.
    pub fn new(mut scores: Vec<f64>) -> Result<Self> {
        if let Some((index, &value)) = scores
            .iter()
            .enumerate()
            .find(|(_, s)| !(s.is_finite() && **s >= 0.0))
        {
            return Err(Error::BadScore { index, value });
        }
        scores.sort_by(f64::total_cmp);
        Ok(Self { sorted: scores })
    }

    /// Number of calibration scores `n`.
    pub fn len(&self) -> usize {
        self.sorted.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.sorted.is_empty()
    }

    /// The scores, ascending.
    pub fn sorted(&self) -> &[f64] {
        &self.sorted
    }

    /// The highest coverage `n` scores support: `n / (n + 1)`.
    pub fn max_coverage(&self) -> f64 {
        max_coverage(self.len())
    }

    /// The 1-based rank `k = ceil((n + 1) c)` of the quantile at coverage `c`.
    pub fn rank(&self, coverage: f64) -> Result<usize> {
        rank(self.len(), coverage)
    }

    /// The conformal quantile `q = s_(k)` at coverage `c` (0 < c <= n / (n + 1)).
    pub fn quantile(&self, coverage: f64) -> Result<f64> {
        Ok(self.sorted[self.rank(coverage)? - 1])
    }
}

/// The highest coverage `n` calibration scores support: `n / (n + 1)`.
pub fn max_coverage(n: usize) -> f64 {
    n as f64 / (n as f64 + 1.0)
}

/// The 1-based rank `k = ceil((n + 1) c)` of the conformal quantile, refused when `k > n`.
pub fn rank(n: usize, coverage: f64) -> Result<usize> {
    check_coverage(coverage)?;
    let k = (((n as f64 + 1.0) * coverage) - RANK_TOLERANCE)
        .ceil()
        .max(1.0) as usize;
    if k > n {
        return Err(Error::Unsupported {
            value: coverage,
            n,
            max: max_coverage(n),
        });
    }
    Ok(k)
}

/// The score of a curve for a simultaneous band: `max_t |exact(t) - predicted(t)| / scale(t)`
/// over the points given (every `scale(t)` > 0). The band `predicted(t) +- q scale(t)` then
/// holds the whole curve exactly when this score is at most `q`.
pub fn sup_score(predicted: &[f64], exact: &[f64], scale: &[f64]) -> Result<f64> {
    if predicted.len() != exact.len() || predicted.len() != scale.len() {
        return Err(Error::Shape(format!(
            "a band score needs curves and a scale of one length: {} predicted, {} exact, {} scale points",
            predicted.len(),
            exact.len(),
            scale.len()
        )));
    }
    let mut worst = 0.0f64;
    for ((p, x), s) in predicted.iter().zip(exact).zip(scale) {
        let r = (x - p).abs() / s;
        // A NaN must not be dropped by max: it makes the score invalid and ScoreSet refuses it.
        worst = if r.is_nan() { f64::NAN } else { worst.max(r) };
        if worst.is_nan() {
            break;
        }
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rank_is_the_ceiling_of_n_plus_one_times_the_level() {
        assert_eq!(rank(9, 0.9), Ok(9));
        assert_eq!(rank(19, 0.9), Ok(18));
        assert_eq!(rank(200, 0.9), Ok(181));
        assert_eq!(rank(200, 0.8), Ok(161));
        assert_eq!(rank(200, 0.95), Ok(191));
        assert_eq!(rank(3, 0.01), Ok(1));
    }

    #[test]
    fn levels_above_n_over_n_plus_one_are_refused_with_the_reason() {
        let err = rank(8, 0.9).unwrap_err();
        assert!(matches!(err, Error::Unsupported { n: 8, .. }), "{err:?}");
        let msg = err.to_string();
        assert!(
            msg.contains("0.8889") && msg.contains("8 calibration samples"),
            "{msg}"
        );
        assert!(rank(200, 0.995).is_ok());
        assert!(rank(200, 0.996).is_err());
        assert!(rank(0, 0.5).is_err());
        for bad in [0.0, 1.0, -0.1, 1.5, f64::NAN] {
            assert!(
                matches!(rank(200, bad), Err(Error::Coverage { .. })),
                "{bad}"
            );
        }
    }

    #[test]
    fn the_quantile_is_the_kth_smallest_score() {
        let s = ScoreSet::new((1..=9).rev().map(f64::from).collect()).unwrap();
        assert_eq!(s.sorted()[0], 1.0);
        assert_eq!(s.quantile(0.9), Ok(9.0));
        assert_eq!(s.quantile(0.5), Ok(5.0));
        assert!(ScoreSet::new(vec![1.0, f64::NAN]).is_err());
        assert!(ScoreSet::new(vec![-1.0]).is_err());
    }

    #[test]
    fn scores_round_trip_through_json_and_refuse_bad_values() {
        let s = ScoreSet::new(vec![0.3, 0.1, 0.2]).unwrap();
        let text = serde_json::to_string(&s).unwrap();
        assert_eq!(text, "[0.1,0.2,0.3]");
        assert_eq!(serde_json::from_str::<ScoreSet>(&text).unwrap(), s);
        let err = serde_json::from_str::<ScoreSet>("[0.1,-2.0]").unwrap_err();
        assert!(err.to_string().contains("score 1 is -2"), "{err}");
    }

    #[test]
    fn the_sup_score_is_the_worst_scaled_deviation() {
        let p = [0.0, 1.0, 2.0];
        let x = [0.5, 1.0, 1.0];
        assert_eq!(sup_score(&p, &x, &[1.0, 1.0, 2.0]), Ok(0.5));
        assert_eq!(sup_score(&p, &x, &[0.25, 1.0, 4.0]), Ok(2.0));
        assert!(sup_score(&p, &x, &[1.0]).is_err());
        assert!(sup_score(&[f64::NAN], &[0.0], &[1.0]).unwrap().is_nan());
    }
}
