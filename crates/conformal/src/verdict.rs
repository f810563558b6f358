//! Intervals and the three-valued verdict of a calibrated answer against its limit.
//!
//! Limits are upper limits: a value passes at or below it (`docs/indices.md`). With an
//! interval `[lo, hi]` at coverage `1 - alpha`:
//! - `pass` when `hi <= limit` (the whole interval inside): wrong with probability at most
//!   alpha, marginally;
//! - `fail` when `lo > limit` (the whole interval outside);
//! - `uncertain` otherwise (the interval straddles the limit): send the design to the solver.
//!
//! A design outside the training ranges has no coverage claim: its interval is still computed,
//! but its verdict is never better than `uncertain` (a pass becomes uncertain; a fail stays).

use serde::{Deserialize, Serialize};

/// A calibrated interval `[lo, hi]` around a predicted value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Interval {
    /// `value +- half_width`.
    pub fn around(value: f64, half_width: f64) -> Self {
        Self {
            lo: value - half_width,
            hi: value + half_width,
        }
    }

    /// Its width `hi - lo`.
    pub fn width(&self) -> f64 {
        self.hi - self.lo
    }

    /// Whether `x` lies inside (ends included).
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }
}

/// The verdict of one answer against one limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// The whole interval at or below the limit.
    Pass,
    /// The interval straddles the limit (or the design is extrapolated): ask the solver.
    Uncertain,
    /// The whole interval above the limit.
    Fail,
}

impl Verdict {
    /// The label written in tables (`pass`, `uncertain`, `fail`).
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Uncertain => "uncertain",
            Verdict::Fail => "fail",
        }
    }

    /// The verdict of `interval` against the upper `limit`; `extrapolated` (a design outside
    /// the training ranges) turns a pass into uncertain.
    pub fn judge(interval: Interval, limit: f64, extrapolated: bool) -> Self {
        let v = if interval.hi <= limit {
            Verdict::Pass
        } else if interval.lo > limit {
            Verdict::Fail
        } else {
            Verdict::Uncertain
        };
        if extrapolated && v == Verdict::Pass {
            Verdict::Uncertain
        } else {
            v
        }
    }

    /// The verdict of several answers together: fail if any fails, else uncertain if any is
    /// uncertain, else pass (`None` when there is none).
    pub fn combine(verdicts: impl IntoIterator<Item = Verdict>) -> Option<Self> {
        verdicts.into_iter().max()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_verdict_follows_where_the_interval_lies() {
        let at = |lo, hi| Interval { lo, hi };
        assert_eq!(Verdict::judge(at(1.0, 2.0), 2.0, false), Verdict::Pass);
        assert_eq!(Verdict::judge(at(1.0, 2.5), 2.0, false), Verdict::Uncertain);
        assert_eq!(Verdict::judge(at(2.0, 2.5), 2.0, false), Verdict::Uncertain);
        assert_eq!(Verdict::judge(at(2.1, 2.5), 2.0, false), Verdict::Fail);
        assert_eq!(Verdict::judge(at(1.0, 2.0), 2.0, true), Verdict::Uncertain);
        assert_eq!(Verdict::judge(at(2.1, 2.5), 2.0, true), Verdict::Fail);
        let i = Interval::around(3.0, 0.5);
        assert_eq!((i.lo, i.hi, i.width()), (2.5, 3.5, 1.0));
        assert!(i.contains(2.5) && i.contains(3.5) && !i.contains(3.6));
    }

    #[test]
    fn several_verdicts_combine_to_the_worst() {
        use Verdict::*;
        assert_eq!(Verdict::combine([Pass, Pass]), Some(Pass));
        assert_eq!(Verdict::combine([Pass, Uncertain, Pass]), Some(Uncertain));
        assert_eq!(Verdict::combine([Uncertain, Fail, Pass]), Some(Fail));
        assert_eq!(Verdict::combine([]), None);
        assert_eq!(serde_json::to_string(&Uncertain).unwrap(), "\"uncertain\"");
    }
}
