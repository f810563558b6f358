//! Statistics of a sample of index values: mean, standard deviation, quantiles (linear
//! interpolation between order statistics, Hyndman and Fan's type 7, as numpy and pandas
//! default to), percentile-bootstrap intervals, the Wilson interval of a proportion, and the
//! exceedance probability of a limit with its two kinds of uncertainty:
//!
//! - sampling: how far the fraction of N designs over the limit may be from the probability
//!   (the Wilson score interval; with no exceedance at all, the rule of three
//!   `[0, -ln(1 - level) / N]`, 3/N at 95 %);
//! - surrogate: with a calibrated interval `[lo, hi]` per design, the fraction whose whole
//!   interval is over the limit (`lo > L`) and the fraction whose interval reaches it
//!   (`hi > L`) bound the fraction the solver would find, at the intervals' coverage.

use crate::{distribution::normal_quantile, out_of_range, Result};
use mbd_dataset::{Purpose, SampleStream};
use rayon::prelude::*;

/// A closed interval `[lo, hi]`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Interval {
    /// Whether `x` lies in the interval.
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }
}

/// The arithmetic mean (NaN when empty).
pub fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

/// The sample standard deviation (divisor `n - 1`; NaN below two values).
pub fn std(x: &[f64]) -> f64 {
    if x.len() < 2 {
        return f64::NAN;
    }
    let m = mean(x);
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (x.len() - 1) as f64).sqrt()
}

/// The `p`-quantile (p in [0, 1]) of `sorted` (ascending): `x[h] ` with `h = (n - 1) p`,
/// interpolated linearly between neighbours. NaN when empty.
pub fn quantile_sorted(sorted: &[f64], p: f64) -> f64 {
    match sorted.len() {
        0 => f64::NAN,
        1 => sorted[0],
        n => {
            let h = (n - 1) as f64 * p.clamp(0.0, 1.0);
            let lo = h.floor() as usize;
            let hi = (lo + 1).min(n - 1);
            sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
        }
    }
}

/// `x` sorted ascending (NaN last).
pub fn sorted(x: &[f64]) -> Vec<f64> {
    let mut s = x.to_vec();
    s.sort_by(f64::total_cmp);
    s
}

/// Checks a two-sided confidence level in (0, 1).
pub fn check_level(field: &str, level: f64) -> Result<()> {
    if level > 0.0 && level < 1.0 {
        Ok(())
    } else {
        Err(out_of_range(field, level, "a level in (0, 1)"))
    }
}

/// Percentile-bootstrap intervals at `level` of the statistics `stat` computes from a
/// resample (a list of `n` row indices drawn with replacement): `reps` replicates, replicate
/// `r` drawn from the stream `(seed, Bootstrap, r)`, so the intervals do not depend on the
/// thread count. Returns one interval per statistic; NaN ends when `reps` is 0.
pub fn bootstrap<F>(n: usize, reps: usize, seed: u64, level: f64, stat: F) -> Vec<Interval>
where
    F: Fn(&[usize]) -> Vec<f64> + Sync,
{
    let replicates: Vec<Vec<f64>> = (0..reps)
        .into_par_iter()
        .map(|r| {
            let mut s = SampleStream::new(seed, Purpose::Bootstrap, r as u64);
            let rows: Vec<usize> = (0..n)
                .map(|_| ((s.uniform() * n as f64) as usize).min(n - 1))
                .collect();
            stat(&rows)
        })
        .collect();
    let k = replicates.first().map_or(0, Vec::len);
    let tail = (1.0 - level) / 2.0;
    (0..k)
        .map(|j| {
            let column: Vec<f64> = replicates.iter().map(|r| r[j]).collect();
            let s = sorted(&column);
            Interval {
                lo: quantile_sorted(&s, tail),
                hi: quantile_sorted(&s, 1.0 - tail),
            }
        })
        .collect()
}

/// The interval at `level` of a binomial proportion with `k` successes in `n` trials: the
/// Wilson score interval, and the rule of three `[0, -ln(1 - level) / n]` (its mirror image)
/// when `k` is 0 (`n`).
pub fn proportion_interval(k: usize, n: usize, level: f64) -> Interval {
    if n == 0 {
        return Interval { lo: 0.0, hi: 1.0 };
    }
    let nf = n as f64;
    if k == 0 {
        return Interval {
            lo: 0.0,
            hi: (-(1.0 - level).ln() / nf).min(1.0),
        };
    }
    if k == n {
        return Interval {
            lo: (1.0 + (1.0 - level).ln() / nf).max(0.0),
            hi: 1.0,
        };
    }
    let z = normal_quantile(1.0 - (1.0 - level) / 2.0);
    let p = k as f64 / nf;
    let z2n = z * z / nf;
    let centre = (p + z2n / 2.0) / (1.0 + z2n);
    let half = z / (1.0 + z2n) * (p * (1.0 - p) / nf + z2n / (4.0 * nf)).sqrt();
    Interval {
        lo: (centre - half).max(0.0),
        hi: (centre + half).min(1.0),
    }
}

/// The probability of exceeding an upper limit, estimated from N designs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Exceedance {
    /// The limit.
    pub limit: f64,
    /// Designs over it (value > limit).
    pub count: usize,
    /// `count / N`.
    pub probability: f64,
    /// The sampling interval of the probability ([`proportion_interval`]).
    pub sampling: Interval,
    /// The surrogate-uncertainty bounds: fraction with `lo > limit`, fraction with
    /// `hi > limit` (`None` without intervals).
    pub surrogate: Option<Interval>,
}

/// The exceedance of `limit` by `values` (with the designs' intervals `bounds` when
/// calibrated), the sampling interval at `level`. Non-finite values count as exceedances (a
/// response that blew up is over any limit).
pub fn exceedance(
    values: &[f64],
    bounds: Option<&[Interval]>,
    limit: f64,
    level: f64,
) -> Exceedance {
    let over = |v: f64| v > limit || v.is_nan();
    let n = values.len();
    let count = values.iter().filter(|&&v| over(v)).count();
    let frac = |k: usize| {
        if n == 0 {
            f64::NAN
        } else {
            k as f64 / n as f64
        }
    };
    let surrogate = bounds.map(|b| Interval {
        lo: frac(b.iter().filter(|i| over(i.lo)).count()),
        hi: frac(b.iter().filter(|i| over(i.hi)).count()),
    });
    Exceedance {
        limit,
        count,
        probability: frac(count),
        sampling: proportion_interval(count, n, level),
        surrogate,
    }
}

/// The quantile levels every Monte Carlo summary reports.
pub const QUANTILES: [f64; 4] = [0.05, 0.5, 0.95, 0.99];

/// Mean, standard deviation and [`QUANTILES`] of a sample, each with its percentile-bootstrap
/// interval.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Values summarised.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Its interval.
    pub mean_ci: Interval,
    /// Standard deviation.
    pub std: f64,
    /// Its interval.
    pub std_ci: Interval,
    /// The quantiles at [`QUANTILES`].
    pub quantiles: Vec<f64>,
    /// Their intervals.
    pub quantile_ci: Vec<Interval>,
}

/// The [`Summary`] of `x` (`reps` bootstrap replicates from `seed`, intervals at `level`).
pub fn summarise(x: &[f64], reps: usize, seed: u64, level: f64) -> Summary {
    let stats = |v: &[f64]| -> Vec<f64> {
        let s = sorted(v);
        [mean(v), std(v)]
            .into_iter()
            .chain(QUANTILES.iter().map(|&p| quantile_sorted(&s, p)))
            .collect()
    };
    let point = stats(x);
    let ci = if x.is_empty() {
        Vec::new()
    } else {
        bootstrap(x.len(), reps, seed, level, |rows| {
            let v: Vec<f64> = rows.iter().map(|&r| x[r]).collect();
            stats(&v)
        })
    };
    let nan = Interval {
        lo: f64::NAN,
        hi: f64::NAN,
    };
    let at = |k: usize| ci.get(k).copied().unwrap_or(nan);
    Summary {
        n: x.len(),
        mean: point[0],
        mean_ci: at(0),
        std: point[1],
        std_ci: at(1),
        quantiles: point[2..].to_vec(),
        quantile_ci: (0..QUANTILES.len()).map(|k| at(k + 2)).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_follow_linear_interpolation() {
        let s = sorted(&[4.0, 1.0, 3.0, 2.0]);
        assert_eq!(quantile_sorted(&s, 0.0), 1.0);
        assert_eq!(quantile_sorted(&s, 1.0), 4.0);
        assert_eq!(quantile_sorted(&s, 0.5), 2.5);
        assert!((quantile_sorted(&s, 0.05) - 1.15).abs() < 1e-12);
        assert!((std(&[1.0, 2.0, 3.0, 4.0]) - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn the_wilson_interval_matches_its_closed_form_and_the_rule_of_three() {
        // k = 10 of n = 100 at 95 %: the textbook 0.0552 .. 0.1744.
        let i = proportion_interval(10, 100, 0.95);
        assert!(
            (i.lo - 0.055_229).abs() < 1e-5 && (i.hi - 0.174_366).abs() < 1e-5,
            "{i:?}"
        );
        let zero = proportion_interval(0, 1000, 0.95);
        assert_eq!(zero.lo, 0.0);
        assert!((zero.hi - 2.995_732e-3).abs() < 1e-8);
        let all = proportion_interval(50, 50, 0.95);
        assert_eq!(all.hi, 1.0);
        assert!((all.lo - (1.0 - 20f64.ln() / 50.0)).abs() < 1e-15);
    }

    /// A case with a known probability: P(U > 0.9) = 0.1 for U uniform; the 95 % Wilson
    /// interval of 4000 draws covers 0.1 in about 95 % of 400 independent studies.
    #[test]
    fn monte_carlo_exceedance_covers_a_known_probability() {
        let (n, studies) = (4000, 400);
        let mut covered = 0;
        for s in 0..studies {
            let mut rng = SampleStream::new(77, Purpose::StudyDesigns, s);
            let x: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
            let e = exceedance(&x, None, 0.9, 0.95);
            covered += e.sampling.contains(0.1) as usize;
        }
        let c = covered as f64 / studies as f64;
        // 4 binomial standard errors of 400 at 0.95: 0.044.
        assert!((c - 0.95).abs() < 0.044, "coverage {c}");
    }

    #[test]
    fn surrogate_bounds_bracket_the_point_fraction() {
        let v = [1.0, 2.0, 3.0, 4.0];
        let b: Vec<Interval> = v
            .iter()
            .map(|&x| Interval {
                lo: x - 0.6,
                hi: x + 0.6,
            })
            .collect();
        let e = exceedance(&v, Some(&b), 2.5, 0.95);
        assert_eq!(e.probability, 0.5);
        assert_eq!(e.surrogate, Some(Interval { lo: 0.25, hi: 0.75 }));
        let e = exceedance(&[1.0, f64::NAN], None, 5.0, 0.95);
        assert_eq!(e.count, 1, "a non-finite response is over the limit");
    }

    #[test]
    fn bootstrap_intervals_cover_the_mean_and_do_not_depend_on_threads() {
        let x: Vec<f64> = (0..500).map(|i| ((i * 37) % 101) as f64).collect();
        let a = summarise(&x, 400, 3, 0.95);
        assert!(a.mean_ci.contains(a.mean));
        let se = a.std / (x.len() as f64).sqrt();
        // The percentile interval of the mean is about +-1.96 standard errors.
        let w = (a.mean_ci.hi - a.mean_ci.lo) / (2.0 * 1.96 * se);
        assert!((w - 1.0).abs() < 0.15, "width ratio {w}");
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let b = one.install(|| summarise(&x, 400, 3, 0.95));
        assert_eq!(a, b);
    }
}
