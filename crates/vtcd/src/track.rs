//! The fixed track constants (`docs/model.md`, Parameters: fixed track defaults) and the
//! substructure under each fastener.
//!
//! Under fastener `j` (at `x_j = j s`, `j = 0..N_f-1`) sit a sleeper `s_j` and a ballast block
//! `b_j` on the subgrade. Forces (N), displacements positive downward:
//! ```text
//! F_fj = k_f (Z_r(x_j) - Z_sj) + c_f (Z_r'(x_j) - Z_sj')           fastener (rail pad)
//! F_bj = k_b (Z_sj - Z_bj)     + c_b (Z_sj' - Z_bj')                ballast
//! m_s Z_sj'' = F_fj - F_bj
//! m_b Z_bj'' = F_bj - k_g Z_bj - c_g Z_bj'
//!              - k_w (2 Z_bj - Z_b,j-1 - Z_b,j+1) - c_w (2 Z_bj' - Z_b,j-1' - Z_b,j+1')
//! ```
//! Ballast shear couples each block to both neighbours; blocks beyond the ends are fixed
//! (`Z_b,-1 = Z_b,N_f = 0`), so every coupling force acts equally and oppositely on two bodies
//! and the assembled stiffness and damping matrices are symmetric.
//! `k_f` and `c_f` vary per sample (see [`crate::params::SampleParams`]); the rest is fixed here.

use serde::{Deserialize, Serialize};

/// Fixed track constants, SI units. [`Default`] gives the spec's values (CHN60 rail on a
/// ballasted substructure, 900 fasteners at 0.6 m, 450 rail modes); a missing field takes its
/// default when deserialized.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrackParams {
    /// Number of fasteners `N_f` (rail length `L = N_f s`). Default 900.
    pub n_f: usize,
    /// Number of rail modes `N_M` (must be < `N_f`). Default 450.
    pub n_m: usize,
    /// Fastener spacing `s` (m). Default 0.6.
    pub s: f64,
    /// Rail mass per length `m_r` (kg/m). Default 60.64 (CHN60).
    pub m_r: f64,
    /// Rail Young's modulus `E` (Pa). Default 2.059e11.
    pub rail_e: f64,
    /// Rail second moment of area `I` (m^4). Default 3.217e-5.
    pub rail_i: f64,
    /// Sleeper mass per fastener `m_s` (kg). Default 237.
    pub m_s: f64,
    /// Ballast block mass per fastener `m_b` (kg). Default 341.3.
    pub m_b: f64,
    /// Ballast stiffness `k_b` (N/m). Default 2.4e8.
    pub k_b: f64,
    /// Ballast damping `c_b` (N s/m). Default 5.88e4.
    pub c_b: f64,
    /// Ballast shear stiffness between neighbouring blocks `k_w` (N/m). Default 7.8e7.
    pub k_w: f64,
    /// Ballast shear damping `c_w` (N s/m). Default 8e4.
    pub c_w: f64,
    /// Subgrade stiffness `k_g` (N/m). Default 6.5e7.
    pub k_g: f64,
    /// Subgrade damping `c_g` (N s/m). Default 3.1e4.
    pub c_g: f64,
}

impl Default for TrackParams {
    fn default() -> Self {
        Self {
            n_f: 900,
            n_m: 450,
            s: 0.6,
            m_r: 60.64,
            rail_e: 2.059e11,
            rail_i: 3.217e-5,
            m_s: 237.0,
            m_b: 341.3,
            k_b: 2.4e8,
            c_b: 5.88e4,
            k_w: 7.8e7,
            c_w: 8e4,
            k_g: 6.5e7,
            c_g: 3.1e4,
        }
    }
}

fn out_of_range(name: &str, value: f64, allowed: &str) -> crate::Error {
    crate::Error::OutOfRange {
        name: name.to_owned(),
        value,
        allowed: allowed.to_owned(),
    }
}

impl TrackParams {
    /// Rail length `L = N_f s` (m).
    pub fn length(&self) -> f64 {
        self.n_f as f64 * self.s
    }

    /// Rail bending stiffness `E I` (N m^2).
    pub fn ei(&self) -> f64 {
        self.rail_e * self.rail_i
    }

    /// Checks counts and signs: `2 <= N_f`, `1 <= N_M < N_f` (discrete sine orthogonality),
    /// masses, lengths, `E`, `I` and stiffnesses > 0, dampings >= 0 (zero switches a damper
    /// off, as the energy test does), all finite.
    pub fn validate(&self) -> crate::Result<()> {
        if self.n_f < 2 {
            return Err(out_of_range("n_f", self.n_f as f64, "an integer >= 2"));
        }
        if self.n_m == 0 || self.n_m >= self.n_f {
            let allowed = format!("an integer in [1, n_f - 1] = [1, {}]", self.n_f - 1);
            return Err(out_of_range("n_m", self.n_m as f64, &allowed));
        }
        let positive = [
            ("s", self.s),
            ("m_r", self.m_r),
            ("rail_e", self.rail_e),
            ("rail_i", self.rail_i),
            ("m_s", self.m_s),
            ("m_b", self.m_b),
            ("k_b", self.k_b),
            ("k_g", self.k_g),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(out_of_range(name, value, "finite and > 0"));
            }
        }
        let non_negative = [
            ("k_w", self.k_w),
            ("c_b", self.c_b),
            ("c_w", self.c_w),
            ("c_g", self.c_g),
        ];
        for (name, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(out_of_range(name, value, "finite and >= 0"));
            }
        }
        Ok(())
    }

    /// Static stiffness of one support column (N/m): fastener, ballast and subgrade springs in
    /// series, `1/k_eff = 1/k_f + 1/k_b + 1/k_g` (ballast shear neglected).
    pub fn support_stiffness(&self, k_f: f64) -> f64 {
        1.0 / (1.0 / k_f + 1.0 / self.k_b + 1.0 / self.k_g)
    }
}

/// Substructure forces and accelerations for all fasteners at once.
///
/// `rail_seat[j] = k_f Z_r(x_j) + c_f Z_r'(x_j)` (N) is the rail's share of the fastener force;
/// `zs, vs` and `zb, vb` are sleeper and ballast displacements and velocities. Writes the
/// fastener forces `F_fj` (N) into `fastener` and the accelerations into `a_s`, `a_b` (m/s^2).
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn substructure(
    tp: &TrackParams,
    k_f: f64,
    c_f: f64,
    rail_seat: &[f64],
    zs: &[f64],
    vs: &[f64],
    zb: &[f64],
    vb: &[f64],
    fastener: &mut [f64],
    a_s: &mut [f64],
    a_b: &mut [f64],
) {
    let n = zs.len();
    debug_assert!([
        rail_seat.len(),
        vs.len(),
        zb.len(),
        vb.len(),
        fastener.len(),
        a_s.len(),
        a_b.len()
    ]
    .iter()
    .all(|&l| l == n));
    let (inv_ms, inv_mb) = (1.0 / tp.m_s, 1.0 / tp.m_b);
    let (k_b, c_b, k_g, c_g, k_w, c_w) = (tp.k_b, tp.c_b, tp.k_g, tp.c_g, tp.k_w, tp.c_w);
    // Pass 1: each column on its own, with the shear's own-block part 2 k_w Z_bj + 2 c_w Z_bj'.
    // Plain zipped slices: no bounds checks, vectorised.
    let (k_self, c_self) = (k_g + 2.0 * k_w, c_g + 2.0 * c_w);
    let columns = rail_seat.iter().zip(zs).zip(vs).zip(zb.iter().zip(vb));
    let outputs = fastener.iter_mut().zip(a_s.iter_mut()).zip(a_b.iter_mut());
    for ((((&seat, &zs), &vs), (&zb, &vb)), ((ff_out, as_out), ab_out)) in columns.zip(outputs) {
        let ff = seat - k_f * zs - c_f * vs;
        let fb = k_b * (zs - zb) + c_b * (vs - vb);
        *ff_out = ff;
        *as_out = (ff - fb) * inv_ms;
        *ab_out = (fb - k_self * zb - c_self * vb) * inv_mb;
    }
    // Pass 2: the neighbours' part of the shear, + k_w (Z_b,j-1 + Z_b,j+1) + c_w (..'), with
    // blocks beyond the ends fixed at zero.
    if n >= 2 {
        let (kw, cw) = (k_w * inv_mb, c_w * inv_mb);
        a_b[0] += kw * zb[1] + cw * vb[1];
        a_b[n - 1] += kw * zb[n - 2] + cw * vb[n - 2];
        let left = zb[..n - 2].iter().zip(&vb[..n - 2]);
        let right = zb[2..].iter().zip(&vb[2..]);
        for (a, ((zl, vl), (zr, vr))) in a_b[1..n - 1].iter_mut().zip(left.zip(right)) {
            *a += kw * (zl + zr) + cw * (vl + vr);
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // matrix loops read best with indices
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_spec_values_and_valid() {
        let tp = TrackParams::default();
        tp.validate().unwrap();
        assert_eq!((tp.n_f, tp.n_m), (900, 450));
        assert!((tp.length() - 540.0).abs() < 1e-9);
    }

    #[test]
    fn bad_track_values_are_named() {
        let mut tp = TrackParams {
            n_m: 900,
            ..Default::default()
        };
        let e = tp.validate().unwrap_err().to_string();
        assert!(e.contains("n_m") && e.contains("899"), "{e}");
        tp.n_m = 10;
        tp.m_s = -1.0;
        assert!(tp.validate().unwrap_err().to_string().contains("m_s"));
    }

    /// The substructure's linear stiffness and damping matrices (sleeper and ballast DOFs,
    /// rail held still) are symmetric: every coupling acts equally and oppositely.
    #[test]
    fn substructure_matrices_are_symmetric() {
        let tp = TrackParams::default();
        let n = 7;
        let (k_f, c_f) = (4e7, 4.5e4);
        // Column j of K (or C) is minus the force response to a unit displacement (velocity).
        let matrix = |velocity: bool| {
            let mut m = vec![vec![0.0; 2 * n]; 2 * n];
            for col in 0..2 * n {
                let mut x = vec![0.0; 2 * n];
                x[col] = 1.0;
                let zero = vec![0.0; n];
                let (zs, zb) = x.split_at(n);
                let (z_s, v_s, z_b, v_b) = if velocity {
                    (&zero[..], zs, &zero[..], zb)
                } else {
                    (zs, &zero[..], zb, &zero[..])
                };
                let (mut f, mut a_s, mut a_b) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                substructure(
                    &tp, k_f, c_f, &zero, z_s, v_s, z_b, v_b, &mut f, &mut a_s, &mut a_b,
                );
                for row in 0..n {
                    m[row][col] = -a_s[row] * tp.m_s;
                    m[n + row][col] = -a_b[row] * tp.m_b;
                }
            }
            m
        };
        for velocity in [false, true] {
            let m = matrix(velocity);
            for i in 0..2 * n {
                assert!(m[i][i] > 0.0);
                for j in 0..2 * n {
                    // Entries are sums of a few constants of size <= 3e8: exact to 1e-7 relative.
                    assert!(
                        (m[i][j] - m[j][i]).abs() <= 1e-9 * m[i][i].abs(),
                        "({i},{j})"
                    );
                }
            }
            // The shear couples neighbours: K_b0,b1 = -k_w.
            let (kw, cw) = (tp.k_w, tp.c_w);
            let expect = if velocity { -cw } else { -kw };
            assert!((m[n][n + 1] - expect).abs() < 1e-6);
        }
    }
}
