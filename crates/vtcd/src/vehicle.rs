//! The 10-DOF half vehicle on one rail (`docs/model.md`, Vehicle).
//!
//! DOF order (equation order): `z_c, beta_c, z_t1, beta_t1, z_t2, beta_t2, z_w1..z_w4`.
//! Displacements (m) positive downward, pitch (rad) positive nose-up, both from static
//! equilibrium on a rigid track, so gravity only appears as the static wheel load `W`.
//!
//! Suspension deflections (compression positive), forces `F = k d + c d'`:
//! ```text
//! d_s1 = Z_c - l_c b_c - Z_t1        d_s2 = Z_c + l_c b_c - Z_t2
//! d_p1 = Z_t1 - l_t b_t1 - Z_w1      d_p2 = Z_t1 + l_t b_t1 - Z_w2
//! d_p3 = Z_t2 - l_t b_t2 - Z_w3      d_p4 = Z_t2 + l_t b_t2 - Z_w4
//! ```
//! Equations of motion (half masses `m = M/2`, `j = J/2`):
//! ```text
//! m_c Z_c''   = -F_s1 - F_s2            j_c b_c''  = l_c (F_s1 - F_s2)
//! m_t Z_t1''  = F_s1 - F_p1 - F_p2      j_t b_t1'' = l_t (F_p1 - F_p2)
//! m_t Z_t2''  = F_s2 - F_p3 - F_p4      j_t b_t2'' = l_t (F_p3 - F_p4)
//! m_w Z_wi''  = F_pi + W - P_i          W = (m_c + 2 m_t + 4 m_w) g / 4
//! ```
//! The residual of equation i is `R_i = (mass_i) a_i - force_i` (N or N m); it vanishes on the
//! exact solution.

use crate::params::SampleParams;

/// Number of vehicle degrees of freedom.
pub const NUM_DOFS: usize = 10;
/// Index of the first wheel DOF (`z_w1`).
pub const FIRST_WHEEL: usize = 6;

/// The one-rail vehicle model built from one sample's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vehicle {
    /// Half car-body mass (kg).
    pub m_c: f64,
    /// Half car-body pitch inertia (kg m^2).
    pub j_c: f64,
    /// Half bogie mass (kg).
    pub m_t: f64,
    /// Half bogie pitch inertia (kg m^2).
    pub j_t: f64,
    /// Half wheelset mass (kg).
    pub m_w: f64,
    /// Primary stiffness per axle box (N/m).
    pub k_p: f64,
    /// Primary damping per axle box (N s/m).
    pub c_p: f64,
    /// Secondary stiffness per bogie side (N/m).
    pub k_s: f64,
    /// Secondary damping per bogie side (N s/m).
    pub c_s: f64,
    /// Half bogie-centre distance (m).
    pub l_c: f64,
    /// Half wheelbase (m).
    pub l_t: f64,
    /// Static wheel load `W` (N).
    pub w: f64,
}

/// Suspension forces (N), compression positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SuspensionForces {
    /// Secondary, front and rear bogie.
    pub secondary: [f64; 2],
    /// Primary, wheels 1..4.
    pub primary: [f64; 4],
}

impl Vehicle {
    /// The half vehicle of `p` under gravity `g` (m/s^2, 9.81 in the spec).
    pub fn new(p: &SampleParams, g: f64) -> Self {
        let (m_c, m_t, m_w) = (p.m_c / 2.0, p.m_t / 2.0, p.m_w / 2.0);
        Self {
            m_c,
            j_c: p.j_c / 2.0,
            m_t,
            j_t: p.j_t / 2.0,
            m_w,
            k_p: p.k_p,
            c_p: p.c_p,
            k_s: p.k_s,
            c_s: p.c_s,
            l_c: p.l_c,
            l_t: p.l_t,
            w: (m_c + 2.0 * m_t + 4.0 * m_w) * g / 4.0,
        }
    }

    /// Diagonal of the mass matrix, in DOF order (kg or kg m^2).
    pub fn masses(&self) -> [f64; NUM_DOFS] {
        let (mc, jc, mt, jt, mw) = (self.m_c, self.j_c, self.m_t, self.j_t, self.m_w);
        [mc, jc, mt, jt, mt, jt, mw, mw, mw, mw]
    }

    /// Suspension forces for displacements `z` and velocities `v` (DOF order).
    #[inline]
    pub fn suspension_forces(&self, z: &[f64; NUM_DOFS], v: &[f64; NUM_DOFS]) -> SuspensionForces {
        let (lc, lt) = (self.l_c, self.l_t);
        let sec =
            |sign: f64, bogie: usize, zz: &[f64; NUM_DOFS]| zz[0] + sign * lc * zz[1] - zz[bogie];
        let pri = |sign: f64, bogie: usize, wheel: usize, zz: &[f64; NUM_DOFS]| {
            zz[bogie] + sign * lt * zz[bogie + 1] - zz[wheel]
        };
        let fs = |sign, bogie| self.k_s * sec(sign, bogie, z) + self.c_s * sec(sign, bogie, v);
        let fp = |sign, bogie, wheel| {
            self.k_p * pri(sign, bogie, wheel, z) + self.c_p * pri(sign, bogie, wheel, v)
        };
        SuspensionForces {
            secondary: [fs(-1.0, 2), fs(1.0, 4)],
            primary: [fp(-1.0, 2, 6), fp(1.0, 2, 7), fp(-1.0, 4, 8), fp(1.0, 4, 9)],
        }
    }

    /// Right-hand sides of the ten equations (N or N m) given contact forces `p` (N).
    #[inline]
    pub fn forces(
        &self,
        z: &[f64; NUM_DOFS],
        v: &[f64; NUM_DOFS],
        p: &[f64; 4],
    ) -> [f64; NUM_DOFS] {
        let s = self.suspension_forces(z, v);
        let [fs1, fs2] = s.secondary;
        let [fp1, fp2, fp3, fp4] = s.primary;
        [
            -fs1 - fs2,
            self.l_c * (fs1 - fs2),
            fs1 - fp1 - fp2,
            self.l_t * (fp1 - fp2),
            fs2 - fp3 - fp4,
            self.l_t * (fp3 - fp4),
            fp1 + self.w - p[0],
            fp2 + self.w - p[1],
            fp3 + self.w - p[2],
            fp4 + self.w - p[3],
        ]
    }

    /// Accelerations `M^-1 F` (m/s^2 or rad/s^2).
    #[inline]
    pub fn accelerations(
        &self,
        z: &[f64; NUM_DOFS],
        v: &[f64; NUM_DOFS],
        p: &[f64; 4],
    ) -> [f64; NUM_DOFS] {
        let f = self.forces(z, v, p);
        let m = self.masses();
        std::array::from_fn(|i| f[i] / m[i])
    }

    /// ODE residuals `R_i = m_i a_i - F_i` (N or N m).
    pub fn residuals(
        &self,
        z: &[f64; NUM_DOFS],
        v: &[f64; NUM_DOFS],
        a: &[f64; NUM_DOFS],
        p: &[f64; 4],
    ) -> [f64; NUM_DOFS] {
        let f = self.forces(z, v, p);
        let m = self.masses();
        std::array::from_fn(|i| m[i] * a[i] - f[i])
    }

    /// Linear stiffness matrix `K` with `F(z, 0, 0) = F(0, 0, 0) - K z` (row = equation).
    pub fn stiffness_matrix(&self) -> [[f64; NUM_DOFS]; NUM_DOFS] {
        self.linear_matrix(|e| (e, [0.0; NUM_DOFS]))
    }

    /// Linear damping matrix `C` with `F(0, v, 0) = F(0, 0, 0) - C v`.
    pub fn damping_matrix(&self) -> [[f64; NUM_DOFS]; NUM_DOFS] {
        self.linear_matrix(|e| ([0.0; NUM_DOFS], e))
    }

    fn linear_matrix(
        &self,
        state: impl Fn([f64; NUM_DOFS]) -> ([f64; NUM_DOFS], [f64; NUM_DOFS]),
    ) -> [[f64; NUM_DOFS]; NUM_DOFS] {
        let zero = [0.0; NUM_DOFS];
        let f0 = self.forces(&zero, &zero, &[0.0; 4]);
        let mut k = [[0.0; NUM_DOFS]; NUM_DOFS];
        for j in 0..NUM_DOFS {
            let mut e = zero;
            e[j] = 1.0;
            let (z, v) = state(e);
            let f = self.forces(&z, &v, &[0.0; 4]);
            for i in 0..NUM_DOFS {
                k[i][j] = f0[i] - f[i];
            }
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vehicle() -> Vehicle {
        Vehicle::new(&SampleParams::NOMINAL, 9.81)
    }

    #[test]
    fn stiffness_and_damping_are_symmetric_and_positive_on_the_diagonal() {
        let v = vehicle();
        for m in [v.stiffness_matrix(), v.damping_matrix()] {
            for i in 0..NUM_DOFS {
                assert!(m[i][i] > 0.0);
                for j in 0..NUM_DOFS {
                    let tol = 1e-12 * (m[i][i].abs() + m[j][j].abs());
                    assert!(
                        (m[i][j] - m[j][i]).abs() <= tol,
                        "({i},{j}) {} vs {}",
                        m[i][j],
                        m[j][i]
                    );
                }
            }
        }
        // The rear bogie sits at -l_c: K[1][4] = -k_s l_c (opposite sign to K[1][2]).
        let k = v.stiffness_matrix();
        assert!((k[1][2] - v.k_s * v.l_c).abs() < 1e-6 && (k[1][4] + v.k_s * v.l_c).abs() < 1e-6);
    }

    #[test]
    fn static_wheel_load_balances_a_rigid_track() {
        // With every DOF at rest and each wheel carrying W, every acceleration vanishes.
        let v = vehicle();
        let z = [0.0; NUM_DOFS];
        let a = v.accelerations(&z, &z, &[v.w; 4]);
        assert!(a.iter().all(|x| x.abs() < 1e-12), "{a:?}");
        // W is a quarter of the half vehicle's weight: (38880 + 2*3060 + 4*1517)/2 * 9.81 / 4.
        let expected = (38880.0 + 2.0 * 3060.0 + 4.0 * 1517.0) / 2.0 * 9.81 / 4.0;
        assert!((v.w - expected).abs() < 1e-9);
    }

    #[test]
    fn residual_vanishes_for_consistent_accelerations() {
        let v = vehicle();
        let z = [
            1e-3, 2e-4, -3e-4, 1e-4, 5e-4, -2e-4, 1e-4, 2e-4, 3e-4, -1e-4,
        ];
        let vel = [0.01, -0.02, 0.03, 0.0, -0.01, 0.02, 0.05, -0.05, 0.01, 0.0];
        let p = [7e4, 7.1e4, 6.9e4, 7e4];
        let a = v.accelerations(&z, &vel, &p);
        let r = v.residuals(&z, &vel, &a, &p);
        assert!(r.iter().all(|x| x.abs() < 1e-8), "{r:?}");
        let mut a2 = a;
        a2[3] += 1.0;
        assert!((v.residuals(&z, &vel, &a2, &p)[3] - v.j_t).abs() < 1e-6);
    }
}
