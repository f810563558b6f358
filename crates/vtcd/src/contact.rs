//! Hertz wheel-rail contact (`docs/model.md`, Wheel-rail contact).
//!
//! `delta = Z_w - Z_r(x_w) - eta` (m, compression positive, all displacements downward);
//! `P = (delta / G)^(3/2)` for `delta > 0`, else 0 (wheel lifted off);
//! `G = 4.57 R^-0.149 * 1e-8` m/N^(2/3) for a conical tread of radius `R` (m).

/// Hertz contact constant `G` (m/N^(2/3)) of a conical tread of radius `r` (m).
/// `R = 0.43` gives 5.18e-8.
pub fn hertz_constant(r: f64) -> f64 {
    4.57 * r.powf(-0.149) * 1e-8
}

/// Contact force (N) for compression `delta` (m); zero when the wheel has lifted off.
#[inline]
pub fn contact_force(delta: f64, g: f64) -> f64 {
    if delta > 0.0 {
        let x = delta / g;
        x * x.sqrt()
    } else {
        0.0
    }
}

/// Static compression (m) under load `p` (N): `delta = G p^(2/3)`.
pub fn static_compression(p: f64, g: f64) -> f64 {
    g * p.powf(2.0 / 3.0)
}

/// Linearised contact stiffness (N/m) at load `p`: `dP/d delta = 1.5 p^(1/3) / G`.
pub fn linear_stiffness(p: f64, g: f64) -> f64 {
    1.5 * p.cbrt() / g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hertz_constant_and_static_compression_match_worked_values() {
        // Check values: R = 0.43 m -> G = 5.18e-8, delta = 88 um at 70 kN, k = 1.19e9 N/m.
        let g = hertz_constant(0.43);
        assert!((g - 5.18e-8).abs() < 0.01e-8, "{g}");
        let d = static_compression(70e3, g);
        assert!((d - 88e-6).abs() < 1e-6, "{d}");
        assert!((contact_force(d, g) - 70e3).abs() < 1e-6 * 70e3);
        assert!((linear_stiffness(70e3, g) - 1.19e9).abs() < 0.01e9);
        assert_eq!(contact_force(-1e-6, g), 0.0);
    }
}
