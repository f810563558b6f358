//! The pre-run time-step check of Zhai's explicit method for a described system.
//!
//! For one oscillator `u'' + 2 xi w u' + w^2 u = 0` the method maps `(x_n, dt v_n, dt^2
//! A_(n-1))` linearly; with `W = w dt` and `g = 2 xi w dt` its amplification matrix is
//! ```text
//! [ 1 - W^2     1 - g      -1/2 ]
//! [ -3/2 W^2    1 - 3/2 g  -1/2 ]
//! [ -W^2        -g          0   ]
//! ```
//! and the step is stable when its spectral radius is <= 1 (undamped: `W < 2`).
//!
//! The system's highest frequency is bounded, in mass-normalised coordinates, by splitting the
//! stiffness `K` (and damping `C`) into positive semi-definite parts and adding their largest
//! eigenvalues (Weyl's inequality):
//! ```text
//! w_max^2 <= sum over beams   w_(N_M)^2                               bending, highest mode
//!          + sum over supports k_0 (1/(mu s) + 1/m_0)                 beam to level 0 (sine
//!                              + k_l (1/m_(l-1) + 1/m_l)              orthogonality), links,
//!                              + (k_g + 4 k_w) / m_L                  ground and shear
//!          + k_P (B_P + lambda_max(G))      elements to points moving on a beam
//!          + Gershgorin(rigid)              elements among bodies and to the ground
//! ```
//! `G_ih = sum_k Y_k(x_i) Y_k(x_h)` is the Gram matrix of a beam's moving points, bounded with
//! the Dirichlet kernel `|sum_(k=1)^N cos k theta| <= D(theta) = min(N, 1/(2 |sin(theta/2)|) +
//! 1/2)`: with every point at least `e` from the beam's ends and points at least `d` apart,
//! `G_ii <= (N + D_e) / (mu L)` and `|G_ih| <= (D_d + D_e) / (mu L)`. `B_P` is the Gershgorin
//! bound of the body side of those elements, `k_P` their largest tangent stiffness, a contact
//! linearised at [`CONTACT_LOAD_FACTOR`] times its static force. Supports not on a uniform grid
//! use the Gram matrix of the support shapes, its largest eigenvalue by power iteration with a
//! [`POWER_MARGIN`]. The same split bounds the damping rate. A `dt` is accepted when every
//! oscillator with `w <= w_max` and `2 xi w <= c_max` is stable.

use crate::corners::{corner_values, largest_corners_up_to};
use crate::engine::{Coupling, Engine};
use mbd_system::model::{ModelEnd, ModelLaw};
use std::f64::consts::PI;

/// Static force multiple at which contacts are linearised: dynamic loads stay well below 3x
/// the static ones, and the bound grows only as the cube root of this factor.
pub const CONTACT_LOAD_FACTOR: f64 = 3.0;
/// Safety factor on a power-iteration estimate of a largest eigenvalue.
pub const POWER_MARGIN: f64 = 1.05;

/// Spectral radius of the amplification matrix for `W = w dt` and `g = 2 xi w dt`, by repeated
/// squaring (`rho = lim ||A^(2^k)||^(1/2^k)`), accurate to ~1e-10 here.
pub fn spectral_radius(w_dt: f64, g: f64) -> f64 {
    let w2 = w_dt * w_dt;
    let mut a = [
        [1.0 - w2, 1.0 - g, -0.5],
        [-1.5 * w2, 1.0 - 1.5 * g, -0.5],
        [-w2, -g, 0.0],
    ];
    let mut log_norm = 0.0;
    let mut power = 1.0;
    for _ in 0..40 {
        let mut sq = [[0.0; 3]; 3];
        for (i, row) in sq.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = (0..3).map(|k| a[i][k] * a[k][j]).sum();
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
    // Marginal (undamped) eigenvalues sit on the unit circle; round-off and the finite number
    // of squarings put them within 1e-9 of it.
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

/// Upper bounds of the highest circular frequency (rad/s) and damping rate (1/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// Highest circular frequency bound (rad/s).
    pub omega_max: f64,
    /// Damping-rate bound (1/s).
    pub damping_max: f64,
}

fn dirichlet(n: f64, half_angle: f64) -> f64 {
    let s = half_angle.sin().abs();
    if s > 0.0 {
        (0.5 / s + 0.5).min(n)
    } else {
        n
    }
}

/// Gershgorin bound of the largest eigenvalue of `M^-1/2 (sum_e w_e b_e b_e^T) M^-1/2`, `b_e`
/// the rigid-DOF participation of element `e`'s deflection.
fn rigid_gershgorin(engine: &Engine, elements: &[(usize, f64)]) -> f64 {
    let m = &engine.model;
    let n = m.dof_mass.len();
    if n == 0 || elements.is_empty() {
        return 0.0;
    }
    let mut k = vec![vec![0.0; n]; n];
    for &(e, w) in elements {
        let b = m.elements[e].incidence(n);
        for i in 0..n {
            for j in 0..n {
                k[i][j] += w * b[i] * b[j];
            }
        }
    }
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| k[i][j].abs() / (m.dof_mass[i] * m.dof_mass[j]).sqrt())
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

/// The contacts' static forces of a rigid part that is not statically determinate, estimated
/// by one linear solve: the beams and the ground held, every spring-damper and table at its
/// stiffness, every contact at one common stiffness (a wheel's tangential motions held by a
/// unit stiffness beside it), `K q = F` under the loads, each contact's force `k_c b . q`
/// (0 where it would pull). The contacts share the loads as the rigid part's geometry and
/// springs distribute them; with contacts much stiffer than the suspension, as on a vehicle,
/// this is the static distribution to within the contacts' compliance. `None` when there is
/// no contact or `K` is singular.
fn linear_contact_loads(engine: &Engine) -> Option<Vec<f64>> {
    let m = &engine.model;
    let n = m.dof_mass.len();
    let contacts: Vec<usize> = (0..m.elements.len())
        .filter(|&e| m.elements[e].law.is_contact())
        .collect();
    if n == 0 || contacts.is_empty() {
        return None;
    }
    let total: f64 = m.loads.iter().map(|l| l.force.abs()).sum();
    let mean = (total / contacts.len() as f64).max(1e-9);
    let k_contact = |e: usize| {
        let law = &m.elements[e].law;
        law.stiffness(law.static_deflection(mean).unwrap_or(0.0))
    };
    let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
    let mut add = |w: f64, b: &[f64]| {
        for i in 0..n {
            for j in 0..n {
                k[(i, j)] += w * b[i] * b[j];
            }
        }
    };
    for (e, el) in m.elements.iter().enumerate() {
        let w = match &el.law {
            ModelLaw::SpringDamper { k, .. } => *k,
            ModelLaw::Table { .. } => 1.0,
            _ => k_contact(e),
        };
        add(w, &el.incidence(n));
        if let Some(wheel) = el.law.wheel() {
            for b in wheel.tangential_incidence(n) {
                add(1.0, &b);
            }
        }
    }
    let mut f = nalgebra::DVector::<f64>::zeros(n);
    for l in &m.loads {
        if let ModelEnd::Body(t) = l.at {
            for (i, c) in t.terms() {
                f[i] += c * l.force;
            }
        }
    }
    let q = k.lu().solve(&f)?;
    let mut out = vec![0.0; m.elements.len()];
    for &e in &contacts {
        let b = m.elements[e].incidence(n);
        let d: f64 = b.iter().zip(q.iter()).map(|(b, q)| b * q).sum();
        out[e] = (k_contact(e) * d).max(0.0);
    }
    out.iter().all(|f| f.is_finite()).then_some(out)
}

/// The rigid part's bounds (1/s^2, 1/s) in a system with wheels, in mass-normalised
/// coordinates: the largest eigenvalue of the symmetric, positive semi-definite stiffness of
/// the elements among bodies and the ground (`stiffnesses`: element and tangent stiffness) and
/// of the wheels' flange springs, and of the dampers' and the wheels' creep damping (`f22 / V`
/// laterally, `f11 / V` longitudinally, each wheel at the load `load(e)`, N), exactly
/// (nalgebra); plus a norm bound `sqrt(|N|_1 |N|_inf)` of the wheels' non-symmetric terms
/// (the normal force's lateral part against roll and shift, the creep couplings of lateral
/// creep to yaw `f22` and of rolling radius to yaw `e0 f11 |rho'| / r0`, the spin coupling
/// `f23 / V`). The spectral radius of the sum is at most the sum of these.
fn spatial_rigid(
    engine: &Engine,
    stiffnesses: &[(usize, f64)],
    dampings: &[(usize, f64)],
    load: &dyn Fn(usize) -> f64,
) -> (f64, f64) {
    let m = &engine.model;
    let n = m.dof_mass.len();
    let zero = || nalgebra::DMatrix::<f64>::zeros(n, n);
    let (mut k, mut c, mut kn, mut cn) = (zero(), zero(), zero(), zero());
    let add = |a: &mut nalgebra::DMatrix<f64>, w: f64, u: &[f64], v: &[f64], abs: bool| {
        for i in 0..n {
            for j in 0..n {
                let x = w * u[i] * v[j];
                a[(i, j)] += if abs { x.abs() } else { x };
            }
        }
    };
    for &(e, w) in stiffnesses {
        let b = m.elements[e].incidence(n);
        add(&mut k, w, &b, &b, false);
    }
    for &(e, w) in dampings {
        let b = m.elements[e].incidence(n);
        add(&mut c, w, &b, &b, false);
    }
    let speed = m.speed.max(1e-9);
    for (e, wheel) in engine.wheels.iter().enumerate() {
        let (Some(w), Some(mw)) = (wheel, m.elements[e].law.wheel()) else {
            continue;
        };
        let q = load(e);
        let q13 = q.cbrt();
        let (f11, f22, f23) = (
            w.creep.k11 * q13 * q13,
            w.creep.k22 * q13 * q13,
            w.creep.k23 * q,
        );
        let [lateral, longitudinal] = mw.tangential_incidence(n);
        let unit = |i: usize| {
            let mut u = vec![0.0; n];
            u[i] = 1.0;
            u
        };
        let (roll, yaw) = (unit(w.roll), unit(w.yaw));
        let (slope, tan_max, angle_slope) = geometry_slopes(&w.geometry);
        let normal = q * (1.0 + tan_max * tan_max);
        add(
            &mut k,
            w.flange.map_or(0.0, |f| f.1),
            &lateral,
            &lateral,
            false,
        );
        add(&mut c, f22 / speed, &lateral, &lateral, false);
        add(&mut c, f11 / speed, &longitudinal, &longitudinal, false);
        add(&mut kn, normal * angle_slope, &lateral, &lateral, true);
        add(&mut kn, normal, &lateral, &roll, true);
        add(&mut kn, f22, &lateral, &yaw, true);
        add(
            &mut kn,
            f11 * slope / w.radius,
            &longitudinal,
            &lateral,
            true,
        );
        add(&mut cn, f23 / speed, &lateral, &yaw, true);
        add(&mut cn, f23 / speed, &yaw, &lateral, true);
    }
    let scale = |a: &mut nalgebra::DMatrix<f64>| {
        for i in 0..n {
            for j in 0..n {
                a[(i, j)] /= (m.dof_mass[i] * m.dof_mass[j]).sqrt();
            }
        }
    };
    for a in [&mut k, &mut c, &mut kn, &mut cn] {
        scale(a);
    }
    let largest = |a: nalgebra::DMatrix<f64>| {
        a.symmetric_eigenvalues()
            .iter()
            .fold(0.0f64, |m, l| m.max(*l))
    };
    let norm = |a: &nalgebra::DMatrix<f64>| {
        let rows = (0..n).map(|i| a.row(i).sum()).fold(0.0, f64::max);
        let cols = (0..n).map(|j| a.column(j).sum()).fold(0.0, f64::max);
        (rows * cols).sqrt()
    };
    (largest(k) + norm(&kn), largest(c) + norm(&cn))
}

/// The largest `|d rho / du|`, `|tan delta|` and `|d delta / du|` of a wheel's geometry.
fn geometry_slopes(g: &crate::wheel::Geometry) -> (f64, f64, f64) {
    match g {
        crate::wheel::Geometry::Cone { gamma, .. } => (gamma.abs(), gamma.abs(), 0.0),
        crate::wheel::Geometry::Table {
            shift,
            radius,
            angle,
        } => {
            let slope = |v: &[f64]| {
                shift
                    .windows(2)
                    .zip(v.windows(2))
                    .map(|(s, v)| ((v[1] - v[0]) / (s[1] - s[0])).abs())
                    .fold(0.0, f64::max)
            };
            let tan = angle.iter().map(|a| a.tan().abs()).fold(0.0, f64::max);
            (slope(radius), tan, slope(angle))
        }
    }
}

/// Largest eigenvalue of `Y^T Y` (`y[j * nm + k] = Y_k(x_j)`) by power iteration, times
/// [`POWER_MARGIN`].
fn support_gram(y: &[f64], nm: usize) -> f64 {
    let ns = y.len() / nm;
    let mut v = vec![1.0 / (nm as f64).sqrt(); nm];
    let mut lambda = 0.0;
    let mut t = vec![0.0; ns];
    for _ in 0..200 {
        for (j, tj) in t.iter_mut().enumerate() {
            *tj = y[j * nm..(j + 1) * nm]
                .iter()
                .zip(&v)
                .map(|(a, b)| a * b)
                .sum();
        }
        let mut w = vec![0.0; nm];
        for (j, tj) in t.iter().enumerate() {
            for (wk, yk) in w.iter_mut().zip(&y[j * nm..(j + 1) * nm]) {
                *wk += tj * yk;
            }
        }
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            return 0.0;
        }
        lambda = norm;
        v = w.into_iter().map(|x| x / norm).collect();
    }
    lambda * POWER_MARGIN
}

impl Bound {
    /// The bound of one assembled sample.
    pub fn of(engine: &Engine) -> Self {
        let m = &engine.model;
        let statics = crate::statics::static_forces(&engine.system, m)
            .map(|s| s.force)
            .or_else(|| linear_contact_loads(engine));
        let total_load: f64 = m.loads.iter().map(|l| l.force.abs()).sum();
        let (mut omega2, mut damping) = beams_with_supports(engine);
        // Elements: to points moving on a beam (per beam), or among bodies and the ground.
        // A contact's static force: its own when the rigid part is determinate, else every
        // load at once (an upper bound).
        let static_load = |e: usize| -> f64 {
            statics
                .as_ref()
                .map_or(total_load, |s| s[e])
                .abs()
                .max(1e-9)
        };
        let tangent = |e: usize| tangent_stiffness(&m.elements[e].law, static_load(e));
        let rigid: Vec<usize> = (0..m.elements.len())
            .filter(|&e| on_beam(engine, e).is_none())
            .collect();
        let stiffnesses: Vec<(usize, f64)> = rigid.iter().map(|&e| (e, tangent(e))).collect();
        let dampings: Vec<(usize, f64)> = rigid
            .iter()
            .map(|&e| (e, m.elements[e].law.damping()))
            .collect();
        if engine.wheels.is_empty() {
            omega2 += rigid_gershgorin(engine, &stiffnesses);
            damping += rigid_gershgorin(engine, &dampings);
        } else {
            let (k, c) = spatial_rigid(engine, &stiffnesses, &dampings, &|e| {
                CONTACT_LOAD_FACTOR * static_load(e)
            });
            // The beams with their supports and the rigid part act on disjoint DOFs: the
            // larger of their bounds holds for both (the elements joining them come below).
            omega2 = omega2.max(k);
            damping = damping.max(c);
        }
        for (k, c) in moving_point_terms(engine, &tangent) {
            omega2 += k;
            damping += c;
        }
        Bound {
            omega_max: omega2.sqrt(),
            damping_max: damping,
        }
    }

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
        if self.omega_max == 0.0 && self.damping_max == 0.0 {
            return f64::INFINITY;
        }
        let mut lo = 0.0;
        let mut hi = 2.5 / self.omega_max.max(self.damping_max / 2.0);
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

    /// The larger of two bounds, component by component.
    pub fn max(self, other: Bound) -> Bound {
        Bound {
            omega_max: self.omega_max.max(other.omega_max),
            damping_max: self.damping_max.max(other.damping_max),
        }
    }
}

/// The bounds (1/s^2, 1/s) of the beams with their supports: each beam with its supports is a
/// system of its own (their matrices are blocks on disjoint DOFs), so the largest of their
/// bounds holds for all.
fn beams_with_supports(engine: &Engine) -> (f64, f64) {
    let m = &engine.model;
    let (mut omega2, mut damping) = (0.0, 0.0);
    for (b, beam) in engine.beams.iter().enumerate() {
        let (mut beam_omega2, mut beam_damping) = (0.0, 0.0);
        beam_omega2 += beam.modal.omega2.last().copied().unwrap_or(0.0);
        beam_damping += beam.modal.damping.last().copied().unwrap_or(0.0);
        let mb = &m.beams[b];
        let supported = match &beam.coupling {
            Coupling::None => None,
            Coupling::Fast(s) => Some((s, 1.0 / (mb.mass_per_length * s.spacing))),
            Coupling::Dense(s, y) => Some((s, support_gram(y, beam.modal.modes()))),
        };
        if let Some((s, seat)) = supported {
            let top = &s.levels[0];
            beam_omega2 += top.k * (seat + 1.0 / top.mass);
            beam_damping += top.c * (seat + 1.0 / top.mass);
            for pair in s.levels.windows(2) {
                let coupling = 1.0 / pair[0].mass + 1.0 / pair[1].mass;
                beam_omega2 += pair[1].k * coupling;
                beam_damping += pair[1].c * coupling;
            }
            let last = s.levels.last().expect("at least one level");
            let (kw, cw) = last.shear.unwrap_or((0.0, 0.0));
            beam_omega2 += (s.ground.0 + 4.0 * kw) / last.mass;
            beam_damping += (s.ground.1 + 4.0 * cw) / last.mass;
        }
        omega2 = f64::max(omega2, beam_omega2);
        damping = f64::max(damping, beam_damping);
    }
    (omega2, damping)
}

/// The largest tangent stiffness of a law (N/m): a contact's at [`CONTACT_LOAD_FACTOR`] times
/// its static force `static_load` (N), a table's steepest segment, a spring's `k`.
fn tangent_stiffness(law: &ModelLaw, static_load: f64) -> f64 {
    match law {
        ModelLaw::Hertz { .. } | ModelLaw::Wheel(_) => {
            let d = law
                .static_deflection(CONTACT_LOAD_FACTOR * static_load)
                .unwrap_or(0.0);
            law.stiffness(d)
        }
        ModelLaw::Table {
            deflection, force, ..
        } => deflection
            .windows(2)
            .zip(force.windows(2))
            .map(|(d, f)| ((f[1] - f[0]) / (d[1] - d[0])).abs())
            .fold(0.0, f64::max),
        ModelLaw::SpringDamper { k, .. } => *k,
    }
}

/// The beam that element `e`'s lower end moves on, if any.
fn on_beam(engine: &Engine, e: usize) -> Option<usize> {
    let m = &engine.model;
    match m.elements[e].to {
        ModelEnd::Moving(p) => m.points[p].0,
        _ => None,
    }
}

/// Per beam with elements to points moving on it, the terms (1/s^2, 1/s) of those elements:
/// their largest tangent stiffness (`tangent`, N/m) and damping times the Gershgorin bound of
/// their body side plus the Dirichlet-kernel bound of the beam's Gram matrix at its points.
fn moving_point_terms(engine: &Engine, tangent: &dyn Fn(usize) -> f64) -> Vec<(f64, f64)> {
    let m = &engine.model;
    let c = &engine.config;
    let t_end = c.t_end();
    let mut terms = Vec::new();
    for (b, beam) in engine.beams.iter().enumerate() {
        let elements: Vec<usize> = (0..m.elements.len())
            .filter(|&e| on_beam(engine, e) == Some(b))
            .collect();
        if elements.is_empty() {
            continue;
        }
        let n_modes = beam.modal.modes() as f64;
        let l = beam.modal.length;
        let offsets: Vec<f64> = beam.points.iter().map(|&p| m.points[p].1).collect();
        let lo = offsets.iter().fold(f64::INFINITY, |a, o| a.min(c.x0 + o));
        let hi = offsets
            .iter()
            .fold(f64::NEG_INFINITY, |a, o| a.max(c.x0 + m.speed * t_end + o));
        let edge = lo.min(l - hi).max(0.0);
        let mut spacing = f64::INFINITY;
        for (i, a) in offsets.iter().enumerate() {
            for b in &offsets[i + 1..] {
                spacing = spacing.min((a - b).abs());
            }
        }
        let n_p = offsets.len() as f64;
        let d_e = dirichlet(n_modes, PI * edge / l);
        let d_d = if spacing.is_finite() {
            dirichlet(n_modes, PI * spacing / (2.0 * l))
        } else {
            0.0
        };
        let row = (n_modes + d_e) + (n_p - 1.0) * (d_d + d_e);
        let gram = row.min(2.0 * n_p * n_modes) / (mb_mu(engine, b) * l);
        let body_side = rigid_gershgorin(
            engine,
            &elements.iter().map(|&e| (e, 1.0)).collect::<Vec<_>>(),
        );
        let k_max = elements.iter().map(|&e| tangent(e)).fold(0.0, f64::max);
        let c_max = elements
            .iter()
            .map(|&e| m.elements[e].law.damping())
            .fold(0.0, f64::max);
        terms.push((k_max * (body_side + gram), c_max * (body_side + gram)));
    }
    terms
}

/// The bound over the whole box of sampling ranges: the largest frequency and damping bounds
/// over its corners (each bound term grows or falls monotonically with each parameter of the
/// simple models, so the corners hold the extremes; which corners are visited:
/// [`crate::corners`]), with every visited corner's model assembled (coverage of the beams
/// checked). Returns the bound and the corner that set the frequency bound, as `(name,
/// value)` pairs.
pub fn parameter_box(
    system: &std::sync::Arc<mbd_system::System>,
    config: &crate::RunConfig,
) -> crate::Result<(Bound, Vec<(String, f64)>)> {
    parameter_box_up_to(system, config, crate::corners::ALL_CORNERS_UP_TO)
}

/// [`parameter_box`], visiting every corner up to `all_up_to` sampled parameters.
fn parameter_box_up_to(
    system: &std::sync::Arc<mbd_system::System>,
    config: &crate::RunConfig,
    all_up_to: usize,
) -> crate::Result<(Bound, Vec<(String, f64)>)> {
    let ranges = system.ranges();
    let largest = largest_corners_up_to(ranges.len(), all_up_to, &|mask| {
        let model = system.instantiate(&corner_values(system, &ranges, mask))?;
        let engine = Engine::assemble(
            system.clone(),
            model,
            config,
            Vec::new(),
            crate::Route::Fast,
        )?;
        let b = Bound::of(&engine);
        Ok(vec![b.omega_max, b.damping_max])
    })?;
    let (omega_max, mask) = largest[0];
    let corner = corner_values(system, &ranges, mask)
        .iter()
        .map(|(n, v)| (n.to_owned(), v))
        .collect();
    Ok((
        Bound {
            omega_max,
            damping_max: largest[1].0,
        },
        corner,
    ))
}

fn mb_mu(engine: &Engine, b: usize) -> f64 {
    engine.model.beams[b].mass_per_length
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound over the box found by the search of [`crate::corners`] is the bound of
    /// every corner visited, on the shipped quarter car and bridge (their bounds move
    /// monotonically with each parameter).
    #[test]
    fn the_searched_box_bound_is_the_bound_over_every_corner() {
        let config = crate::RunConfig {
            duration: 0.5,
            dt: 1e-4,
            output_every: 10,
            start: crate::StartMode::Equilibrium,
            startup_zero_fraction: 0.0,
            startup_ramp_fraction: 0.0,
            x0: 5.0,
        };
        for text in [
            include_str!("../../../systems/quarter-car.yaml"),
            include_str!("../../../systems/bridge.yaml"),
        ] {
            let system = std::sync::Arc::new(
                mbd_system::load_str(text, "s.yaml", &Default::default())
                    .unwrap_or_else(|d| panic!("{d}")),
            );
            let (every, _) = parameter_box_up_to(&system, &config, 64).unwrap();
            let (searched, corner) = parameter_box_up_to(&system, &config, 0).unwrap();
            assert_eq!(searched, every, "{}", system.name);
            assert_eq!(corner.len(), system.ranges().len());
        }
    }

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
}
