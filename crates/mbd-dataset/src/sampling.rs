//! Splits and parameter sampling: every sampled parameter of the system description is drawn
//! independently and uniformly on its range, `x = lo + (hi - lo) u`, `u ~ U[0, 1)`.
//!
//! Sample ids `0..n_train` are the training split, the next `n_validation` ids the validation
//! split, the `n_test` ids after those the test split (held out from every choice of
//! settings) and the `n_calibration` ids after those the calibration split (held-out solver
//! runs that only the conformal calibration reads: never training, early stopping or the
//! choice of settings); adding test or calibration samples leaves every earlier draw
//! unchanged. Sample
//! `id` takes its values, in the description's order of sampled parameters, from
//! `SampleStream::new(seed, Purpose::Parameters, id)`: they depend only on `(seed, id)`, not on
//! the order, the thread or the shard that draws them.

use crate::rng::{Purpose, SampleStream};
use crate::{Error, Result};
use mbd_system::System;
use serde::{Deserialize, Serialize};

/// Counts and seed as written in the pipeline (unchecked).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplitSizes {
    /// Seed of every parameter draw.
    pub seed: u64,
    /// Training samples (ids `0..n_train`), at least 1.
    pub n_train: u64,
    /// Validation samples, at least 1.
    pub n_validation: u64,
    /// Test samples, at least 1.
    pub n_test: u64,
    /// Calibration samples (ids after the test split), 0 or more; 0: no calibration, and
    /// nothing downstream claims a coverage.
    #[serde(default)]
    pub n_calibration: u64,
}

impl SplitSizes {
    /// The four counts in id order, with their pipeline names.
    fn counts(&self) -> [(Split, &'static str, u64); 4] {
        [
            (Split::Train, "n_train", self.n_train),
            (Split::Validation, "n_validation", self.n_validation),
            (Split::Test, "n_test", self.n_test),
            (Split::Calibration, "n_calibration", self.n_calibration),
        ]
    }
}

/// Which split a sample belongs to (the `split` column of `params.parquet`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Split {
    /// Training sample.
    Train,
    /// Validation sample (model selection, per-epoch reports).
    Validation,
    /// Test sample: held out for the final report (Table 4).
    Test,
    /// Calibration sample: a held-out solver run for the conformal intervals only.
    Calibration,
}

impl Split {
    /// Every split, in id order.
    pub const ALL: [Split; 4] = [
        Split::Train,
        Split::Validation,
        Split::Test,
        Split::Calibration,
    ];

    /// The label written in the `split` column.
    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Validation => "validation",
            Split::Test => "test",
            Split::Calibration => "calibration",
        }
    }

    /// The split of a `split` label, `None` for any other text.
    pub fn from_label(label: &str) -> Option<Split> {
        Split::ALL.into_iter().find(|s| s.as_str() == label)
    }
}

/// A checked sampling plan over a description's sampled parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct SamplingPlan {
    sizes: SplitSizes,
    ranges: Vec<[f64; 2]>,
}

impl SamplingPlan {
    /// Checks the counts (each >= 1, total an i64) and takes the ranges of `system`.
    pub fn new(sizes: SplitSizes, system: &System) -> Result<Self> {
        for (split, field, n) in sizes.counts() {
            if n == 0 && split != Split::Calibration {
                return Err(Error::OutOfRange {
                    name: field.to_owned(),
                    value: 0.0,
                    allowed: "an integer >= 1".to_owned(),
                });
            }
        }
        let total = sizes
            .counts()
            .iter()
            .try_fold(0u64, |t, &(_, _, n)| t.checked_add(n));
        if total.is_none_or(|t| t > i64::MAX as u64) {
            return Err(Error::OutOfRange {
                name: "n_train + n_validation + n_test + n_calibration".to_owned(),
                value: sizes.counts().iter().map(|&(_, _, n)| n as f64).sum(),
                allowed: format!("<= {} (sample ids are i64)", i64::MAX),
            });
        }
        Ok(Self {
            sizes,
            ranges: system.ranges(),
        })
    }

    /// Total number of samples.
    pub fn num_samples(&self) -> u64 {
        self.sizes.counts().iter().map(|&(_, _, n)| n).sum()
    }

    /// The sizes.
    pub fn sizes(&self) -> SplitSizes {
        self.sizes
    }

    /// The `[min, max]` of every sampled parameter.
    pub fn ranges(&self) -> &[[f64; 2]] {
        &self.ranges
    }

    /// The split of sample `id` (an id past the end falls in the last non-empty split).
    pub fn split(&self, id: u64) -> Split {
        let mut end = 0;
        let mut last = Split::Train;
        for (split, _, n) in self.sizes.counts() {
            end += n;
            if n > 0 {
                last = split;
            }
            if id < end {
                return split;
            }
        }
        last
    }

    /// The sampled parameters of sample `id`, in the description's order:
    /// `x_j = lo_j + (hi_j - lo_j) u_j`, `u_j` the `j`-th uniform of its stream.
    pub fn draw(&self, id: u64) -> Vec<f64> {
        let mut stream = SampleStream::new(self.sizes.seed, Purpose::Parameters, id);
        self.ranges
            .iter()
            .map(|&[lo, hi]| stream.uniform_in(lo, hi))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "format: 1\nname: t\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n  k: {unit: N/m, nominal: 800, range: {factor: [0.5, 1.5]}}\nbodies:\n  b: {mass: m, dofs: [z]}\nelements:\n  s: {kind: spring_damper, from: b, to: ground, k: k}\n";

    fn plan(n_train: u64, n_validation: u64, n_test: u64) -> Result<SamplingPlan> {
        plan_with_calibration(n_train, n_validation, n_test, 0)
    }

    fn plan_with_calibration(
        n_train: u64,
        n_validation: u64,
        n_test: u64,
        n_calibration: u64,
    ) -> Result<SamplingPlan> {
        let system = mbd_system::load_str(TEXT, "t.yaml", &Default::default()).unwrap();
        SamplingPlan::new(
            SplitSizes {
                seed: 11,
                n_train,
                n_validation,
                n_test,
                n_calibration,
            },
            &system,
        )
    }

    #[test]
    fn splits_follow_ids_and_draws_stay_in_range() {
        let p = plan(3, 2, 1).unwrap();
        let labels: Vec<&str> = (0..6).map(|id| p.split(id).as_str()).collect();
        assert_eq!(
            labels,
            [
                "train",
                "train",
                "train",
                "validation",
                "validation",
                "test"
            ]
        );
        assert_eq!(p.ranges(), [[1.0, 3.0], [400.0, 1200.0]]);
        for id in 0..200 {
            let v = p.draw(id);
            assert!(
                (1.0..3.0).contains(&v[0]) && (400.0..1200.0).contains(&v[1]),
                "{v:?}"
            );
        }
    }

    /// A sample's draw depends on (seed, id) only: more test samples change nothing before.
    #[test]
    fn draws_depend_on_seed_and_id_only() {
        let a = plan(3, 2, 1).unwrap();
        let b = plan(3, 2, 50).unwrap();
        assert_eq!(a.draw(4), b.draw(4));
        assert_ne!(a.draw(4), a.draw(5));
        // The values of the first draw are the stream's first uniforms mapped to the ranges.
        let mut s = SampleStream::new(11, Purpose::Parameters, 4);
        assert_eq!(
            a.draw(4),
            [s.uniform_in(1.0, 3.0), s.uniform_in(400.0, 1200.0)]
        );
    }

    /// Calibration ids follow the test split; adding them changes no earlier draw or split.
    #[test]
    fn calibration_ids_follow_the_test_split() {
        let without = plan(3, 2, 1).unwrap();
        let with = plan_with_calibration(3, 2, 1, 4).unwrap();
        assert_eq!(with.num_samples(), 10);
        let labels: Vec<&str> = (0..10).map(|id| with.split(id).as_str()).collect();
        assert_eq!(
            &labels[5..],
            [
                "test",
                "calibration",
                "calibration",
                "calibration",
                "calibration"
            ]
        );
        for id in 0..6 {
            assert_eq!(with.split(id), without.split(id));
            assert_eq!(with.draw(id), without.draw(id));
        }
        assert_eq!(
            without.split(6),
            Split::Test,
            "past the end: the last non-empty split"
        );
        for split in Split::ALL {
            assert_eq!(Split::from_label(split.as_str()), Some(split));
        }
        assert_eq!(Split::from_label("holdout"), None);
    }

    #[test]
    fn empty_splits_are_refused_with_the_field_named() {
        assert!(plan(0, 1, 1).unwrap_err().to_string().contains("n_train"));
        assert!(plan(1, 0, 1)
            .unwrap_err()
            .to_string()
            .contains("n_validation"));
        assert!(plan(1, 1, 0).unwrap_err().to_string().contains("n_test"));
        assert!(plan(u64::MAX, 1, 1).is_err());
    }
}
