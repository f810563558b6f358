//! The railway vehicle of the vehicle-track system written out by hand: the 10-DOF half
//! vehicle on one rail (car body and two bogies bouncing and pitching, four wheelsets
//! bouncing) with linear primary and secondary suspensions, and Hertz's wheel-rail contact.
//! An independent reference for the description `systems/vtcd.yaml` (the residuals of the
//! losses, the stored columns of `simulate`, the static wheel load of the indices).
//!
//! DOF order (equation order): `z_c, beta_c, z_t1, beta_t1, z_t2, beta_t2, z_w1..z_w4`.
//! Displacements (m) positive downward, pitch (rad) positive nose-up, both from static
//! equilibrium on a rigid track, so gravity appears only as the static wheel load `W`.
//! Suspension deflections (compression positive), forces `F = k d + c d'`:
//! ```text
//! d_s1 = Z_c - l_c b_c - Z_t1        d_s2 = Z_c + l_c b_c - Z_t2
//! d_p1 = Z_t1 - l_t b_t1 - Z_w1      d_p2 = Z_t1 + l_t b_t1 - Z_w2
//! d_p3 = Z_t2 - l_t b_t2 - Z_w3      d_p4 = Z_t2 + l_t b_t2 - Z_w4
//! ```
//! Equations of motion with half masses `m = M/2`, `j = J/2` (one rail carries half the car):
//! ```text
//! m_c Z_c''   = -F_s1 - F_s2            j_c b_c''  = l_c (F_s1 - F_s2)
//! m_t Z_t1''  = F_s1 - F_p1 - F_p2      j_t b_t1'' = l_t (F_p1 - F_p2)
//! m_t Z_t2''  = F_s2 - F_p3 - F_p4      j_t b_t2'' = l_t (F_p3 - F_p4)
//! m_w Z_wi''  = F_pi + W - P_i          W = (m_c + 2 m_t + 4 m_w) g / 4
//! ```
//! The residual of equation `i` is `R_i = (mass_i) a_i - force_i` (N or N m); it vanishes on
//! the exact solution. The contact force is `P = (delta / G)^(3/2)` for a compression
//! `delta > 0` (m), zero once the wheel lifts, with `G = 4.57 R^-0.149 1e-8` (m N^-2/3) for a
//! wheel of radius `R` (m).

/// Number of vehicle degrees of freedom.
pub const NUM_DOFS: usize = 10;

/// The vehicle's DOF columns, in equation order.
pub const DOFS: [&str; NUM_DOFS] = [
    "z_c", "beta_c", "z_t1", "beta_t1", "z_t2", "beta_t2", "z_w1", "z_w2", "z_w3", "z_w4",
];

/// The sampled parameters of the vehicle-track description, in the order of the public schema
/// (the columns of its `params.parquet`): the vehicle's eleven, the speed and the fastener's two.
pub const PARAMETERS: [&str; 14] = [
    "m_c", "j_c", "m_t", "j_t", "m_w", "k_p", "c_p", "k_s", "c_s", "l_c", "l_t", "v_kmh", "k_f",
    "c_f",
];

/// The contact-force columns, wheel 1 (front) to 4.
pub const CONTACTS: [&str; 4] = ["p_1", "p_2", "p_3", "p_4"];

/// The half vehicle of one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfVehicle {
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

impl HalfVehicle {
    /// The half vehicle from the whole vehicle's parameters, looked up by their names in the
    /// description (`m_c`, `j_c`, `m_t`, `j_t`, `m_w` whole-vehicle masses and inertias; `k_p`,
    /// `c_p`, `k_s`, `c_s`, `l_c`, `l_t`), under gravity `g` (m/s^2).
    pub fn new(value: impl Fn(&str) -> f64, g: f64) -> Self {
        let (m_c, m_t, m_w) = (value("m_c") / 2.0, value("m_t") / 2.0, value("m_w") / 2.0);
        Self {
            m_c,
            j_c: value("j_c") / 2.0,
            m_t,
            j_t: value("j_t") / 2.0,
            m_w,
            k_p: value("k_p"),
            c_p: value("c_p"),
            k_s: value("k_s"),
            c_s: value("c_s"),
            l_c: value("l_c"),
            l_t: value("l_t"),
            w: (m_c + 2.0 * m_t + 4.0 * m_w) * g / 4.0,
        }
    }

    /// Diagonal of the mass matrix, in DOF order (kg or kg m^2).
    pub fn masses(&self) -> [f64; NUM_DOFS] {
        let (mc, jc, mt, jt, mw) = (self.m_c, self.j_c, self.m_t, self.j_t, self.m_w);
        [mc, jc, mt, jt, mt, jt, mw, mw, mw, mw]
    }

    /// Right-hand sides of the ten equations (N or N m) for displacements `z`, velocities `v`
    /// (DOF order) and contact forces `p` (N).
    pub fn forces(
        &self,
        z: &[f64; NUM_DOFS],
        v: &[f64; NUM_DOFS],
        p: &[f64; 4],
    ) -> [f64; NUM_DOFS] {
        let (lc, lt) = (self.l_c, self.l_t);
        // Secondary (car body over bogie `b`) and primary (bogie `b` over wheel `w`) deflections.
        let sec = |sign: f64, b: usize, x: &[f64; NUM_DOFS]| x[0] + sign * lc * x[1] - x[b];
        let pri =
            |sign: f64, b: usize, w: usize, x: &[f64; NUM_DOFS]| x[b] + sign * lt * x[b + 1] - x[w];
        let fs = |sign, b| self.k_s * sec(sign, b, z) + self.c_s * sec(sign, b, v);
        let fp = |sign, b, w| self.k_p * pri(sign, b, w, z) + self.c_p * pri(sign, b, w, v);
        let (fs1, fs2) = (fs(-1.0, 2), fs(1.0, 4));
        let (fp1, fp2, fp3, fp4) = (fp(-1.0, 2, 6), fp(1.0, 2, 7), fp(-1.0, 4, 8), fp(1.0, 4, 9));
        [
            -fs1 - fs2,
            lc * (fs1 - fs2),
            fs1 - fp1 - fp2,
            lt * (fp1 - fp2),
            fs2 - fp3 - fp4,
            lt * (fp3 - fp4),
            fp1 + self.w - p[0],
            fp2 + self.w - p[1],
            fp3 + self.w - p[2],
            fp4 + self.w - p[3],
        ]
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
}

/// Hertz's contact constant `G = 4.57 R^-0.149 1e-8` (m N^-2/3) of a wheel of radius `r` (m).
pub fn hertz_constant(r: f64) -> f64 {
    4.57 * r.powf(-0.149) * 1e-8
}

/// The contact force (N) of a compression `delta` (m, positive pressing): `(delta / G)^(3/2)`,
/// zero when the wheel has lifted.
pub fn contact_force(delta: f64, g: f64) -> f64 {
    if delta > 0.0 {
        let x = delta / g;
        x * x.sqrt()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nominal(name: &str) -> f64 {
        match name {
            "m_c" => 38880.0,
            "j_c" => 1.91e6,
            "m_t" => 3060.0,
            "j_t" => 3200.0,
            "m_w" => 1517.0,
            "k_p" => 1.772e6,
            "c_p" => 2e4,
            "k_s" => 4.5e5,
            "c_s" => 2e4,
            "l_c" => 9.0,
            "l_t" => 1.2,
            other => panic!("{other}"),
        }
    }

    /// At rest on a rigid track each wheel carries the static load: `P_i = W`, and `4 W` is
    /// the half vehicle's weight.
    #[test]
    fn the_static_wheel_load_balances_the_vehicle_at_rest() {
        let veh = HalfVehicle::new(nominal, 9.81);
        let zero = [0.0; NUM_DOFS];
        let r = veh.residuals(&zero, &zero, &zero, &[veh.w; 4]);
        assert!(r.iter().all(|x| *x == 0.0), "{r:?}");
        let weight = (veh.m_c + 2.0 * veh.m_t + 4.0 * veh.m_w) * 9.81;
        assert!((4.0 * veh.w - weight).abs() < 1e-9 * weight);
    }

    /// A car body lowered by `d` compresses both secondary springs: each bogie is pushed by
    /// `k_s d` and the body held back by `2 k_s d`; no pitch moment by symmetry.
    #[test]
    fn a_lowered_car_body_loads_both_bogies_alike() {
        let veh = HalfVehicle::new(nominal, 9.81);
        let mut z = [0.0; NUM_DOFS];
        z[0] = 1e-3;
        let f = veh.forces(&z, &[0.0; NUM_DOFS], &[veh.w; 4]);
        assert_eq!(f[0], -2.0 * veh.k_s * 1e-3);
        assert_eq!(f[1], 0.0);
        assert_eq!((f[2], f[4]), (veh.k_s * 1e-3, veh.k_s * 1e-3));
    }

    /// Hertz: the force of the compression `G P^(2/3)` is `P`; a lifted wheel carries none.
    #[test]
    fn hertz_contact_inverts_its_static_compression() {
        let g = hertz_constant(0.43);
        let p: f64 = 70e3;
        let delta = g * p.powf(2.0 / 3.0);
        assert!((contact_force(delta, g) - p).abs() < 1e-9 * p);
        assert_eq!(contact_force(-1e-6, g), 0.0);
    }
}
