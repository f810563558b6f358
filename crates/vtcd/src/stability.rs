//! Pre-run time-step check for Zhai's explicit method.
//!
//! For one oscillator `u'' + 2 xi w u' + w^2 u = 0` the method maps `(x_n, dt v_n, dt^2 A_{n-1})`
//! linearly; with `W = w dt` and `g = 2 xi w dt` its amplification matrix is
//! ```text
//! [ 1 - W^2     1 - g      -1/2 ]
//! [ -3/2 W^2    1 - 3/2 g  -1/2 ]
//! [ -W^2        -g          0   ]
//! ```
//! and the step is stable when its spectral radius is <= 1 (undamped: `W < 2`; damping lowers
//! the bound, e.g. `xi = 0.1 -> 1.64`).
//!
//! The coupled model is bounded from above, in mass-normalised coordinates, by splitting its
//! stiffness `K` (and damping `C`) into positive semi-definite parts and adding their largest
//! eigenvalues (Weyl's inequality):
//! ```text
//! w_max^2 <= w_{N_M}^2                                 rail bending, highest mode
//!          + k_f (1/(m_r s) + 1/m_s)                   fasteners (exact: sine orthogonality)
//!          + k_b (1/m_s + 1/m_b) + (k_g + 4 k_w) / m_b sleeper-ballast-subgrade, shear
//!          + k_H (1/m_w + lambda_max(G))               linearised Hertz, 4 wheels on the rail
//!          + Gershgorin(vehicle)                       suspension
//! ```
//! `G_ih = sum_k Y_k(x_i) Y_k(x_h) = (1/(m_r L)) sum_k [cos(k pi (x_i - x_h)/L) - cos(k pi
//! (x_i + x_h)/L)]` is the wheels' 4x4 Gram matrix. Its Gershgorin bound uses the Dirichlet
//! kernel, `|sum_{k=1}^{N} cos k theta| <= D(theta) = min(N, 1/(2 |sin(theta/2)|) + 1/2)`:
//! with every wheel at least `e` from both rail ends during the run and wheels at least
//! `d = min(2 l_t, 2 (l_c - l_t))` apart, `G_ii <= (N_M + D_e) / (m_r L)` and
//! `|G_ih| <= (D_d + D_e) / (m_r L)`, `D_e = D(2 pi e / L)`, `D_d = D(pi d / L)`.
//! with `k_H = 1.5 P^(1/3) / G` linearised at [`CONTACT_LOAD_FACTOR`] times the static wheel
//! load (`k_H` grows only as `P^(1/3)`). The same split bounds the damping rate `c_max`. A `dt`
//! is accepted when every oscillator with `w <= w_max` and `2 xi w <= c_max` is stable.

use crate::contact;
use crate::rail::Rail;
use crate::track::TrackParams;
use crate::vehicle::{Vehicle, NUM_DOFS};
use std::f64::consts::PI;

/// Wheel load (in static wheel loads `W`) at which the Hertz contact is linearised for the
/// frequency bound: dynamic loads of these runs stay well below 3 W, and the bound grows only
/// as the cube root of this factor.
pub const CONTACT_LOAD_FACTOR: f64 = 3.0;

/// Spectral radius of the amplification matrix for `W = w dt` and `g = 2 xi w dt`, by
/// repeated squaring (`rho = lim ||A^(2^k)||^(1/2^k)`), accurate to ~1e-10 here.
pub fn spectral_radius(w_dt: f64, g: f64) -> f64 {
    let w2 = w_dt * w_dt;
    let mut a = [
        [1.0 - w2, 1.0 - g, -0.5],
        [-1.5 * w2, 1.0 - 1.5 * g, -0.5],
        [-w2, -g, 0.0],
    ];
    // log ||A^(2^k)|| accumulated with renormalisation, divided by 2^k at the end.
    let mut log_norm = 0.0;
    let mut power = 1.0;
    for _ in 0..40 {
        let mut sq = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                sq[i][j] = (0..3).map(|k| a[i][k] * a[k][j]).sum();
            }
        }
        let norm = sq.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
        if norm == 0.0 {
            return 0.0;
        }
        log_norm = 2.0 * log_norm + norm.ln();
        power *= 2.0;
        for row in &mut sq {
            for x in row.iter_mut() {
                *x /= norm;
            }
        }
        a = sq;
    }
    (log_norm / power).exp()
}

fn stable(w_dt: f64, g: f64) -> bool {
    // Marginal (undamped) eigenvalues sit on the unit circle; round-off and the finite
    // number of squarings put them within 1e-9 of it.
    spectral_radius(w_dt, g) <= 1.0 + 1e-9
}

/// Largest `w dt` for which the oscillator with damping ratio `xi` is stable (bisection).
pub fn oscillator_limit(xi: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 2.5);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if stable(mid, 2.0 * xi * mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Upper bounds of the coupled system's highest circular frequency `w_max` (rad/s) and
/// damping rate `c_max` (1/s, largest eigenvalue of `M^-1/2 C M^-1/2`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectrumBound {
    /// Highest circular frequency bound (rad/s).
    pub omega_max: f64,
    /// Damping-rate bound (1/s).
    pub damping_max: f64,
}

fn vehicle_gershgorin(m: &[[f64; NUM_DOFS]; NUM_DOFS], masses: &[f64; NUM_DOFS]) -> f64 {
    (0..NUM_DOFS)
        .map(|i| {
            (0..NUM_DOFS)
                .map(|j| m[i][j].abs() / (masses[i] * masses[j]).sqrt())
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

/// Bounds for one vehicle (`k_f`, `c_f` of its sample) on track `tp` with Hertz constant `g`,
/// its wheels staying within `wheel_span = [lowest, highest]` positions (m) during the run.
pub fn spectrum_bound(
    vehicle: &Vehicle,
    tp: &TrackParams,
    k_f: f64,
    c_f: f64,
    g: f64,
    wheel_span: [f64; 2],
) -> SpectrumBound {
    let rail = Rail::new(tp);
    let w_rail = rail.omega2.last().copied().unwrap_or(0.0);
    let rail_seat = 1.0 / (tp.m_r * tp.s);
    let rail_point = wheel_gram_bound(vehicle, tp, wheel_span);
    let k_h = contact::linear_stiffness(CONTACT_LOAD_FACTOR * vehicle.w, g);
    let masses = vehicle.masses();
    let omega2 = w_rail
        + k_f * (rail_seat + 1.0 / tp.m_s)
        + tp.k_b * (1.0 / tp.m_s + 1.0 / tp.m_b)
        + (tp.k_g + 4.0 * tp.k_w) / tp.m_b
        + k_h * (1.0 / vehicle.m_w + rail_point)
        + vehicle_gershgorin(&vehicle.stiffness_matrix(), &masses);
    let damping = c_f * (rail_seat + 1.0 / tp.m_s)
        + tp.c_b * (1.0 / tp.m_s + 1.0 / tp.m_b)
        + (tp.c_g + 4.0 * tp.c_w) / tp.m_b
        + vehicle_gershgorin(&vehicle.damping_matrix(), &masses);
    SpectrumBound {
        omega_max: omega2.sqrt(),
        damping_max: damping,
    }
}

/// Gershgorin bound of `lambda_max(G)` (1/kg) for the wheels' Gram matrix (module doc).
fn wheel_gram_bound(vehicle: &Vehicle, tp: &TrackParams, wheel_span: [f64; 2]) -> f64 {
    let (n, l) = (tp.n_m as f64, tp.length());
    let dirichlet = |half_angle: f64| {
        let s = half_angle.sin().abs();
        if s > 0.0 {
            (0.5 / s + 0.5).min(n)
        } else {
            n
        }
    };
    let edge = wheel_span[0].min(l - wheel_span[1]).max(0.0);
    let spacing = (2.0 * vehicle.l_t)
        .min(2.0 * (vehicle.l_c - vehicle.l_t))
        .max(0.0);
    let d_e = dirichlet(PI * edge / l);
    let d_d = dirichlet(PI * spacing / (2.0 * l));
    let row = (n + d_e) + 3.0 * (d_d + d_e);
    // Never above the trivial bound 4 wheels x 2 N_M / (m_r L).
    row.min(8.0 * n) / (tp.m_r * l)
}

impl SpectrumBound {
    /// Whether every oscillator with `w <= omega_max` and damping rate `<= damping_max` is
    /// stable at `dt` (checked on a grid that includes the corners).
    pub fn stable_at(&self, dt: f64) -> bool {
        const NW: usize = 32;
        const NG: usize = 8;
        (1..=NW).all(|i| {
            let w_dt = self.omega_max * dt * i as f64 / NW as f64;
            (0..=NG).all(|j| stable(w_dt, self.damping_max * dt * j as f64 / NG as f64))
        })
    }

    /// The largest stable `dt` (s), by bisection to 0.1%.
    pub fn dt_limit(&self) -> f64 {
        let mut lo = 0.0;
        let mut hi = 2.5 / self.omega_max;
        while hi - lo > 1e-3 * hi {
            let mid = 0.5 * (lo + hi);
            if self.stable_at(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// `Ok` when `dt` is within the limit, else [`crate::Error::StepTooLarge`].
    /// The grid check costs ~0.2 ms; the bisection for the limit runs only to report a refusal.
    pub fn check(&self, dt: f64) -> crate::Result<()> {
        if dt > 0.0 && self.stable_at(dt) {
            Ok(())
        } else {
            Err(crate::Error::StepTooLarge {
                dt,
                limit: self.dt_limit(),
                omega_max: self.omega_max,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::SampleParams;

    /// The worked limits of the damped oscillator, to the 2 decimals given.
    #[test]
    fn oscillator_limits_match_worked_values() {
        for (xi, limit) in [
            (0.0, 2.0),
            (0.01, 1.96),
            (0.05, 1.81),
            (0.1, 1.64),
            (0.2, 1.35),
            (0.5, 0.83),
        ] {
            let got = oscillator_limit(xi);
            assert!((got - limit).abs() < 0.006, "xi {xi}: {got} vs {limit}");
        }
    }

    /// The paper's dt = 1e-4 passes on the full track for the extreme vehicle; ten times it
    /// is refused with a message naming dt and the limit.
    #[test]
    fn paper_step_passes_and_large_step_is_refused() {
        let tp = TrackParams::default();
        let g = contact::hertz_constant(0.43);
        let p = SampleParams {
            m_w: 0.8 * 1517.0,
            k_f: 4.5e7,
            c_f: 5e4,
            ..SampleParams::NOMINAL
        };
        let bound = spectrum_bound(&Vehicle::new(&p, 9.81), &tp, p.k_f, p.c_f, g, [20.0, 531.6]);
        bound.check(1e-4).unwrap();
        let limit = bound.dt_limit();
        assert!(limit > 1e-4 && limit < 1e-3, "{limit}");
        let msg = bound.check(1e-3).unwrap_err().to_string();
        assert!(
            msg.contains("0.001") && msg.contains(&format!("{limit:.3e}")),
            "{msg}"
        );
    }
}
