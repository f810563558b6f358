//! Parameter sampling (`docs/model.md`, Parameters): each of the 14 parameters of a sample is
//! drawn independently and uniformly on its range, `x = lo + (hi - lo) u`, `u ~ U[0, 1)`.
//!
//! Default ranges (the spec's table): the first eleven are `0.8-1.2 x` the CRH380 nominal value
//! ([`SampleParams::NOMINAL`]); `v_kmh` 300-350 km/h, `k_f` 3.5e7-4.5e7 N/m, `c_f` 4e4-5e4 N s/m.
//! Every range can be overridden, either relative to a nominal value or absolute:
//!
//! ```yaml
//! seed: 1
//! n_train: 160
//! n_validation: 40
//! n_test: 100
//! ranges:
//!   m_c: {nominal: 38880, factor: [0.8, 1.2]}   # kg, whole vehicle
//!   v_kmh: [300, 350]                            # km/h
//! ```
//!
//! Parse ([`SamplingParams`], serde) -> validate ([`SamplingParams::validate`]) -> run
//! ([`SamplingPlan::draw`]). Sample ids `0..n_train` are the training split, the next
//! `n_validation` ids the validation split and the `n_test` ids after those the test split
//! (held out from every choice of settings). Adding the test split therefore leaves the ids,
//! splits and draws of the training and validation samples unchanged. Sample `id` takes its 14 values, in the spec's
//! order, from `SampleStream::new(seed, Purpose::Parameters, id)`, so a sample's values depend
//! only on `(seed, id)`: not on the order, the thread or the shard that draws it.

use crate::params::{SampleParams, NUM_PARAMETERS, PARAMETER_NAMES};
use crate::rng::{Purpose, SampleStream};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Relative range of the first eleven parameters around their nominal value (spec: 80%-120%).
pub const NOMINAL_FACTOR: [f64; 2] = [0.8, 1.2];
/// Running speed range (km/h).
pub const V_KMH_RANGE: [f64; 2] = [300.0, 350.0];
/// Fastener stiffness range (N/m).
pub const K_F_RANGE: [f64; 2] = [3.5e7, 4.5e7];
/// Fastener damping range (N s/m).
pub const C_F_RANGE: [f64; 2] = [4e4, 5e4];

/// How one parameter's range is written: `[min, max]` or `{nominal: X, factor: [lo, hi]}`
/// (giving `[lo X, hi X]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "a parameter range: `[min, max]` or `{nominal: X, factor: [lo, hi]}`"
)]
pub enum RangeSpec {
    /// Absolute bounds `[min, max]` in the parameter's unit.
    Absolute([f64; 2]),
    /// Bounds relative to a nominal value.
    Relative {
        /// Nominal value, in the parameter's unit.
        nominal: f64,
        /// Multipliers `[lo, hi]` of the nominal value.
        factor: [f64; 2],
    },
}

impl RangeSpec {
    /// The absolute bounds `[min, max]`.
    pub fn bounds(&self) -> [f64; 2] {
        match *self {
            RangeSpec::Absolute(b) => b,
            RangeSpec::Relative { nominal, factor } => [nominal * factor[0], nominal * factor[1]],
        }
    }
}

/// The spec's default range of parameter `i` (in [`PARAMETER_NAMES`] order).
pub fn default_range(i: usize) -> RangeSpec {
    match PARAMETER_NAMES[i] {
        "v_kmh" => RangeSpec::Absolute(V_KMH_RANGE),
        "k_f" => RangeSpec::Absolute(K_F_RANGE),
        "c_f" => RangeSpec::Absolute(C_F_RANGE),
        _ => RangeSpec::Relative {
            nominal: SampleParams::NOMINAL.to_array()[i],
            factor: NOMINAL_FACTOR,
        },
    }
}

/// The sampling configuration as written in the pipeline (unchecked).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingParams {
    /// Seed of every parameter draw.
    pub seed: u64,
    /// Number of training samples (ids `0..n_train`), at least 1.
    pub n_train: u64,
    /// Number of validation samples (the ids after the training ones), at least 1.
    pub n_validation: u64,
    /// Number of test samples (the ids after the validation ones), at least 1.
    pub n_test: u64,
    /// Range overrides by parameter name; parameters not listed keep the spec's range.
    #[serde(default)]
    pub ranges: BTreeMap<String, RangeSpec>,
}

/// Which split a sample belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Split {
    /// Training sample.
    Train,
    /// Validation sample.
    Validation,
    /// Test sample: held out for the final report.
    Test,
}

impl Split {
    /// The label written in the `split` column (`"train"`, `"validation"` or `"test"`).
    pub fn as_str(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Validation => "validation",
            Split::Test => "test",
        }
    }
}

/// A checked sampling configuration: every range finite, positive and non-empty.
#[derive(Debug, Clone, PartialEq)]
pub struct SamplingPlan {
    seed: u64,
    n_train: u64,
    n_validation: u64,
    n_test: u64,
    ranges: [[f64; 2]; NUM_PARAMETERS],
}

impl SamplingParams {
    /// Checks counts and ranges; names the field and the allowed range on failure.
    pub fn validate(&self) -> Result<SamplingPlan> {
        for (field, n) in [
            ("n_train", self.n_train),
            ("n_validation", self.n_validation),
            ("n_test", self.n_test),
        ] {
            if n == 0 {
                return Err(Error::OutOfRange {
                    name: field.to_owned(),
                    value: 0.0,
                    allowed: "an integer >= 1".to_owned(),
                });
            }
        }
        let total = self
            .n_train
            .checked_add(self.n_validation)
            .and_then(|t| t.checked_add(self.n_test));
        if total.is_none_or(|t| t > i64::MAX as u64) {
            return Err(Error::OutOfRange {
                name: "n_train + n_validation + n_test".to_owned(),
                value: self.n_train as f64 + self.n_validation as f64 + self.n_test as f64,
                allowed: format!("<= {} (sample ids are i64)", i64::MAX),
            });
        }
        for name in self.ranges.keys() {
            if !PARAMETER_NAMES.contains(&name.as_str()) {
                return Err(Error::UnknownParameter {
                    name: name.clone(),
                    allowed: PARAMETER_NAMES.join(", "),
                });
            }
        }
        let mut ranges = [[0.0; 2]; NUM_PARAMETERS];
        for (i, name) in PARAMETER_NAMES.iter().enumerate() {
            let spec = self.ranges.get(*name).copied().unwrap_or(default_range(i));
            let [lo, hi] = spec.bounds();
            // Every parameter is a mass, inertia, stiffness, damping, length or speed: > 0.
            if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi) {
                let [dlo, dhi] = default_range(i).bounds();
                let what = if lo.is_finite() && hi.is_finite() && lo > 0.0 && lo >= hi {
                    "empty or inverted"
                } else {
                    "bounds must be finite and > 0"
                };
                return Err(Error::InvalidRange {
                    name: (*name).to_owned(),
                    lo,
                    hi,
                    allowed: format!(
                        "{what}; need finite 0 < min < max (spec range [{dlo}, {dhi}])"
                    ),
                });
            }
            ranges[i] = [lo, hi];
        }
        Ok(SamplingPlan {
            seed: self.seed,
            n_train: self.n_train,
            n_validation: self.n_validation,
            n_test: self.n_test,
            ranges,
        })
    }
}

impl SamplingPlan {
    /// Total number of samples, `n_train + n_validation + n_test`.
    pub fn num_samples(&self) -> u64 {
        self.n_train + self.n_validation + self.n_test
    }

    /// Number of training samples.
    pub fn n_train(&self) -> u64 {
        self.n_train
    }

    /// Number of validation samples.
    pub fn n_validation(&self) -> u64 {
        self.n_validation
    }

    /// Number of test samples.
    pub fn n_test(&self) -> u64 {
        self.n_test
    }

    /// The checked `[min, max]` of every parameter, in spec order.
    pub fn ranges(&self) -> &[[f64; 2]; NUM_PARAMETERS] {
        &self.ranges
    }

    /// The split of sample `id`: train for `id < n_train`, then `n_validation` validation
    /// ids, test after.
    pub fn split(&self, id: u64) -> Split {
        if id < self.n_train {
            Split::Train
        } else if id < self.n_train + self.n_validation {
            Split::Validation
        } else {
            Split::Test
        }
    }

    /// The 14 parameters of sample `id`: in spec order, `x_j = lo_j + (hi_j - lo_j) u_j` with
    /// `u_j` the `j`-th uniform of the sample's [`Purpose::Parameters`] stream.
    pub fn draw(&self, id: u64) -> SampleParams {
        let mut stream = SampleStream::new(self.seed, Purpose::Parameters, id);
        let mut values = [0.0; NUM_PARAMETERS];
        for (v, [lo, hi]) in values.iter_mut().zip(self.ranges) {
            *v = stream.uniform_in(lo, hi);
        }
        SampleParams::from_array(values)
    }

    /// Every sample in id order: `(id, split, parameters)`.
    pub fn samples(&self) -> Vec<(u64, Split, SampleParams)> {
        (0..self.num_samples())
            .map(|id| (id, self.split(id), self.draw(id)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(n_train: u64, n_validation: u64) -> SamplingParams {
        SamplingParams {
            seed: 11,
            n_train,
            n_validation,
            n_test: 1,
            ranges: BTreeMap::new(),
        }
    }

    fn with_range(name: &str, spec: RangeSpec) -> SamplingParams {
        let mut p = params(3, 2);
        p.ranges.insert(name.to_owned(), spec);
        p
    }

    #[test]
    fn default_ranges_are_the_spec_table() {
        let plan = params(1, 1).validate().unwrap();
        let r = plan.ranges();
        // m_c: 0.8 and 1.2 x 38880 kg; l_t: 0.8 and 1.2 x 1.2 m; then the absolute ranges.
        assert_eq!(r[0], [0.8 * 38880.0, 1.2 * 38880.0]);
        assert_eq!(r[10], [0.8 * 1.2, 1.2 * 1.2]);
        assert_eq!(r[11], [300.0, 350.0]);
        assert_eq!(r[12], [3.5e7, 4.5e7]);
        assert_eq!(r[13], [4e4, 5e4]);
    }

    #[test]
    fn splits_follow_ids() {
        let plan = params(3, 2).validate().unwrap();
        let s: Vec<_> = plan
            .samples()
            .iter()
            .map(|(id, s, _)| (*id, s.as_str()))
            .collect();
        assert_eq!(
            s,
            [
                (0, "train"),
                (1, "train"),
                (2, "train"),
                (3, "validation"),
                (4, "validation"),
                (5, "test")
            ]
        );
        let plan = SamplingParams {
            n_test: 3,
            ..params(2, 1)
        }
        .validate()
        .unwrap();
        let s: Vec<_> = plan.samples().iter().map(|(_, s, _)| *s).collect();
        use Split::*;
        assert_eq!(s, [Train, Train, Validation, Test, Test, Test]);
        assert_eq!((plan.n_test(), plan.num_samples()), (3, 6));
    }

    /// The test split is appended after the validation ids: the training and validation
    /// samples of a plan with a test split are exactly those of the same plan with any other
    /// test count (ids, splits and draws), so earlier artifacts for them stay valid.
    #[test]
    fn test_split_leaves_train_and_validation_unchanged() {
        let small = SamplingParams {
            n_test: 1,
            ..params(7, 3)
        }
        .validate()
        .unwrap();
        let big = SamplingParams {
            n_test: 100,
            ..params(7, 3)
        }
        .validate()
        .unwrap();
        let (a, b) = (small.samples(), big.samples());
        assert_eq!(a[..10], b[..10]);
        assert!(b[10..].iter().all(|(_, s, _)| *s == Split::Test));
        assert_eq!(b.len(), 110);
        // Test draws are fresh samples, not copies of training ones.
        assert_ne!(b[10].2, b[0].2);
    }

    #[test]
    fn draws_depend_only_on_seed_and_id() {
        let plan = params(40, 10).validate().unwrap();
        let forward: Vec<SampleParams> = (0..50).map(|id| plan.draw(id)).collect();
        // Reverse order, a second plan object, and the upper half on another thread.
        let again = params(40, 10).validate().unwrap();
        let mut reverse: Vec<SampleParams> = (0..50).rev().map(|id| again.draw(id)).collect();
        reverse.reverse();
        assert_eq!(forward, reverse);
        let upper = std::thread::scope(|s| {
            s.spawn(|| (25..50).map(|id| plan.draw(id)).collect::<Vec<_>>())
                .join()
                .unwrap()
        });
        assert_eq!(&forward[25..], &upper[..]);
        // The sample set of a larger plan with the same seed starts with the same samples.
        let bigger = params(400, 100).validate().unwrap();
        assert_eq!(bigger.draw(7), forward[7]);
        // Another seed gives other values.
        let mut other = params(40, 10);
        other.seed = 12;
        assert_ne!(other.validate().unwrap().draw(7), forward[7]);
    }

    #[test]
    fn draws_are_uniform_on_their_ranges() {
        let n = 20_000u64;
        let plan = params(n, 1).validate().unwrap();
        let ranges = *plan.ranges();
        let mut u = vec![[0.0; NUM_PARAMETERS]; n as usize];
        for (id, row) in u.iter_mut().enumerate() {
            let x = plan.draw(id as u64).to_array();
            for j in 0..NUM_PARAMETERS {
                let [lo, hi] = ranges[j];
                assert!(
                    x[j] >= lo && x[j] < hi,
                    "{} = {} outside [{lo}, {hi})",
                    PARAMETER_NAMES[j],
                    x[j]
                );
                row[j] = (x[j] - lo) / (hi - lo);
            }
        }
        let nf = n as f64;
        for j in 0..NUM_PARAMETERS {
            let mean = u.iter().map(|r| r[j]).sum::<f64>() / nf;
            let var = u.iter().map(|r| (r[j] - mean).powi(2)).sum::<f64>() / nf;
            // U[0,1): mean 1/2 with standard error sqrt(1/12/n) = 0.0020; variance 1/12 with
            // standard error sqrt((1/80 - 1/144)/n) = 0.00053. Bounds are 4 standard errors.
            assert!(
                (mean - 0.5).abs() < 4.0 * (1.0 / 12.0 / nf).sqrt(),
                "{j}: mean {mean}"
            );
            assert!(
                (var - 1.0 / 12.0).abs() < 4.0 * ((1.0 / 80.0 - 1.0 / 144.0) / nf).sqrt(),
                "{j}: var {var}"
            );
            // Independence of neighbouring parameters: correlation within 4/sqrt(n) = 0.028.
            let k = (j + 1) % NUM_PARAMETERS;
            let cov = u.iter().map(|r| (r[j] - 0.5) * (r[k] - 0.5)).sum::<f64>() / nf;
            assert!(
                (cov * 12.0).abs() < 4.0 / nf.sqrt(),
                "corr({j},{k}) = {}",
                cov * 12.0
            );
        }
    }

    #[test]
    fn overrides_apply() {
        let plan = with_range("v_kmh", RangeSpec::Absolute([200.0, 210.0]))
            .validate()
            .unwrap();
        assert_eq!(plan.ranges()[11], [200.0, 210.0]);
        let plan = with_range(
            "m_w",
            RangeSpec::Relative {
                nominal: 1000.0,
                factor: [0.5, 1.5],
            },
        )
        .validate()
        .unwrap();
        assert_eq!(plan.ranges()[4], [500.0, 1500.0]);
        let v = plan.draw(0).m_w;
        assert!((500.0..1500.0).contains(&v));
    }

    #[test]
    fn parses_both_range_forms_and_refuses_unknown_fields() {
        let p: SamplingParams = serde_json::from_str(
            r#"{"seed": 3, "n_train": 2, "n_validation": 1, "n_test": 1,
                "ranges": {"m_c": {"nominal": 38880, "factor": [0.8, 1.2]}, "v_kmh": [300, 350]}}"#,
        )
        .unwrap();
        assert_eq!(p.ranges["v_kmh"], RangeSpec::Absolute([300.0, 350.0]));
        assert_eq!(
            p.validate().unwrap().ranges()[0],
            [0.8 * 38880.0, 1.2 * 38880.0]
        );
        let e = serde_json::from_str::<SamplingParams>(
            r#"{"seed": 3, "n_train": 2, "n_validation": 1, "n_test": 1, "ranges": {"m_c": 5}}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("`[min, max]` or `{nominal: X, factor: [lo, hi]}`"),
            "{e}"
        );
        let e =
            serde_json::from_str::<SamplingParams>(r#"{"seed": 3, "n_train": 2, "n_valid": 1}"#)
                .unwrap_err()
                .to_string();
        assert!(e.contains("unknown field `n_valid`"), "{e}");
        let e = serde_json::from_str::<SamplingParams>(
            r#"{"seed": 3, "n_train": 2, "n_validation": 1}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("missing field `n_test`"), "{e}");
    }

    fn message(p: SamplingParams) -> String {
        p.validate().unwrap_err().to_string()
    }

    #[test]
    fn bad_input_is_named() {
        // Negative mass.
        let e = message(with_range("m_c", RangeSpec::Absolute([-10.0, 100.0])));
        assert!(
            e.contains("`m_c`") && e.contains("> 0") && e.contains("[31104, 46656]"),
            "{e}"
        );
        let e = message(with_range(
            "m_t",
            RangeSpec::Relative {
                nominal: -3060.0,
                factor: [0.8, 1.2],
            },
        ));
        assert!(e.contains("`m_t`") && e.contains("finite and > 0"), "{e}");
        // Empty and inverted ranges.
        let e = message(with_range("k_f", RangeSpec::Absolute([4e7, 4e7])));
        assert!(
            e.contains("`k_f`")
                && e.contains("empty or inverted")
                && e.contains("[35000000, 45000000]"),
            "{e}"
        );
        let e = message(with_range("v_kmh", RangeSpec::Absolute([350.0, 300.0])));
        assert!(
            e.contains("`v_kmh` = [350, 300]") && e.contains("empty or inverted"),
            "{e}"
        );
        let e = message(with_range(
            "l_c",
            RangeSpec::Relative {
                nominal: 9.0,
                factor: [1.2, 0.8],
            },
        ));
        assert!(
            e.contains("`l_c`") && e.contains("empty or inverted"),
            "{e}"
        );
        // Non-finite bound.
        let e = message(with_range("c_f", RangeSpec::Absolute([4e4, f64::INFINITY])));
        assert!(e.contains("`c_f`") && e.contains("finite"), "{e}");
        // Zero counts.
        let e = message(params(0, 5));
        assert!(e.contains("`n_train`") && e.contains(">= 1"), "{e}");
        let e = message(params(5, 0));
        assert!(e.contains("`n_validation`") && e.contains(">= 1"), "{e}");
        let e = message(SamplingParams {
            n_test: 0,
            ..params(5, 1)
        });
        assert!(e.contains("`n_test`") && e.contains(">= 1"), "{e}");
        let e = message(SamplingParams {
            n_test: u64::MAX,
            ..params(5, 1)
        });
        assert!(e.contains("n_train + n_validation + n_test"), "{e}");
        // Unknown parameter name.
        let e = message(with_range("m_x", RangeSpec::Absolute([1.0, 2.0])));
        assert!(
            e.contains("unknown parameter `m_x`") && e.contains("m_c, j_c"),
            "{e}"
        );
    }
}
