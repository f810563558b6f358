//! The lateral indices of a railway vehicle in space (a description's `lateral:` binding,
//! `docs/indices.md`, "Lateral indices"), of one record's evaluation window:
//!
//! ```text
//! Y/Q per wheel             Y / max(Q, Q_min),  Q_min = 1 % of the static wheel load P0 / 2
//!   instantaneous           max over t and wheels
//!   2 m sliding mean        max over t and wheels of its mean over 2 m of track (EN 14363)
//! wheelset lateral force    H = Y_R - Y_L (the track shift force): max over t and wheelsets of
//!                           |its 2 m sliding mean| (kN), and that over the Prud'homme limit
//!                           alpha (10 + P0 / 3) kN (P0 in kN)
//! car-body lateral          a = y'' + x psi'' - h phi'' at the centre (x = 0) and above the
//!   acceleration            bogies (x = +-l_c), h the measuring points' height below the
//!                           centre: peak max |a|, RMS, lateral Sperling W_y (lateral weighting)
//! stability                 the growth rate (1/s) of a column's oscillation once the
//!                           irregularity has ended (every stored excitation exactly 0 to the
//!                           end): the slope of a line fitted to ln RMS of its periods (about
//!                           its mean), moved toward 0 by 2 standard errors of the slope (0
//!                           within them); > 0 grows (hunting), < 0 decays
//! ```
//!
//! `Y` is the rail's lateral force on the wheel toward the track's centre (the flanging wheel's
//! is positive, flange force included), `Q` the wheel's vertical load (N). The sliding mean
//! is taken over every stored point (finer than EN 14363's 0.5 m steps, so its maximum is at
//! least theirs); a window shorter than 2 m of track takes its whole length.

use crate::config::SperlingParams;
use crate::{check_finite_signal, sperling, Error, IndexColumn, Result};

/// The stability index's column: the growth rate of the lateral oscillation once the track is
/// ideal (1/s; > 0: it grows).
pub const STABILITY_INDEX: &str = "lateral_stability_growth_1ps";

/// The lateral index columns, in [`lateral_indices`] order.
pub const LATERAL_COLUMNS: [IndexColumn; 14] = [
    IndexColumn {
        name: "derailment_quotient_max",
        unit: "-",
        definition: "max over t and wheels of Y / Q",
    },
    IndexColumn {
        name: "derailment_quotient_2m",
        unit: "-",
        definition: "max over t and wheels of the 2 m sliding mean of Y / Q",
    },
    IndexColumn {
        name: "wheelset_lateral_force_kn",
        unit: "kN",
        definition: "max over t and wheelsets of |the 2 m sliding mean of Y_R - Y_L|",
    },
    IndexColumn {
        name: "prudhomme_ratio",
        unit: "-",
        definition: "wheelset_lateral_force_kn / (alpha (10 + P0 / 3)), P0 the static axle load in kN",
    },
    IndexColumn {
        name: "car_body_lat_acc_peak_centre_ms2",
        unit: "m/s^2",
        definition: "max_t |y_c'' - h phi_c''|",
    },
    IndexColumn {
        name: "car_body_lat_acc_peak_front_ms2",
        unit: "m/s^2",
        definition: "max_t |y_c'' + l_c psi_c'' - h phi_c''| (above the front bogie)",
    },
    IndexColumn {
        name: "car_body_lat_acc_peak_rear_ms2",
        unit: "m/s^2",
        definition: "max_t |y_c'' - l_c psi_c'' - h phi_c''| (above the rear bogie)",
    },
    IndexColumn {
        name: "car_body_lat_acc_rms_centre_ms2",
        unit: "m/s^2",
        definition: "RMS over t of y_c'' - h phi_c''",
    },
    IndexColumn {
        name: "car_body_lat_acc_rms_front_ms2",
        unit: "m/s^2",
        definition: "RMS over t of y_c'' + l_c psi_c'' - h phi_c''",
    },
    IndexColumn {
        name: "car_body_lat_acc_rms_rear_ms2",
        unit: "m/s^2",
        definition: "RMS over t of y_c'' - l_c psi_c'' - h phi_c''",
    },
    IndexColumn {
        name: "sperling_wy_centre",
        unit: "-",
        definition: "Sperling ride index W_y (lateral) at the centre",
    },
    IndexColumn {
        name: "sperling_wy_front",
        unit: "-",
        definition: "Sperling ride index W_y above the front bogie",
    },
    IndexColumn {
        name: "sperling_wy_rear",
        unit: "-",
        definition: "Sperling ride index W_y above the rear bogie",
    },
    IndexColumn {
        name: STABILITY_INDEX,
        unit: "1/s",
        definition: "growth rate of the stability column's oscillation after the irregularity ends, 0 within 2 standard errors of its fit (> 0: it grows)",
    },
];

/// Shortest quiet part (s) after the irregularity the stability index measures over.
pub const MIN_QUIET_S: f64 = 0.5;

/// One record's signals over its evaluation window for the lateral indices, equally long,
/// spacing `dt` (s).
#[derive(Debug, Clone)]
pub struct LateralRecord<'a> {
    /// Time step (s).
    pub dt: f64,
    /// Per wheel, front to rear, left before right: `(Y, Q)` (N).
    pub wheels: Vec<(&'a [f64], &'a [f64])>,
    /// The car body's lateral (m/s^2), yaw and roll (rad/s^2) accelerations.
    pub car_body: [&'a [f64]; 3],
    /// The stability column.
    pub stability: &'a [f64],
    /// The stored excitations.
    pub excitations: Vec<&'a [f64]>,
}

/// The constants of a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LateralParams {
    /// Speed (m/s).
    pub speed: f64,
    /// Half the bogie-centre distance `l_c` (m).
    pub half_length: f64,
    /// The measuring points' height below the car body's centre `h` (m).
    pub floor: f64,
    /// Static axle load `P0` (N).
    pub axle_load: f64,
    /// `alpha` of the Prud'homme limit.
    pub prudhomme: f64,
}

/// The largest mean of `n`-point windows of `x` (all of it when shorter).
fn sliding_mean_max(x: &[f64], n: usize, map: impl Fn(f64) -> f64) -> f64 {
    let n = n.clamp(1, x.len());
    let mut sum: f64 = x[..n].iter().sum();
    let mut best = map(sum / n as f64);
    for k in n..x.len() {
        sum += x[k] - x[k - n];
        best = best.max(map(sum / n as f64));
    }
    best
}

/// The three car-body lateral signals (centre, front, rear).
pub fn car_body_lateral(rec: &LateralRecord, p: &LateralParams) -> [Vec<f64>; 3] {
    let [y, psi, phi] = rec.car_body;
    std::array::from_fn(|k| {
        let x = [0.0, p.half_length, -p.half_length][k];
        (0..y.len())
            .map(|t| y[t] + x * psi[t] - p.floor * phi[t])
            .collect()
    })
}

/// The growth rate (1/s) of `y` over the part of the window where every excitation is zero:
/// the slope of a straight line fitted to the logarithm of its envelope ([`envelope`]),
/// moved toward 0 by [`STABILITY_SIGMAS`] standard errors of that slope (0 when within them).
fn stability(rec: &LateralRecord) -> Result<f64> {
    let n = rec.stability.len();
    let quiet_from = (0..n)
        .rev()
        .find(|&t| rec.excitations.iter().any(|e| e[t] != 0.0))
        .map_or(0, |t| t + 1);
    let needed = (MIN_QUIET_S / rec.dt).ceil() as usize;
    if n - quiet_from < needed.max(4 * MIN_WINDOWS) {
        return Err(Error::TooShort {
            what: format!(
                "the stability index's quiet part (every excitation zero to the end, at least {MIN_QUIET_S} s)"
            ),
            found: n - quiet_from,
            needed: needed.max(4 * MIN_WINDOWS),
        });
    }
    let Some(points) = envelope(&rec.stability[quiet_from..], rec.dt) else {
        return Ok(0.0);
    };
    let (slope, error) = line_slope(&points);
    let tolerance = STABILITY_SIGMAS * error;
    Ok(if slope > tolerance {
        slope - tolerance
    } else if slope < -tolerance {
        slope + tolerance
    } else {
        0.0
    })
}

/// Standard errors of the fitted slope by which the stability index is moved toward 0: a
/// growth rate within them is no verdict either way (about 2.5 % of records with a steady
/// oscillation and noise read above 0).
pub const STABILITY_SIGMAS: f64 = 2.0;

/// Fewest windows of the envelope the stability index fits a line to.
pub const MIN_WINDOWS: usize = 4;

/// The envelope of an oscillation `y` at spacing `dt` (s): `(t, ln RMS)` of consecutive
/// windows one period long, about the mean of `y`, the last window ending at the end; the
/// period is the lag of the highest peak of `y`'s autocorrelation after its first zero
/// crossing (white noise adds only to lag 0). When fewer than [`MIN_WINDOWS`] periods fit
/// (or `y` does not oscillate), [`MIN_WINDOWS`] equal windows. `None` when a window is still.
fn envelope(y: &[f64], dt: f64) -> Option<Vec<(f64, f64)>> {
    let n = y.len();
    let mean = y.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = y.iter().map(|v| v - mean).collect();
    let lag = |l: usize| -> f64 { d[..n - l].iter().zip(&d[l..]).map(|(a, b)| a * b).sum() };
    let period = (1..n / MIN_WINDOWS)
        .find(|&l| lag(l) < 0.0)
        .and_then(|first| {
            (first..n / MIN_WINDOWS)
                .map(|l| (l, lag(l)))
                .filter(|&(_, r)| r > 0.0)
                .fold(None, |best: Option<(usize, f64)>, (l, r)| match best {
                    Some((_, b)) if b >= r => best,
                    _ => Some((l, r)),
                })
                .map(|(l, _)| l)
        });
    let width = period.unwrap_or(n / MIN_WINDOWS);
    let windows = n / width;
    let start = n - windows * width;
    (0..windows)
        .map(|k| {
            let w = &d[start + k * width..start + (k + 1) * width];
            let rms = (w.iter().map(|v| v * v).sum::<f64>() / width as f64).sqrt();
            let centre = (start + k * width) as f64 + 0.5 * (width as f64 - 1.0);
            (rms > 0.0).then(|| (centre * dt, rms.ln()))
        })
        .collect()
}

/// The least-squares slope of `points` `(t, v)` and its standard error (from the residuals,
/// `points.len() - 2` degrees of freedom).
fn line_slope(points: &[(f64, f64)]) -> (f64, f64) {
    let m = points.len() as f64;
    let t_mean = points.iter().map(|p| p.0).sum::<f64>() / m;
    let v_mean = points.iter().map(|p| p.1).sum::<f64>() / m;
    let stt: f64 = points.iter().map(|p| (p.0 - t_mean).powi(2)).sum();
    let stv: f64 = points.iter().map(|p| (p.0 - t_mean) * (p.1 - v_mean)).sum();
    let slope = stv / stt;
    let residual: f64 = points
        .iter()
        .map(|p| (p.1 - v_mean - slope * (p.0 - t_mean)).powi(2))
        .sum();
    (slope, (residual / (m - 2.0) / stt).sqrt())
}

/// The lateral indices of one record, in [`LATERAL_COLUMNS`] order. The record must be
/// non-empty; every signal is checked finite (the error names its position in the record).
pub fn lateral_indices(
    rec: &LateralRecord,
    p: &LateralParams,
    sperling_params: &SperlingParams,
) -> Result<[f64; 14]> {
    let n = rec.stability.len();
    if n == 0 {
        return Err(Error::TooShort {
            what: "record".into(),
            found: 0,
            needed: 1,
        });
    }
    for (i, (y, q)) in rec.wheels.iter().enumerate() {
        check_finite_signal(&format!("Y of wheel {}", i + 1), y)?;
        check_finite_signal(&format!("Q of wheel {}", i + 1), q)?;
    }
    for (name, s) in ["lateral", "yaw", "roll"].iter().zip(rec.car_body) {
        check_finite_signal(&format!("car body's {name} acceleration"), s)?;
    }
    check_finite_signal("stability column", rec.stability)?;
    let window = ((2.0 / (p.speed * rec.dt)).round() as usize).max(1);
    let q_min = 0.01 * p.axle_load / 2.0;
    let (mut dq, mut dq_2m) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (y, q) in &rec.wheels {
        let ratio: Vec<f64> = y.iter().zip(*q).map(|(y, q)| y / q.max(q_min)).collect();
        dq = ratio.iter().copied().fold(dq, f64::max);
        dq_2m = dq_2m.max(sliding_mean_max(&ratio, window, |v| v));
    }
    let mut force = 0.0f64;
    for pair in rec.wheels.chunks_exact(2) {
        let h: Vec<f64> = pair[1]
            .0
            .iter()
            .zip(pair[0].0)
            .map(|(r, l)| r - l)
            .collect();
        force = force.max(sliding_mean_max(&h, window, f64::abs));
    }
    let force_kn = 1e-3 * force;
    let limit_kn = p.prudhomme * (10.0 + 1e-3 * p.axle_load / 3.0);
    let car = car_body_lateral(rec, p);
    let mut out = [0.0; 14];
    out[0] = dq;
    out[1] = dq_2m;
    out[2] = force_kn;
    out[3] = force_kn / limit_kn;
    for (k, a) in car.iter().enumerate() {
        out[4 + k] = crate::abs_max(a);
        out[7 + k] = (a.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        out[10 + k] = sperling::sperling_wy(a, rec.dt, sperling_params)?;
    }
    out[13] = stability(rec)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> LateralParams {
        LateralParams {
            speed: 50.0,
            half_length: 9.0,
            floor: 0.5,
            axle_load: 1.4e5,
            prudhomme: 1.0,
        }
    }

    /// A record of `n` points at `dt`: wheels with given `Y` and `Q`, the car body still, the
    /// stability column `y(t)`, one excitation that ends at `quiet` (s).
    fn record<'a>(
        wheels: &'a [(Vec<f64>, Vec<f64>)],
        zero: &'a [f64],
        y: &'a [f64],
        excitation: &'a [f64],
    ) -> LateralRecord<'a> {
        LateralRecord {
            dt: 1e-3,
            wheels: wheels
                .iter()
                .map(|(y, q)| (y.as_slice(), q.as_slice()))
                .collect(),
            car_body: [zero, zero, zero],
            stability: y,
            excitations: vec![excitation],
        }
    }

    /// Closed forms: a steady flanging wheel's Y/Q, a 2 m mean that skips a spike shorter
    /// than 2 m, the Prud'homme ratio of a steady track shift force, a decaying and a growing
    /// oscillation's rate.
    #[test]
    fn closed_forms() {
        let n = 2000;
        let dt = 1e-3;
        // Wheel 2 (right) pushed by 30 kN at a load of 75 kN, a 1 ms spike of 90 kN on it;
        // wheel 1 (left) at 5 kN outward.
        let mut y_r = vec![3.0e4; n];
        y_r[1000] = 9.0e4;
        let wheels = vec![(vec![-5.0e3; n], vec![6.5e4; n]), (y_r, vec![7.5e4; n])];
        let zero = vec![0.0; n];
        let sigma = -0.8;
        let y: Vec<f64> = (0..n)
            .map(|t| {
                let t = t as f64 * dt;
                1e-3 * (sigma * t).exp() * (2.0 * std::f64::consts::PI * 5.0 * t).sin()
            })
            .collect();
        let excitation: Vec<f64> = (0..n).map(|t| if t < 400 { 1e-3 } else { 0.0 }).collect();
        let rec = record(&wheels, &zero, &y, &excitation);
        let out = lateral_indices(&rec, &params(), &SperlingParams::default()).unwrap();
        assert!((out[0] - 9.0e4 / 7.5e4).abs() < 1e-12, "{}", out[0]);
        // 2 m at 50 m/s is 40 points: the spike adds 60 kN / 40 to the mean.
        let want = (3.0e4 + 6.0e4 / 40.0) / 7.5e4;
        assert!((out[1] - want).abs() < 1e-12, "{} vs {want}", out[1]);
        let h = (3.0e4 + 5.0e3 + 6.0e4 / 40.0) * 1e-3;
        assert!((out[2] - h).abs() < 1e-9, "{}", out[2]);
        assert!((out[3] - h / (10.0 + 140.0 / 3.0)).abs() < 1e-12);
        // 1.6 s of quiet, 8 cycles: the RMS ratio of the halves is exp(sigma 0.8 s).
        assert!((out[13] - sigma).abs() < 0.02, "{}", out[13]);
        let growing: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(t, v)| v * (1.6 * t as f64 * dt).exp())
            .collect();
        let rec = record(&wheels, &zero, &growing, &excitation);
        let out = lateral_indices(&rec, &params(), &SperlingParams::default()).unwrap();
        assert!((out[13] - 0.8).abs() < 0.02, "{}", out[13]);
        // No quiet part: refused.
        let busy = vec![1e-3; n];
        let rec = record(&wheels, &zero, &y, &busy);
        assert!(lateral_indices(&rec, &params(), &SperlingParams::default()).is_err());
    }

    /// A quiet record `exp(sigma t) sin(2 pi 5 t)` (1.6 s after a 0.4 s excitation, 1 ms
    /// steps) plus uniform noise of half-width `noise` drawn from `seed` (xorshift).
    fn oscillation(sigma: f64, noise: f64, seed: u64) -> Vec<f64> {
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        (0..2000)
            .map(|t| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                let t = t as f64 * 1e-3;
                (sigma * t).exp() * (2.0 * std::f64::consts::PI * 5.0 * t).sin()
                    + noise * (2.0 * u - 1.0)
            })
            .collect()
    }

    /// The stability index of `y` on a record whose excitation ends at 0.4 s.
    fn growth(y: &[f64]) -> f64 {
        let zero = vec![0.0; y.len()];
        let excitation: Vec<f64> = (0..y.len())
            .map(|t| if t < 400 { 1.0 } else { 0.0 })
            .collect();
        let wheels = vec![(vec![0.0; y.len()], vec![7.5e4; y.len()]); 2];
        let rec = record(&wheels, &zero, y, &excitation);
        lateral_indices(&rec, &params(), &SperlingParams::default()).unwrap()[13]
    }

    /// The fitted envelope of a damped or growing sinusoid is its exponential: the slope is
    /// `sigma` with a vanishing standard error (the windows are whole periods).
    #[test]
    fn the_envelope_of_an_exponential_sinusoid_is_its_exponential() {
        for sigma in [-0.8, -0.1, 0.3, 0.8] {
            let y = oscillation(sigma, 0.0, 1);
            let points = envelope(&y[400..], 1e-3).unwrap();
            assert_eq!(points.len(), 8, "sigma {sigma}: one window per period");
            let (slope, error) = line_slope(&points);
            assert!(
                (slope - sigma).abs() < 2e-3 * sigma.abs().max(1.0),
                "{sigma}: {slope}"
            );
            assert!(error < 1e-3, "{sigma}: {error}");
        }
    }

    /// With noise (5 % of the starting amplitude): a decay reads as decay and a growth as
    /// growth, each within 0.1/s; a steady oscillation reads 0 in most records and never
    /// more than 0.05/s; a slow decay (-0.05/s) never reads as growth. Over 40 records each.
    #[test]
    fn noise_within_its_standard_errors_is_no_growth() {
        for seed in 1..=40 {
            let decay = growth(&oscillation(-0.8, 0.05, seed));
            assert!(
                decay < 0.0 && (decay + 0.8).abs() < 0.1,
                "seed {seed}: {decay}"
            );
            let grow = growth(&oscillation(0.8, 0.05, seed));
            assert!(
                grow > 0.0 && (grow - 0.8).abs() < 0.1,
                "seed {seed}: {grow}"
            );
            let slow = growth(&oscillation(-0.05, 0.05, seed));
            assert!(slow <= 0.0, "seed {seed}: {slow}");
        }
        let steady: Vec<f64> = (1..=40)
            .map(|s| growth(&oscillation(0.0, 0.05, s)))
            .collect();
        let zeros = steady.iter().filter(|g| **g == 0.0).count();
        assert!(zeros >= 30, "{zeros} of 40 read 0: {steady:?}");
        assert!(steady.iter().all(|g| g.abs() < 0.05), "{steady:?}");
    }

    /// The lateral Sperling index of a sinusoid on a spectral line is the closed form with the
    /// lateral weighting, and differs from the vertical one where the weightings differ.
    #[test]
    fn lateral_sperling_closed_form() {
        let (n, dt) = (4000, 1e-3);
        let (amp, f) = (0.3, 2.0);
        let a: Vec<f64> = (0..n)
            .map(|k| amp * (2.0 * std::f64::consts::PI * f * k as f64 * dt).sin())
            .collect();
        let p = SperlingParams::default();
        let wy = sperling::sperling_wy(&a, dt, &p).unwrap();
        let want = 0.896 * ((100.0 * amp).powi(3) * 0.8 * f * f / f).powf(0.1);
        assert!((wy - want).abs() < 1e-9 * want, "{wy} vs {want}");
        let wz = sperling::sperling_wz(&a, dt, &p).unwrap();
        assert!((wz / wy - (0.325f64 / 0.8).powf(0.1)).abs() < 1e-9);
    }
}
