//! The simply supported Euler-Bernoulli beam: modes, Fryba's series for a moving constant
//! force, and the static deflection.
//!
//! Length `L`, bending stiffness `EI`, mass per length `mu`, deflection `w(x, t)` positive in
//! the direction of the load (downward). Modes `sin(n pi x / L)`, modal mass `mu L / 2`,
//! natural frequencies `w_n = (n pi / L)^2 sqrt(EI / mu)` (e.g. Clough and Penzien, *Dynamics
//! of Structures*, ch. 18).
//!
//! **Moving constant force** (Fryba, *Vibration of Solids and Structures under Moving Loads*,
//! 3rd ed. 1999, ch. 1; undamped case): a force `P` entering at `x = 0` at `t = 0` at constant
//! speed `v`, the beam at rest, no damping; for `0 <= t <= L / v`, with `W_n = n pi v / L`,
//! ```text
//! w(x, t) = sum_n 2 P / (mu L (w_n^2 - W_n^2)) (sin W_n t - (W_n / w_n) sin w_n t) sin(n pi x / L)
//! ```
//! At resonance (`W_n = w_n`) the term has the limit `P (sin W t - W t cos W t) / (mu L W^2)`
//! times the shape. The speed parameter is `alpha = v / (2 f_1 L) = W_1 / w_1`.
//!
//! **Static deflection** at mid-span under a force `P` at mid-span: `P L^3 / (48 E I)`; under
//! `P` at `a`, at `x >= a`: `P a (L - x) (2 L x - x^2 - a^2) / (6 E I L)` (Roark's formulas,
//! simply supported beam, point load); the modal series of the same is
//! `sum_n 2 P / (mu L w_n^2) sin(n pi a / L) sin(n pi x / L)`.

use std::f64::consts::PI;

/// A simply supported beam (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimpleBeam {
    /// Length `L` (m).
    pub length: f64,
    /// Mass per length `mu` (kg/m).
    pub mass_per_length: f64,
    /// Bending stiffness `EI` (N m^2).
    pub bending_stiffness: f64,
}

impl SimpleBeam {
    /// `w_n = (n pi / L)^2 sqrt(EI / mu)` (rad/s), `n >= 1`.
    pub fn omega(&self, n: usize) -> f64 {
        (n as f64 * PI / self.length).powi(2)
            * (self.bending_stiffness / self.mass_per_length).sqrt()
    }

    /// The first natural frequency `f_1` (Hz).
    pub fn f1(&self) -> f64 {
        self.omega(1) / (2.0 * PI)
    }

    /// Speed parameter `alpha = v / (2 f_1 L)` at speed `v` (m/s).
    pub fn speed_parameter(&self, v: f64) -> f64 {
        v / (2.0 * self.f1() * self.length)
    }

    /// The speed (m/s) of speed parameter `alpha`.
    pub fn speed_for(&self, alpha: f64) -> f64 {
        alpha * 2.0 * self.f1() * self.length
    }

    /// Fryba's series truncated to `modes` modes: the deflection (m) at `x` and time `t` under a
    /// force `p` (N) that entered at `x = 0` at `t = 0` with speed `v` (m/s); valid for
    /// `0 <= t <= L / v`.
    pub fn fryba(&self, p: f64, v: f64, x: f64, t: f64, modes: usize) -> f64 {
        let (l, mu) = (self.length, self.mass_per_length);
        (1..=modes)
            .map(|n| {
                let w = self.omega(n);
                let big_w = n as f64 * PI * v / l;
                let time = if (w - big_w).abs() > 1e-9 * w {
                    ((big_w * t).sin() - big_w / w * (w * t).sin()) / (w * w - big_w * big_w)
                } else {
                    ((big_w * t).sin() - big_w * t * (big_w * t).cos()) / (2.0 * big_w * big_w)
                };
                2.0 * p / (mu * l) * time * (n as f64 * PI * x / l).sin()
            })
            .sum()
    }

    /// The static deflection (m) at `x` under `p` (N) at `a` (closed form, Roark).
    pub fn static_deflection(&self, p: f64, a: f64, x: f64) -> f64 {
        let (l, ei) = (self.length, self.bending_stiffness);
        // Symmetry: put the observation point on the far side of the load.
        let (a, x) = if x >= a { (a, x) } else { (l - a, l - x) };
        p * a * (l - x) * (2.0 * l * x - x * x - a * a) / (6.0 * ei * l)
    }

    /// The static deflection's modal series truncated to `modes` modes.
    pub fn static_series(&self, p: f64, a: f64, x: f64, modes: usize) -> f64 {
        let (l, mu) = (self.length, self.mass_per_length);
        (1..=modes)
            .map(|n| {
                let k = n as f64 * PI / l;
                2.0 * p / (mu * l * self.omega(n).powi(2)) * (k * a).sin() * (k * x).sin()
            })
            .sum()
    }
}

/// `P L^3 / (48 E I)` (m): mid-span deflection under `p` (N) at mid-span.
pub fn static_midspan(p: f64, length: f64, bending_stiffness: f64) -> f64 {
    p * length.powi(3) / (48.0 * bending_stiffness)
}

#[cfg(test)]
mod tests {
    use super::*;

    const BEAM: SimpleBeam = SimpleBeam {
        length: 25.0,
        mass_per_length: 2303.0,
        bending_stiffness: 8.323e9,
    };

    /// The Roark closed form, its modal series and `P L^3 / 48 EI` agree: the series converges
    /// like `sum_(n > N) n^-4`.
    #[test]
    fn static_forms_agree() {
        let p = 1e5;
        let mid = static_midspan(p, 25.0, 8.323e9);
        assert!((BEAM.static_deflection(p, 12.5, 12.5) - mid).abs() < 1e-15);
        // The mid-span series is (96 / pi^4) sum_(odd n <= N) n^-4 of P L^3 / 48 EI; its tail
        // past N = 401 is (96 / pi^4) / (6 N^3) = 2.5e-9.
        let series = BEAM.static_series(p, 12.5, 12.5, 401);
        assert!((series - mid).abs() < 4e-9 * mid, "{series} {mid}");
        let (a, x) = (6.0, 17.0);
        let closed = BEAM.static_deflection(p, a, x);
        assert!((BEAM.static_series(p, a, x, 401) - closed).abs() < 1e-8 * mid);
        assert_eq!(closed, BEAM.static_deflection(p, x, a)); // Maxwell reciprocity
    }

    /// At crawling speed Fryba's series is the static influence line; the removable resonance
    /// is continuous.
    #[test]
    fn fryba_series_crawls_to_the_static_line_and_is_continuous_at_resonance() {
        let p = 1e5;
        let v = BEAM.speed_for(1e-6);
        let t = 12.5 / v;
        let dynamic = BEAM.fryba(p, v, 12.5, t, 15);
        let statics = BEAM.static_series(p, 12.5, 12.5, 15);
        assert!(
            (dynamic - statics).abs() < 1e-5 * statics,
            "{dynamic} {statics}"
        );
        // alpha = 1: W_1 = w_1. Compare with speeds just beside it.
        let v1 = BEAM.speed_for(1.0);
        let t = 0.6 * 25.0 / v1;
        let at = BEAM.fryba(p, v1, 9.0, t, 1);
        let near = BEAM.fryba(p, v1 * (1.0 + 1e-6), 9.0, t, 1);
        assert!((at - near).abs() < 1e-5 * at.abs(), "{at} {near}");
    }
}
