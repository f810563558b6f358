//! An adaptive explicit Runge-Kutta integrator: Dormand and Prince's embedded 5(4) pair
//! (Dormand and Prince 1980, *J. Comp. Appl. Math.* 6; Hairer, Norsett and Wanner, *Solving
//! Ordinary Differential Equations I*, table 5.2), written here from the published tableau as
//! a reference solver independent of the engine's integrator.
//!
//! `y' = f(t, y)`. Each step takes the 5th-order solution (local extrapolation); the embedded
//! 4th-order solution gives the error estimate
//! ```text
//! err = sqrt( mean_i ( (y5_i - y4_i) / (atol_i + rtol max(|y_i|, |y5_i|)) )^2 )
//! ```
//! and the step is accepted when `err <= 1`, the next one `h 0.9 err^(-1/5)` (clamped to
//! `[0.2 h, 5 h]`). Steps end exactly at every requested output time, so a caller puts a
//! discontinuity of `f` at a segment boundary and integrates each smooth segment separately.

/// The tableau's nodes `c_i`.
const C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
/// The tableau's `a_ij`, rows 2-7 (row 7 is the 5th-order weights: first same as last).
const A: [[f64; 6]; 6] = [
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
        0.0,
        0.0,
    ],
    [
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
        0.0,
    ],
    [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
    ],
];
/// 5th-order minus 4th-order weights `b_i - b*_i`.
const E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// Tolerances and limits of the integration.
#[derive(Debug, Clone, PartialEq)]
pub struct Tolerances {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance per component (the same length as the state).
    pub atol: Vec<f64>,
    /// Largest step (s).
    pub h_max: f64,
}

/// Counts of one integration.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
}

/// Integrates `y' = f(t, y)` from `(times[0], y0)` and returns the state at every time of
/// `times` (increasing; the first entry is `y0`).
///
/// # Panics
/// When the step size underflows (a singular or far too stiff problem).
pub fn solve(
    mut f: impl FnMut(f64, &[f64], &mut [f64]),
    y0: &[f64],
    times: &[f64],
    tol: &Tolerances,
    stats: &mut Stats,
) -> Vec<Vec<f64>> {
    let n = y0.len();
    assert_eq!(tol.atol.len(), n, "one absolute tolerance per component");
    let mut out = Vec::with_capacity(times.len());
    let Some(&t0) = times.first() else {
        return out;
    };
    out.push(y0.to_vec());
    let mut y = y0.to_vec();
    let mut t = t0;
    let mut k = vec![vec![0.0; n]; 7];
    let mut stage = vec![0.0; n];
    let mut y5 = vec![0.0; n];
    f(t, &y, &mut k[0]);
    // The first step is h_max; a too large one is rejected and shrunk.
    let mut h = tol.h_max;
    for &target in &times[1..] {
        assert!(target >= t, "output times increase");
        while t < target {
            // The last step of an interval takes what remains, also when the sum of steps
            // fell short of the target by round-off.
            let remaining = target - t;
            if remaining <= 1e-13 * t.abs().max(1.0) {
                // A target within round-off of the current time (a breakpoint and an output
                // time that differ in the last bits): no step.
                t = target;
                break;
            }
            let last = h >= remaining || remaining - h < 1e-9 * h;
            let step = if last { remaining } else { h };
            assert!(
                step > 1e-14 * t.abs().max(1.0),
                "step size underflow at t = {t}"
            );
            for s in 1..7 {
                for i in 0..n {
                    let mut acc = 0.0;
                    for (j, kj) in k.iter().enumerate().take(s) {
                        acc += A[s - 1][j] * kj[i];
                    }
                    stage[i] = y[i] + step * acc;
                }
                f(t + C[s] * step, &stage, &mut k[s]);
                if s == 6 {
                    y5.copy_from_slice(&stage);
                }
            }
            // k[6] = f(t + h, y5) (first same as last).
            let mut sum = 0.0;
            for i in 0..n {
                let e: f64 = (0..7).map(|j| E[j] * k[j][i]).sum::<f64>() * step;
                let scale = tol.atol[i] + tol.rtol * y[i].abs().max(y5[i].abs());
                sum += (e / scale).powi(2);
            }
            let err = (sum / n as f64).sqrt();
            let factor = if err == 0.0 {
                5.0
            } else {
                (0.9 * err.powf(-0.2)).clamp(0.2, 5.0)
            };
            if err <= 1.0 {
                t = if last { target } else { t + step };
                y.copy_from_slice(&y5);
                k.swap(0, 6);
                stats.accepted += 1;
                if !last || factor < 1.0 {
                    h = (step * factor).min(tol.h_max);
                }
            } else {
                stats.rejected += 1;
                h = step * factor.min(1.0);
            }
        }
        out.push(y.clone());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damped oscillator against its closed form, and the order of the embedded pair.
    #[test]
    fn damped_oscillator_is_solved_to_the_tolerance() {
        let (w, xi) = (40.0f64, 0.03f64);
        let wd = w * (1.0 - xi * xi).sqrt();
        let exact = |t: f64| (-xi * w * t).exp() * ((wd * t).cos() + xi * w / wd * (wd * t).sin());
        let times: Vec<f64> = (0..=200).map(|i| i as f64 * 0.01).collect();
        for (rtol, bound) in [(1e-6, 1e-5), (1e-10, 1e-9), (1e-12, 2e-11)] {
            let mut stats = Stats::default();
            let ys = solve(
                |_, y, d| {
                    d[0] = y[1];
                    d[1] = -w * w * y[0] - 2.0 * xi * w * y[1];
                },
                &[1.0, 0.0],
                &times,
                &Tolerances {
                    rtol,
                    atol: vec![rtol, rtol * w],
                    h_max: 0.1,
                },
                &mut stats,
            );
            let err = times
                .iter()
                .zip(&ys)
                .map(|(t, y)| (y[0] - exact(*t)).abs())
                .fold(0.0, f64::max);
            assert!(err < bound, "rtol {rtol}: error {err}");
            assert!(stats.accepted > 10);
        }
    }

    /// A fixed-step run (tolerance so loose that every step is accepted at `h_max`) converges
    /// with order 5: halving the step divides the error by about 32.
    #[test]
    fn fifth_order_at_fixed_step() {
        let run = |h: f64| {
            let mut stats = Stats::default();
            let ys = solve(
                |_, y, d| {
                    d[0] = y[1];
                    d[1] = -y[0];
                },
                &[1.0, 0.0],
                &[0.0, 4.0],
                &Tolerances {
                    rtol: 1.0,
                    atol: vec![1.0, 1.0],
                    h_max: h,
                },
                &mut stats,
            );
            (ys[1][0] - 4.0f64.cos()).abs()
        };
        let (e1, e2) = (run(0.1), run(0.05));
        let order = (e1 / e2).log2();
        assert!((order - 5.0).abs() < 0.3, "order {order} ({e1} {e2})");
    }
}
