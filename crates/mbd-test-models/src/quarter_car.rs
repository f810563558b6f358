//! The two-mass quarter car on a road: closed-form frequency response (the standard textbook
//! model, e.g. Wong, *Theory of Ground Vehicles*, ch. 7; Gillespie, *Fundamentals of Vehicle
//! Dynamics*, ch. 5).
//!
//! Sprung mass `m_s` on the suspension `k_s, c_s`, unsprung mass `m_u` on the tyre `k_t, c_t`,
//! the tyre following the road `r(t) = h(x0 + v t)`. With every displacement and the road
//! counted in the same direction (up or down: the response is the same),
//! ```text
//! m_s z_s'' = -k_s (z_s - z_u) - c_s (z_s' - z_u')
//! m_u z_u'' =  k_s (z_s - z_u) + c_s (z_s' - z_u') - k_t (z_u - r) - c_t (z_u' - r')
//! ```
//! For `r = R e^{i w t}` and `s = i w` the steady state `z = Z e^{i w t}` solves
//! ```text
//! [ m_s s^2 + c_s s + k_s        -(c_s s + k_s)                      ] [Z_s]   [ 0               ]
//! [ -(c_s s + k_s)               m_u s^2 + (c_s + c_t) s + k_s + k_t ] [Z_u] = [ (k_t + c_t s) R ]
//! ```
//! by Cramer's rule: `Z_s = -a_12 b / det`, `Z_u = a_11 b / det`, `det = a_11 a_22 - a_12^2`.
//! Derived responses per unit road: sprung acceleration `-w^2 Z_s`, suspension travel
//! `Z_s - Z_u` (compression positive when the body moves toward the wheel), dynamic tyre force
//! `(k_t + c_t s)(Z_u - R)` (compression positive: the tyre pressed further than the road).
//!
//! A road harmonic of wavelength `lambda` at speed `v` excites `w = 2 pi v / lambda`.

use crate::complex::C64;

/// The quarter car's constants (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuarterCar {
    /// Sprung mass (kg).
    pub m_s: f64,
    /// Unsprung mass (kg).
    pub m_u: f64,
    /// Suspension stiffness (N/m).
    pub k_s: f64,
    /// Suspension damping (N s/m).
    pub c_s: f64,
    /// Tyre stiffness (N/m).
    pub k_t: f64,
    /// Tyre damping (N s/m), usually 0.
    pub c_t: f64,
}

/// The complex response to a unit road harmonic at circular frequency `omega`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    /// Circular frequency (rad/s).
    pub omega: f64,
    /// Sprung displacement per unit road (1).
    pub z_s: C64,
    /// Unsprung displacement per unit road (1).
    pub z_u: C64,
    /// `k_t + c_t s` (N/m).
    tyre: C64,
}

impl Response {
    /// Sprung acceleration per unit road, `-w^2 Z_s` (1/s^2).
    pub fn sprung_acceleration(&self) -> C64 {
        self.z_s.scale(-self.omega * self.omega)
    }

    /// Unsprung acceleration per unit road, `-w^2 Z_u` (1/s^2).
    pub fn unsprung_acceleration(&self) -> C64 {
        self.z_u.scale(-self.omega * self.omega)
    }

    /// Suspension travel per unit road, `Z_s - Z_u` (1).
    pub fn suspension_travel(&self) -> C64 {
        self.z_s - self.z_u
    }

    /// Dynamic tyre force per unit road, `(k_t + c_t s)(Z_u - 1)` (N/m).
    pub fn tyre_force(&self) -> C64 {
        self.tyre * (self.z_u - C64::real(1.0))
    }
}

impl QuarterCar {
    /// The response at `omega` (rad/s).
    pub fn response(&self, omega: f64) -> Response {
        let s = C64::new(0.0, omega);
        let s2 = C64::real(-omega * omega);
        let susp = C64::real(self.k_s) + s.scale(self.c_s);
        let tyre = C64::real(self.k_t) + s.scale(self.c_t);
        let a11 = s2.scale(self.m_s) + susp;
        let a12 = -susp;
        let a22 = s2.scale(self.m_u) + susp + tyre;
        let det = a11 * a22 - a12 * a12;
        Response {
            omega,
            z_s: -(a12 * tyre) / det,
            z_u: (a11 * tyre) / det,
            tyre,
        }
    }

    /// Undamped natural frequencies (rad/s) of the two modes, body and wheel hop: the roots of
    /// `m_s m_u w^4 - (m_s (k_s + k_t) + m_u k_s) w^2 + k_s k_t = 0`.
    pub fn natural_frequencies(&self) -> [f64; 2] {
        let a = self.m_s * self.m_u;
        let b = self.m_s * (self.k_s + self.k_t) + self.m_u * self.k_s;
        let c = self.k_s * self.k_t;
        let disc = (b * b - 4.0 * a * c).sqrt();
        [
            ((b - disc) / (2.0 * a)).sqrt(),
            ((b + disc) / (2.0 * a)).sqrt(),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAR: QuarterCar = QuarterCar {
        m_s: 320.0,
        m_u: 40.0,
        k_s: 22_000.0,
        c_s: 1500.0,
        k_t: 200_000.0,
        c_t: 0.0,
    };

    /// The solved amplitudes satisfy both rows of the 2x2 system (residual to round-off), the
    /// static limit is rigid following (`Z_s = Z_u = 1`), and the high-frequency limit isolates.
    #[test]
    fn response_solves_the_equations_and_has_the_right_limits() {
        for omega in [0.3, 7.0, 60.0, 400.0] {
            let r = CAR.response(omega);
            let s = C64::new(0.0, omega);
            let susp = C64::real(CAR.k_s) + s.scale(CAR.c_s);
            let row1 = r.z_s.scale(-CAR.m_s * omega * omega) + susp * (r.z_s - r.z_u);
            let row2 = r.z_u.scale(-CAR.m_u * omega * omega) - susp * (r.z_s - r.z_u)
                + C64::real(CAR.k_t) * (r.z_u - C64::real(1.0));
            let scale = CAR.k_t;
            assert!(row1.abs() < 1e-12 * scale && row2.abs() < 1e-12 * scale);
        }
        let r = CAR.response(1e-6);
        assert!((r.z_s - C64::real(1.0)).abs() < 1e-9);
        assert!(CAR.response(1e4).z_s.abs() < 1e-6);
        // Body mode ~1.2 Hz and wheel hop ~11.8 Hz for these values.
        let [w1, w2] = CAR.natural_frequencies();
        let (f1, f2) = (w1 / std::f64::consts::TAU, w2 / std::f64::consts::TAU);
        assert!(
            (1.0..1.5).contains(&f1) && (10.0..13.0).contains(&f2),
            "{f1} {f2}"
        );
    }
}
