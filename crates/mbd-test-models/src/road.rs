//! Road roughness: the ISO 8608 displacement spectrum and what a linear system's output makes of
//! a random-phase road.
//!
//! **ISO 8608** (ISO 8608:2016, *Mechanical vibration - Road surface profiles - Reporting of
//! measured data*): displacement PSD over spatial frequency `n` (cycles/m),
//! ```text
//! G_d(n) = G_d(n0) (n / n0)^-2        n0 = 0.1 cycles/m
//! ```
//! with `G_d(n0)` = 16e-6 m^3 for class A, 4x per class (B 64e-6, C 256e-6, D 1024e-6, ...):
//! [`CLASSES`], the geometric means of the classes. Power in a band: `integral_n1^n2 G_d dn =
//! G_d(n0) n0^2 (1/n1 - 1/n2)` ([`band_power`]). At speed `v` the road under a tyre has the
//! temporal frequency `f = n v` and PSD `G(f) = G_d(f / v) / v`.
//!
//! **Random-phase roads.** A generator that writes `eta(x) = sum_k sqrt(2 P_k) cos(2 pi n_k x +
//! phi_k)` with fixed bin powers `P_k` (m^2) and random phases gives a linear output `y` of
//! response `H` the mean square `sum_k |H(2 pi n_k v)|^2 P_k` in expectation over the phases,
//! and exactly that over any window holding a whole number of periods of every bin (discrete
//! orthogonality): [`spectral_sum`]. The continuous counterpart is `integral |H|^2 G_d dn`
//! ([`band_integral`]), which the sum approximates by one point per bin.
//!
//! **Linear interpolation.** A profile sampled every `dx` and read by linear interpolation keeps
//! a harmonic of spatial frequency `n` with the gain of the triangle kernel,
//! `sinc^2(n dx) = (sin(pi n dx) / (pi n dx))^2 ~ 1 - (pi n dx)^2 / 3` ([`interpolation_gain`]),
//! and adds images at `m / dx +- n` (`m >= 1`) whose gains are `sinc^2(m -+ n dx)`, of order
//! `(n dx)^2`.

use std::f64::consts::PI;

/// ISO 8608 reference spatial frequency `n0` (cycles/m).
pub const N0: f64 = 0.1;

/// ISO 8608 classes and their `G_d(n0)` (m^3), geometric means.
pub const CLASSES: [(char, f64); 8] = [
    ('A', 16e-6),
    ('B', 64e-6),
    ('C', 256e-6),
    ('D', 1024e-6),
    ('E', 4096e-6),
    ('F', 16384e-6),
    ('G', 65536e-6),
    ('H', 262144e-6),
];

/// `G_d(n0)` of a class (m^3).
///
/// # Panics
/// On a letter outside A-H.
pub fn class_g0(class: char) -> f64 {
    CLASSES
        .iter()
        .find(|c| c.0 == class)
        .map(|c| c.1)
        .unwrap_or_else(|| panic!("ISO 8608 has classes A-H, not {class}"))
}

/// `G_d(n) = g0 (n / n0)^-2` (m^3) at `n` (cycles/m).
pub fn psd(g0: f64, n: f64) -> f64 {
    g0 * (n / N0).powi(-2)
}

/// `integral_n1^n2 G_d(n) dn = g0 n0^2 (1/n1 - 1/n2)` (m^2).
pub fn band_power(g0: f64, n1: f64, n2: f64) -> f64 {
    g0 * N0 * N0 * (1.0 / n1 - 1.0 / n2)
}

/// Amplitude gain of linear interpolation between samples `dx` apart for a harmonic of spatial
/// frequency `n`: `sinc^2(n dx)`.
pub fn interpolation_gain(n: f64, dx: f64) -> f64 {
    let a = PI * n * dx;
    if a == 0.0 {
        1.0
    } else {
        (a.sin() / a).powi(2)
    }
}

/// `sum_k gain2(2 pi n_k v) P_k` over bins `(n_k, P_k)` (cycles/m, m^2): the mean square of a
/// linear output whose power gain per unit road is `gain2(omega)` (`|H|^2`, with any
/// interpolation gain folded in by the caller).
pub fn spectral_sum(bins: &[(f64, f64)], speed: f64, gain2: impl Fn(f64) -> f64) -> f64 {
    bins.iter()
        .map(|&(n, p)| gain2(2.0 * PI * n * speed) * p)
        .sum()
}

/// `integral_n1^n2 gain2(2 pi n v) G_d(n) dn` by composite Simpson in `ln n` on `points`
/// intervals (rounded up to even).
pub fn band_integral(
    g0: f64,
    band: [f64; 2],
    speed: f64,
    gain2: impl Fn(f64) -> f64,
    points: usize,
) -> f64 {
    let m = points.max(2).next_multiple_of(2);
    let (a, b) = (band[0].ln(), band[1].ln());
    let h = (b - a) / m as f64;
    let f = |u: f64| {
        let n = u.exp();
        gain2(2.0 * PI * n * speed) * psd(g0, n) * n
    };
    let mut sum = f(a) + f(b);
    for i in 1..m {
        sum += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_power_is_the_integral_of_the_psd() {
        let g0 = class_g0('C');
        assert_eq!(g0, 256e-6);
        let exact = band_power(g0, 0.011, 2.83);
        let numeric = band_integral(g0, [0.011, 2.83], 1.0, |_| 1.0, 2000);
        assert!((numeric - exact).abs() < 1e-10 * exact, "{numeric} {exact}");
        // psd at n0 is g0.
        assert_eq!(psd(g0, N0), g0);
    }

    #[test]
    fn interpolation_gain_matches_its_expansion() {
        // (pi n dx)^2 / 3 with n dx = 0.283: the 24 % of systems-interfaces.md at 2.83 /m and
        // dx 0.1 m.
        let g = interpolation_gain(2.83, 0.1);
        assert!((1.0 - g - 0.24).abs() < 0.01, "{g}");
        let small = interpolation_gain(0.5, 0.01);
        let approx = 1.0 - (PI * 0.005f64).powi(2) / 3.0;
        assert!((small - approx).abs() < 1e-8);
    }
}
