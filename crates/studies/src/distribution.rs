//! The distribution of one study parameter, sampled by its inverse CDF from a unit-cube
//! coordinate `u` in [0, 1) (a ChaCha draw in a Monte Carlo study, a scrambled Sobol'
//! coordinate in a sensitivity study), so one mapping serves both designs.
//!
//! Normal and lognormal distributions are truncated at a range (by default the model's
//! training range): `x = F^-1(F(lo) + u (F(hi) - F(lo)))`, so every draw lies inside it.
//! Values are in the parameter's own unit.

use crate::{out_of_range, Result};

/// One parameter's distribution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distribution {
    /// Uniform on `[lo, hi]`.
    Uniform {
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// Normal with `mean` and standard deviation `std`, truncated at `[lo, hi]`.
    Normal {
        /// Mean (before truncation).
        mean: f64,
        /// Standard deviation (before truncation), > 0.
        std: f64,
        /// Lower truncation point.
        lo: f64,
        /// Upper truncation point.
        hi: f64,
    },
    /// `ln x` normal with median `median` (> 0) and standard deviation `sigma_log` (> 0),
    /// truncated at `[lo, hi]` (0 < lo).
    LogNormal {
        /// Median `exp(mu)` (before truncation).
        median: f64,
        /// Standard deviation of `ln x`.
        sigma_log: f64,
        /// Lower truncation point.
        lo: f64,
        /// Upper truncation point.
        hi: f64,
    },
    /// Always `value` (not a factor of a sensitivity study).
    Fixed(f64),
}

impl Distribution {
    /// Checks the distribution's numbers; `field` names it in messages.
    pub fn validate(&self, field: &str) -> Result<()> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(out_of_range(
                    format!("{field}.{name}"),
                    v,
                    "a finite number",
                ))
            }
        };
        let range = |lo: f64, hi: f64| {
            finite("lo", lo)?;
            finite("hi", hi)?;
            if lo < hi {
                Ok(())
            } else {
                Err(out_of_range(
                    format!("{field}: range"),
                    format!("[{lo}, {hi}]"),
                    "lo < hi",
                ))
            }
        };
        match *self {
            Self::Uniform { lo, hi } => range(lo, hi),
            Self::Normal { mean, std, lo, hi } => {
                finite("mean", mean)?;
                if !(std > 0.0 && std.is_finite()) {
                    return Err(out_of_range(format!("{field}.std"), std, "> 0"));
                }
                range(lo, hi)?;
                self.mass(field).map(|_| ())
            }
            Self::LogNormal {
                median,
                sigma_log,
                lo,
                hi,
            } => {
                if !(median > 0.0 && median.is_finite()) {
                    return Err(out_of_range(format!("{field}.median"), median, "> 0"));
                }
                if !(sigma_log > 0.0 && sigma_log.is_finite()) {
                    return Err(out_of_range(format!("{field}.sigma_log"), sigma_log, "> 0"));
                }
                range(lo, hi)?;
                if lo <= 0.0 {
                    return Err(out_of_range(
                        format!("{field}: range"),
                        format!("[{lo}, {hi}]"),
                        "0 < lo for a lognormal",
                    ));
                }
                self.mass(field).map(|_| ())
            }
            Self::Fixed(v) => finite("fixed", v),
        }
    }

    /// The standard-normal bounds of a truncated normal or lognormal, refused when the range
    /// holds (numerically) no probability.
    fn mass(&self, field: &str) -> Result<(f64, f64)> {
        let (a, b) = match *self {
            Self::Normal { mean, std, lo, hi } => ((lo - mean) / std, (hi - mean) / std),
            Self::LogNormal {
                median,
                sigma_log,
                lo,
                hi,
            } => (
                (lo / median).ln() / sigma_log,
                (hi / median).ln() / sigma_log,
            ),
            _ => return Ok((0.0, 1.0)),
        };
        let (pa, pb) = (normal_cdf(a), normal_cdf(b));
        if pb - pa < 1e-12 {
            return Err(out_of_range(
                format!("{field}: range"),
                format!("{a:.2} to {b:.2} standard deviations"),
                "a range that holds some of the distribution's probability",
            ));
        }
        Ok((pa, pb))
    }

    /// The value at unit-cube coordinate `u` in [0, 1] (the inverse CDF).
    pub fn at(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        match *self {
            Self::Uniform { lo, hi } => lo + u * (hi - lo),
            Self::Fixed(v) => v,
            Self::Normal { mean, std, lo, hi } => {
                let (pa, pb) = self.mass("").unwrap_or((0.0, 1.0));
                (mean + std * normal_quantile(pa + u * (pb - pa))).clamp(lo, hi)
            }
            Self::LogNormal {
                median,
                sigma_log,
                lo,
                hi,
            } => {
                let (pa, pb) = self.mass("").unwrap_or((0.0, 1.0));
                (median * (sigma_log * normal_quantile(pa + u * (pb - pa))).exp()).clamp(lo, hi)
            }
        }
    }

    /// Whether the parameter varies (every kind but [`Distribution::Fixed`]).
    pub fn varies(&self) -> bool {
        !matches!(self, Self::Fixed(_))
    }

    /// The smallest and largest value a draw can take.
    pub fn support(&self) -> (f64, f64) {
        match *self {
            Self::Uniform { lo, hi }
            | Self::Normal { lo, hi, .. }
            | Self::LogNormal { lo, hi, .. } => (lo, hi),
            Self::Fixed(v) => (v, v),
        }
    }
}

/// The standard normal CDF `Phi(x) = erfc(-x / sqrt 2) / 2`.
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
}

/// The standard normal quantile `Phi^-1(p)` for p in (0, 1) (-inf at 0, +inf at 1): Acklam's
/// rational approximation refined by one Halley step on [`normal_cdf`] (relative error near
/// machine precision).
pub fn normal_quantile(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    let x = if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    };
    // One Halley step: e = Phi(x) - p, u = e sqrt(2 pi) exp(x^2 / 2).
    let e = normal_cdf(x) - p;
    let u = e * (2.0 * std::f64::consts::PI).sqrt() * (x * x / 2.0).exp();
    x - u / (1.0 + x * u / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_normal_quantile_inverts_the_cdf_and_hits_known_points() {
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-12);
        assert!((normal_quantile(0.5)).abs() < 1e-15);
        for p in [1e-10, 1e-4, 0.01, 0.1, 0.3, 0.7, 0.9, 0.999, 1.0 - 1e-9] {
            let x = normal_quantile(p);
            assert!((normal_cdf(x) - p).abs() < 1e-13 * p.max(1e-3), "p {p}");
        }
        assert!((normal_cdf(1.0) - 0.841_344_746_068_542_9).abs() < 1e-15);
    }

    #[test]
    fn truncated_draws_stay_inside_and_follow_the_cdf() {
        let d = Distribution::Normal {
            mean: 1.0,
            std: 2.0,
            lo: 0.0,
            hi: 3.0,
        };
        d.validate("p").unwrap();
        assert!(d.at(0.0).abs() < 1e-12);
        assert!((d.at(1.0) - 3.0).abs() < 1e-12);
        // The median of the truncated law: Phi((m - 1) / 2) halfway between Phi(-1/2), Phi(1).
        let (pa, pb) = (normal_cdf(-0.5), normal_cdf(1.0));
        let m = d.at(0.5);
        assert!((normal_cdf((m - 1.0) / 2.0) - (pa + pb) / 2.0).abs() < 1e-13);
        let ln = Distribution::LogNormal {
            median: 2.0,
            sigma_log: 0.5,
            lo: 0.1,
            hi: 100.0,
        };
        assert!(
            (ln.at(0.5) - 2.0).abs() < 1e-6,
            "symmetric mass: the median"
        );
        let u = Distribution::Uniform { lo: -1.0, hi: 3.0 };
        assert_eq!(u.at(0.25), 0.0);
    }

    #[test]
    fn bad_numbers_are_refused_with_the_field() {
        let e = Distribution::Normal {
            mean: 0.0,
            std: 1.0,
            lo: 50.0,
            hi: 60.0,
        }
        .validate("c_s")
        .unwrap_err();
        assert!(e.to_string().starts_with("c_s: range"), "{e}");
        let e = Distribution::LogNormal {
            median: 1.0,
            sigma_log: 1.0,
            lo: -1.0,
            hi: 2.0,
        }
        .validate("k")
        .unwrap_err();
        assert!(e.to_string().contains("0 < lo"), "{e}");
        assert!(Distribution::Uniform { lo: 2.0, hi: 1.0 }
            .validate("x")
            .is_err());
        assert!(Distribution::Fixed(f64::NAN).validate("x").is_err());
    }
}
