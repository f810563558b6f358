//! The static equilibrium at `t = 0`: every velocity zero, every acceleration zero, the loads
//! carried by the elements onto the beams and the ground.
//!
//! **Fast path** (every rigid body statically determinate, every supported beam on uniform
//! supports from `x = 0`): three passes.
//! 1. *Forces.* A body whose unknown element forces are as many as its DOFs is solved from its
//!    own equilibrium (`sum` of the generalised forces = 0, known forces and loads on the right);
//!    its elements' forces become known, and the next such body follows. For a vehicle this
//!    runs from the car body down to the wheels: suspensions carry nothing, each contact the
//!    load of its wheel.
//! 2. *Beams.* Each beam deflects under its points' static forces at `x_i(0)`: without supports
//!    `q_k = sum_i F_i Y_k(x_i) / w_k^2`; with uniform supports the condensed problem below, by
//!    preconditioned conjugate gradients.
//! 3. *Positions,* bodies in the reverse order: each element's static deflection under its
//!    force (`G F^(2/3)` for Hertz, `(F - preload) / k` for a spring) fixes its upper end from
//!    its lower end, `u_from = (u_to + eta) + d`; a body of one or two DOFs solves its rows
//!    `z + c_j beta = y_j` in closed form (`beta = (y_2 - y_1) / (c_2 - c_1)`, `z = w_1 y_1 +
//!    w_2 y_2`, which for symmetric points is the mean), larger ones by LU.
//!
//! *Supports, condensed.* With velocities zero the chain is linear: the links above the last
//! level act in series, `k_top = k_0 k_1 / (k_0 + k_1)` folded over the levels, so
//! `F_0j = k_top (w(x_j) - z_Lj)`, and the last level solves one tridiagonal system,
//! `(k_top + k_g + 2 k_w) z_Lj - k_w (z_L(j-1) + z_L(j+1)) = k_top w(x_j)`. The modal problem
//! `w_k^2 q_k + sum_j F_0j Y_k(x_j) = b_k` is symmetric positive definite; its operator costs two
//! sine transforms and one tridiagonal solve. The preconditioner is exact for the same track
//! without the support under the end node: there the support grid shares the beam's discrete
//! sine basis and the modal operator is diagonal, `w_k^2 + (N/2) scale^2 s_k` with
//! `s_k = k_top - k_top^2 / (k_top + k_g + k_w (2 - 2 cos(pi k / N)))`; the real track differs by
//! one support, so the iteration reaches round-off in a few steps. An intermediate level sits
//! between its neighbours: `z_0 = (k_0 w + k_1 z_1) / (k_0 + k_1)` for one, by the series force
//! for more.
//!
//! **General route** (anything else, or [`crate::Route::General`]): Newton's method on the whole
//! state, `J dX = -A(X)` with the Jacobian by central differences and a dense LU solve, with
//! backtracking on the residual. The fast path is tested equal to it.
//!
//! **Wheelsets at rest.** The state sought has every velocity zero with the frame moving at
//! `V` (the wheels roll; [`crate::wheel`] states the forces and signs: `x` forward, `y` right,
//! `z` down). Which stiffness restrains which DOF there:
//! - *Vertical:* each wheel's Hertz contact, tangent `dQ/dd = 1.5 Q^(1/3) / G` (N/m), holds its
//!   wheelset's `z` and, the two wheels together, its roll (`2 e0^2` times that, N m/rad); the
//!   suspensions hold the bodies above; the rails and their supports sit under the contacts.
//! - *Lateral rail:* its fastening spring `k` (N/m) toward the alignment under it.
//! - *Wheelset on its rails* (shift `u = y - y_rail`, yaw `psi`): only the wheel-rail contact.
//!   For conical treads the gravitational stiffness `2 Q gamma (1 + gamma^2) / e0` (N/m,
//!   restoring: a shift `y` rolls the axle by `-gamma y / e0` and tilts both normal forces);
//!   the rolling-radius difference's longitudinal creep, a yaw moment `-2 e0 f11 gamma u / r0`
//!   (N m); the yaw's lateral creep, a force `2 f22 psi` (N) (these two a circulatory pair,
//!   the yaw itself held by the suspension); the flange `k_fl` beyond its clearance. The
//!   bodies above a wheelset (bogie, car body), which hang on it laterally, inherit this.
//!
//! Every one of these grows with the wheel load `Q` (`f11, f22 ~ Q^(2/3)`): at zero load the
//! whole vehicle's lateral translation and yaw relative to the rails are free. Newton's start
//! presses each contact by a 1 N force only, where that stiffness is about `1e-5` of its
//! loaded value and near the central differences' round-off: the Jacobian is singular or
//! nearly so, and the first steps wander far sideways (they may not come back). With
//! wheelsets, both routes therefore solve in two stages: first with each wheelset's `y` and yaw
//! (and `x`) and the lateral rails under it held at the start (their rows left out), which
//! puts the loads on the contacts (the bodies above held laterally by their suspensions to the
//! wheelsets); then every unknown from there, where the wheel-rail lateral stiffness is the
//! loaded one. On the condensed route Newton also starts from the loaded contacts rather than
//! from 1 N: every wheel pressed by the mean wheel load on the rails deflected under those
//! loads, each wheelset's height and roll putting both its wheels there (from 1 N the first
//! vertical step, on the tangent of a 1 N Hertz contact, overshoots far enough to open every
//! contact).

use crate::beam::ModalBeam;
use crate::dst::SineTransform;
use crate::engine::{Coupling, Engine, Route};
use crate::{Error, Result};
use mbd_system::model::{Model, ModelEnd, ModelSupports};
use mbd_system::system::Source;
use mbd_system::System;
use std::f64::consts::PI;

/// Relative residual the conjugate gradients stop at.
const TOLERANCE: f64 = 1e-14;
/// Relative residual below which a stalled iteration still counts as converged.
const ACCEPT: f64 = 1e-11;
/// Iterations without a new smallest residual after which the iteration has stalled.
const STALL: usize = 10;
/// Iteration cap of the conjugate gradients.
const MAX_ITERATIONS: usize = 500;
/// Newton iterations of the general route.
const NEWTON_ITERATIONS: usize = 60;

/// The static forces of every element, and the bodies in the order they were solved with the
/// elements that solved each (`None` when the rigid part is not statically determinate).
#[derive(Debug, Clone, PartialEq)]
pub struct StaticForces {
    /// Force of each element (N).
    pub force: Vec<f64>,
    /// Bodies in solving order, each with its solving elements.
    pub order: Vec<(usize, Vec<usize>)>,
}

fn body_dofs(system: &System, body: usize) -> Vec<usize> {
    let b = &system.bodies[body];
    // Vertical bodies keep the order z, pitch of the closed forms below.
    b.z.into_iter()
        .chain(b.pitch)
        .chain(
            b.dofs()
                .into_iter()
                .filter(|&d| Some(d) != b.z && Some(d) != b.pitch),
        )
        .collect()
}

fn on_body(end: &ModelEnd, dofs: &[usize]) -> bool {
    match end {
        ModelEnd::Body(t) => t.terms().any(|(i, _)| dofs.contains(&i)),
        _ => false,
    }
}

/// Pass 1 of the fast path: the element forces from body equilibrium, when determinate.
pub fn static_forces(system: &System, m: &Model) -> Option<StaticForces> {
    let n_b = system.bodies.len();
    let mut known = vec![false; m.elements.len()];
    let mut force = vec![0.0; m.elements.len()];
    let mut done = vec![false; n_b];
    let mut order = Vec::new();
    let elements_of: Vec<Vec<usize>> = (0..n_b)
        .map(|b| {
            let dofs = body_dofs(system, b);
            (0..m.elements.len())
                .filter(|&e| {
                    on_body(&m.elements[e].from, &dofs) || on_body(&m.elements[e].to, &dofs)
                })
                .collect()
        })
        .collect();
    while order.len() < n_b {
        let next = (0..n_b).find(|&b| {
            !done[b] && {
                let unknown = elements_of[b].iter().filter(|&&e| !known[e]).count();
                unknown == body_dofs(system, b).len()
            }
        })?;
        let dofs = body_dofs(system, next);
        let unknown: Vec<usize> = elements_of[next]
            .iter()
            .copied()
            .filter(|&e| !known[e])
            .collect();
        let n = dofs.len();
        // Rows: each DOF's generalised force; columns: the unknown elements.
        let mut a = vec![vec![0.0; n]; n];
        let mut rhs = vec![0.0; n];
        for (r, &dof) in dofs.iter().enumerate() {
            let mut total = 0.0;
            for (gi, g) in m.assembly[dof].iter().enumerate() {
                let coef = g.coefficient.unwrap_or(1.0);
                let mut sum = 0.0;
                let mut first = true;
                for (s, sign) in &g.terms {
                    let value = match *s {
                        Source::Load(i) => Some(m.loads[i].force),
                        Source::Element(i) if known[i] => Some(force[i]),
                        Source::Element(i) => {
                            let c = unknown
                                .iter()
                                .position(|&u| u == i)
                                .expect("an unknown of this body");
                            a[r][c] += coef * sign;
                            None
                        }
                    };
                    if let Some(v) = value {
                        let signed = if *sign < 0.0 { -v } else { v };
                        sum = if first { signed } else { sum + signed };
                        first = false;
                    }
                }
                let gv = if g.coefficient.is_some() {
                    coef * sum
                } else {
                    sum
                };
                total = if gi == 0 { gv } else { total + gv };
            }
            rhs[r] = -total;
        }
        let f = solve_small(&a, &rhs)?;
        for (c, &e) in unknown.iter().enumerate() {
            force[e] = f[c];
            known[e] = true;
        }
        done[next] = true;
        order.push((next, unknown));
    }
    // Elements between the ground or moving points only carry nothing statically determinable.
    if known.iter().any(|k| !k) {
        return None;
    }
    Some(StaticForces { force, order })
}

/// `a x = b` for n = 1 or 2 in closed form, LU beyond; `None` when singular.
fn solve_small(a: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    match a.len() {
        0 => Some(Vec::new()),
        1 => (a[0][0] != 0.0).then(|| vec![b[0] / a[0][0]]),
        2 => {
            let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
            if det == 0.0 || !det.is_finite() {
                return None;
            }
            Some(vec![
                (b[0] * a[1][1] - a[0][1] * b[1]) / det,
                (a[0][0] * b[1] - b[0] * a[1][0]) / det,
            ])
        }
        n => {
            let m = nalgebra::DMatrix::from_fn(n, n, |i, j| a[i][j]);
            let v = nalgebra::DVector::from_column_slice(b);
            m.lu().solve(&v).map(|x| x.iter().copied().collect())
        }
    }
}

/// The static equilibrium state (displacements; velocities are zero).
pub fn equilibrium(engine: &Engine) -> Result<Vec<f64>> {
    let fast_beams = engine
        .beams
        .iter()
        .all(|b| !matches!(b.coupling, Coupling::Dense(..)));
    if engine.route == Route::Fast && fast_beams {
        if let Some(f) = static_forces(&engine.system, &engine.model) {
            return fast(engine, &f);
        }
        if engine.beams.iter().any(|b| !b.points.is_empty()) {
            return condensed(engine);
        }
    }
    general(engine)
}

/// The static state of beam `b` under the point forces `point_force` (N, downward, at the
/// points' positions `px` at `t = 0`): its modal coordinates and support levels.
fn beam_static(
    engine: &Engine,
    b: usize,
    px: &[f64],
    point_force: &[f64],
) -> Result<(Vec<f64>, Vec<f64>)> {
    let beam = &engine.beams[b];
    let nm = beam.modal.modes();
    let mut rhs = vec![0.0; nm];
    let mut y = vec![0.0; nm];
    for &p in &beam.points {
        beam.modal.shapes_at(px[p], &mut y);
        for (r, yk) in rhs.iter_mut().zip(&y) {
            *r += point_force[p] * yk;
        }
    }
    match &beam.coupling {
        Coupling::None => Ok((
            rhs.iter()
                .zip(&beam.modal.omega2)
                .map(|(r, w2)| r / w2)
                .collect(),
            Vec::new(),
        )),
        Coupling::Fast(s) => supported_deflection(&beam.modal, s, &rhs),
        Coupling::Dense(..) => unreachable!("the general route handles dense couplings"),
    }
}

/// Deflection `w` under moving point `p` of a static beam state (m; 0 on the ground or off a
/// beam).
fn point_deflection(engine: &Engine, x: &[f64], p: usize, position: f64) -> f64 {
    let Some(b) = engine.model.points[p].0 else {
        return 0.0;
    };
    let modal = &engine.beams[b].modal;
    let modes = engine.layout.beams[b].modes.clone();
    let mut y = vec![0.0; modal.modes()];
    modal.shapes_at(position, &mut y);
    ModalBeam::deflection(&y, &x[modes])
}

fn fast(engine: &Engine, sf: &StaticForces) -> Result<Vec<f64>> {
    let m = &engine.model;
    let c = &engine.config;
    let mut x = vec![0.0; engine.layout.len];
    let origin = c.x0 + m.speed * 0.0;
    let px: Vec<f64> = m.points.iter().map(|(_, o)| origin + o).collect();
    // Point loads: the static forces of the elements ending there, and the loads there.
    let mut point_force = vec![0.0; m.points.len()];
    for (i, e) in m.elements.iter().enumerate() {
        if let ModelEnd::Moving(p) = e.to {
            point_force[p] += sf.force[i];
        }
    }
    for l in &m.loads {
        if let ModelEnd::Moving(p) = l.at {
            point_force[p] += l.force;
        }
    }
    for b in 0..engine.beams.len() {
        let lay = &engine.layout.beams[b];
        let (q, levels) = beam_static(engine, b, &px, &point_force)?;
        x[lay.modes.clone()].copy_from_slice(&q);
        x[lay.supports.clone()].copy_from_slice(&levels);
    }
    // Positions, bodies in the reverse order of the force pass.
    let ramp = c.ramp(0.0);
    for (body, elements) in sf.order.iter().rev() {
        let dofs = body_dofs(&engine.system, *body);
        let mut rows = Vec::with_capacity(elements.len());
        for &e in elements {
            let el = &m.elements[e];
            let d = el
                .law
                .static_deflection(sf.force[e])
                .ok_or_else(|| Error::Statics {
                    what: format!(
                    "element `{}` cannot carry its static force {:.6e} N (a contact in tension?)",
                    engine.system.elements[e].name, sf.force[e]
                ),
                })?;
            let eta = match (el.profile, el.to) {
                (Some(p), ModelEnd::Moving(pt)) if ramp > 0.0 => {
                    Some(ramp * engine.profiles[p].at(px[pt]))
                }
                (Some(_), _) => Some(0.0),
                _ => None,
            };
            let other = |end: &ModelEnd| match end {
                ModelEnd::Ground => 0.0,
                ModelEnd::Body(t) => t.displacement(&x),
                ModelEnd::Moving(p) => point_deflection(engine, &x, *p, px[*p]),
            };
            // The body is the element's upper end (u_from = (u_to + eta) + d) or its lower end
            // (u_to = (u_from - eta) - d).
            let (terms, y) = if on_body(&el.from, &dofs) {
                let mut y = other(&el.to);
                if let Some(eta) = eta {
                    y += eta;
                }
                (el.from, y + d)
            } else {
                let mut y = other(&el.from);
                if let Some(eta) = eta {
                    y -= eta;
                }
                (el.to, y - d)
            };
            let ModelEnd::Body(t) = terms else {
                unreachable!("on the body")
            };
            rows.push((t, y));
        }
        let values = solve_positions(&dofs, &rows).ok_or_else(|| Error::Statics {
            what: format!(
                "the static position of body `{}` is singular",
                engine.system.bodies[*body].name
            ),
        })?;
        for (dof, v) in dofs.iter().zip(values) {
            x[*dof] = v;
        }
    }
    Ok(x)
}

/// Solves `u_j = z + c_j beta = y_j` (or the one-DOF forms) for a body's DOFs.
fn solve_positions(
    dofs: &[usize],
    rows: &[(mbd_system::model::PointTerms, f64)],
) -> Option<Vec<f64>> {
    let coef = |t: &mbd_system::model::PointTerms, dof: usize| -> f64 {
        t.terms().find(|(i, _)| *i == dof).map_or(0.0, |(_, c)| c)
    };
    match dofs.len() {
        1 => {
            let (t, y) = rows[0];
            let c = coef(&t, dofs[0]);
            if c == 1.0 {
                Some(vec![y])
            } else {
                (c != 0.0).then(|| vec![y / c])
            }
        }
        2 if rows.iter().all(|(t, _)| coef(t, dofs[0]) == 1.0) => {
            let ((t1, y1), (t2, y2)) = (rows[0], rows[1]);
            let (c1, c2) = (coef(&t1, dofs[1]), coef(&t2, dofs[1]));
            let span = c2 - c1;
            if span == 0.0 {
                return None;
            }
            let beta = (y2 - y1) / span;
            let (w1, w2) = (c2 / span, -c1 / span);
            Some(vec![w1 * y1 + w2 * y2, beta])
        }
        n => {
            let a: Vec<Vec<f64>> = rows
                .iter()
                .map(|(t, _)| dofs.iter().map(|&d| coef(t, d)).collect())
                .collect();
            let b: Vec<f64> = rows.iter().map(|r| r.1).collect();
            if a.len() != n {
                return None;
            }
            solve_small(&a, &b)
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The condensed support operator of the module doc.
struct Operator<'a> {
    beam: &'a ModalBeam,
    dst: SineTransform,
    k_top: f64,
    k_w: f64,
    upper: Vec<f64>,
    inv_pivot: Vec<f64>,
    scaled: Vec<f64>,
    grid: Vec<f64>,
    last: Vec<f64>,
    force: Vec<f64>,
    modal: Vec<f64>,
}

/// `k_top`: the links above the last level in series, folded pairwise `a b / (a + b)`.
fn series(s: &ModelSupports) -> f64 {
    let mut k = s.levels[0].k;
    for l in &s.levels[1..] {
        k = k * l.k / (k + l.k);
    }
    k
}

impl<'a> Operator<'a> {
    fn new(beam: &'a ModalBeam, s: &ModelSupports) -> Self {
        let n = s.count;
        let k_top = series(s);
        let k_w = s.levels.last().and_then(|l| l.shear).map_or(0.0, |sh| sh.0);
        let diag = k_top + s.ground.0 + 2.0 * k_w;
        let (mut upper, mut inv_pivot) = (vec![0.0; n], vec![0.0; n]);
        // Forward elimination of the constant tridiagonal [-k_w, diag, -k_w]: strictly
        // diagonally dominant (k_top + k_g > 0), so every pivot is positive.
        let mut prev_upper = 0.0;
        for j in 0..n {
            let pivot = diag + k_w * prev_upper;
            inv_pivot[j] = 1.0 / pivot;
            upper[j] = -k_w * inv_pivot[j];
            prev_upper = upper[j];
        }
        Self {
            beam,
            dst: SineTransform::new(n),
            k_top,
            k_w,
            upper,
            inv_pivot,
            scaled: vec![0.0; beam.modes()],
            grid: vec![0.0; n],
            last: vec![0.0; n],
            force: vec![0.0; n],
            modal: vec![0.0; beam.modes()],
        }
    }

    /// Beam deflection on the support grid (`grid[0] = 0`, the end node) and the last level
    /// under it, for modal coordinates `q`.
    fn deflect(&mut self, q: &[f64]) {
        let scale = self.beam.shape_scale;
        for (s, q) in self.scaled.iter_mut().zip(q) {
            *s = scale * q;
        }
        self.grid[0] = 0.0;
        self.dst.apply(&self.scaled, &mut self.grid[1..]);
        let mut prev = 0.0;
        for j in 0..self.grid.len() {
            let rhs = self.k_top * self.grid[j] + self.k_w * prev;
            self.last[j] = rhs * self.inv_pivot[j];
            prev = self.last[j];
        }
        for j in (0..self.grid.len() - 1).rev() {
            self.last[j] -= self.upper[j] * self.last[j + 1];
        }
    }

    /// `out = K q`: modal stiffness plus the support reactions.
    fn apply(&mut self, q: &[f64], out: &mut [f64]) {
        self.deflect(q);
        for ((f, z), b) in self.force.iter_mut().zip(&self.grid).zip(&self.last) {
            *f = self.k_top * (z - b);
        }
        self.dst.apply(&self.force[1..], &mut self.modal);
        let scale = self.beam.shape_scale;
        for (((o, q), w2), m) in out
            .iter_mut()
            .zip(q)
            .zip(&self.beam.omega2)
            .zip(&self.modal)
        {
            *o = w2 * q + scale * m;
        }
    }
}

/// The static state of a beam on uniform supports under modal loads `b`: modal coordinates and
/// every level's displacements (level-major).
pub(crate) fn supported_deflection(
    beam: &ModalBeam,
    s: &ModelSupports,
    b: &[f64],
) -> Result<(Vec<f64>, Vec<f64>)> {
    let nm = beam.modes();
    let mut op = Operator::new(beam, s);
    let n_f = s.count as f64;
    let scale2 = beam.shape_scale * beam.shape_scale;
    let (k_top, k_g, k_w) = (op.k_top, s.ground.0, op.k_w);
    let inv_precond: Vec<f64> = (1..=nm)
        .zip(&beam.omega2)
        .map(|(k, w2)| {
            let lambda = 2.0 - 2.0 * (PI * k as f64 / n_f).cos();
            let sk = k_top - k_top * k_top / (k_top + k_g + k_w * lambda);
            1.0 / (w2 + 0.5 * n_f * scale2 * sk)
        })
        .collect();
    let b_norm = dot(b, b).sqrt();
    let mut q = vec![0.0; nm];
    if b_norm > 0.0 {
        let mut r = b.to_vec();
        let mut z: Vec<f64> = r.iter().zip(&inv_precond).map(|(r, m)| r * m).collect();
        let mut p = z.clone();
        let mut kp = vec![0.0; nm];
        let mut rz = dot(&r, &z);
        let mut residual = 1.0;
        let (mut iterations, mut best, mut best_at) = (0, f64::INFINITY, 0);
        while residual > TOLERANCE && iterations < MAX_ITERATIONS && iterations - best_at < STALL {
            op.apply(&p, &mut kp);
            let alpha = rz / dot(&p, &kp);
            for ((q, r), (p, kp)) in q.iter_mut().zip(r.iter_mut()).zip(p.iter().zip(&kp)) {
                *q += alpha * p;
                *r -= alpha * kp;
            }
            iterations += 1;
            // The true residual, not the recurrence's (which drifts below round-off).
            op.apply(&q, &mut kp);
            let true_r: f64 = b
                .iter()
                .zip(&kp)
                .map(|(b, k)| (b - k) * (b - k))
                .sum::<f64>()
                .sqrt();
            residual = true_r / b_norm;
            if residual < best {
                (best, best_at) = (residual, iterations);
            }
            for ((z, r), m) in z.iter_mut().zip(&r).zip(&inv_precond) {
                *z = r * m;
            }
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for (p, z) in p.iter_mut().zip(&z) {
                *p = z + beta * *p;
            }
        }
        if residual.is_nan() || residual > ACCEPT {
            return Err(Error::NoConvergence {
                what: "static deflection of a supported beam (conjugate gradients)".to_owned(),
                iterations,
                residual,
            });
        }
    }
    op.deflect(&q);
    let n = s.count;
    let levels = s.levels.len();
    let mut out = vec![0.0; levels * n];
    out[(levels - 1) * n..].copy_from_slice(&op.last);
    match levels {
        1 => {}
        2 => {
            // The one intermediate level between the beam and the last: a weighted mean.
            let (k0, k1) = (s.levels[0].k, s.levels[1].k);
            let sum = k0 + k1;
            for ((o, z), b) in out[..n].iter_mut().zip(&op.grid).zip(&op.last) {
                *o = (k0 * z + k1 * b) / sum;
            }
        }
        _ => {
            for j in 0..n {
                let f = op.k_top * (op.grid[j] - op.last[j]);
                let mut above = op.grid[j];
                for l in 0..levels - 1 {
                    above -= f / s.levels[l].k;
                    out[l * n + j] = above;
                }
            }
        }
    }
    Ok((q, out))
}

/// Each beam's static response to a unit force at each of the `loaded` points (at `px`), as a
/// whole state (zero outside that beam's modes and supports), in `loaded` order.
fn unit_responses(engine: &Engine, loaded: &[usize], px: &[f64]) -> Result<Vec<Vec<f64>>> {
    let m = &engine.model;
    let len = engine.layout.len;
    let mut units: Vec<Vec<f64>> = Vec::with_capacity(loaded.len());
    for &p in loaded {
        let b = m.points[p].0.expect("a point on a beam");
        let lay = &engine.layout.beams[b];
        // A beam with the same modes and points as an earlier one (the other rail) has the
        // same response to its k-th point: moved into this beam's part of the state.
        let k = engine.beams[b]
            .points
            .iter()
            .position(|&o| o == p)
            .expect("its point");
        let earlier = engine.beams[b].shares.and_then(|b0| {
            let p0 = engine.beams[b0].points[k];
            let j = loaded.iter().position(|&l| l == p0)?;
            let l0 = &engine.layout.beams[b0];
            let mut u = vec![0.0; len];
            u[lay.modes.clone()].copy_from_slice(&units[j][l0.modes.clone()]);
            u[lay.supports.clone()].copy_from_slice(&units[j][l0.supports.clone()]);
            Some(u)
        });
        if let Some(u) = earlier {
            units.push(u);
            continue;
        }
        let mut unit_force = vec![0.0; m.points.len()];
        unit_force[p] = 1.0;
        let (q, levels) = beam_static(engine, b, px, &unit_force)?;
        let mut u = vec![0.0; len];
        u[lay.modes.clone()].copy_from_slice(&q);
        u[lay.supports.clone()].copy_from_slice(&levels);
        units.push(u);
    }
    Ok(units)
}

/// The condensed route, for a rigid part that is not statically determinate on beams whose
/// statics are linear (no supports, or uniform ones): each beam's static response to a unit
/// force at each of its points (`U_j`, the state of [`beam_static`]) makes the beams' state
/// the superposition `sum_j F_j U_j` of the point forces `F`; Newton's method (central
/// differences, dense LU, backtracking) then solves the rigid DOFs `q` and the point forces
/// together, `M A_rigid(q, F) = 0` and `F = (the elements' net force at each point)`, a few
/// dozen unknowns instead of the whole state.
fn condensed(engine: &Engine) -> Result<Vec<f64>> {
    let m = &engine.model;
    let c = &engine.config;
    let (len, n_r) = (engine.layout.len, engine.layout.rigid);
    let px: Vec<f64> = m.points.iter().map(|(_, o)| c.x0 + o).collect();
    let loaded: Vec<usize> = (0..m.points.len())
        .filter(|&p| m.points[p].0.is_some())
        .collect();
    let units = unit_responses(engine, &loaded, &px)?;
    // Compliance: the deflection under loaded point i of unit response j.
    let compliance: Vec<Vec<f64>> = loaded
        .iter()
        .map(|&p| {
            units
                .iter()
                .map(|u| point_deflection(engine, u, p, px[p]))
                .collect()
        })
        .collect();
    let n = n_r + loaded.len();
    let state = |z: &[f64]| -> Vec<f64> {
        let mut x = vec![0.0; len];
        x[..n_r].copy_from_slice(&z[..n_r]);
        for (u, f) in units.iter().zip(&z[n_r..]) {
            for (xi, ui) in x[n_r..].iter_mut().zip(&u[n_r..]) {
                *xi += f * ui;
            }
        }
        x
    };
    // The rigid part alone: the beams enter through their deflections under the points.
    let scratch = std::cell::RefCell::new((
        crate::engine::Quantities::with_wheels(
            m.elements.len(),
            m.points.len(),
            !engine.wheels.is_empty(),
        ),
        vec![0.0; n_r],
    ));
    let zero = vec![0.0; n_r];
    let residual = |z: &[f64]| -> Vec<f64> {
        let mut guard = scratch.borrow_mut();
        let (q, a) = &mut *guard;
        q.point_x.copy_from_slice(&px);
        q.point_w.fill(0.0);
        q.point_rate.fill(0.0);
        for (i, &p) in loaded.iter().enumerate() {
            q.point_w[p] = compliance[i]
                .iter()
                .zip(&z[n_r..])
                .map(|(c, f)| c * f)
                .sum();
        }
        engine.rigid_part(q, 0.0, &z[..n_r], &zero, a);
        let mut r: Vec<f64> = (0..n_r).map(|i| a[i] * m.dof_mass[i]).collect();
        r.extend(
            loaded
                .iter()
                .zip(&z[n_r..])
                .map(|(&p, f)| q.point_force[p] - f),
        );
        r
    };
    let scale = m.loads.iter().map(|l| l.force.abs()).sum::<f64>().max(1.0);
    let z = wheelsets_loaded(engine, &loaded, &compliance, &px).unwrap_or_else(|| {
        let mut z = closed_contacts(engine)[..n_r].to_vec();
        z.extend(vec![0.0; loaded.len()]);
        // Start from the point forces of the rigid start on undeflected beams.
        let r0 = residual(&z);
        for (k, zf) in z[n_r..].iter_mut().enumerate() {
            *zf = r0[n_r + k];
        }
        z
    });
    let typical = |j: usize| if j < n_r { 1e-6 } else { 1.0 };
    let z = staged_newton(
        &residual,
        z,
        &typical,
        scale,
        "static equilibrium (Newton, condensed route)",
        &wheel_lateral(engine),
    )?;
    debug_assert_eq!(z.len(), n);
    Ok(state(&z))
}

/// The unknowns a wheel holds laterally: each wheelset's `y`, yaw (and `x`) and the lateral
/// rail under each wheel, sorted (empty without wheels).
fn wheel_lateral(engine: &Engine) -> Vec<usize> {
    let mut held: Vec<usize> = engine
        .wheels
        .iter()
        .flatten()
        .flat_map(|w| [Some(w.y), Some(w.yaw), w.x, w.rail])
        .flatten()
        .collect();
    held.sort_unstable();
    held.dedup();
    held
}

/// Newton's method in two stages for a system with wheelsets (one, [`newton`], without):
/// first with the unknowns `held` fixed at their values in `z` (their rows left out), then on
/// every unknown from there (see the module doc, "Wheelsets at rest").
fn staged_newton(
    residual: &dyn Fn(&[f64]) -> Vec<f64>,
    z: Vec<f64>,
    typical: &dyn Fn(usize) -> f64,
    scale: f64,
    what: &str,
    held: &[usize],
) -> Result<Vec<f64>> {
    if held.is_empty() {
        return newton(residual, z, typical, scale, what);
    }
    let free: Vec<usize> = (0..z.len())
        .filter(|i| held.binary_search(i).is_err())
        .collect();
    let full = |s: &[f64]| -> Vec<f64> {
        let mut x = z.clone();
        for (&i, v) in free.iter().zip(s) {
            x[i] = *v;
        }
        x
    };
    let sub = |s: &[f64]| -> Vec<f64> {
        let r = residual(&full(s));
        free.iter().map(|&i| r[i]).collect()
    };
    let start = free.iter().map(|&i| z[i]).collect();
    let held_what = format!("{what}, wheelsets held laterally");
    let s = newton(&sub, start, &|j| typical(free[j]), scale, &held_what)?;
    newton(residual, full(&s), typical, scale, what)
}

/// Newton's method on `residual(z) = 0` from `z`, the Jacobian by central differences with
/// steps `1e-7 max(|z_j|, typical(j))`, a dense LU solve and backtracking on `|residual|`;
/// converged at `|residual| <= 1e-12 scale`.
fn newton(
    residual: &dyn Fn(&[f64]) -> Vec<f64>,
    mut z: Vec<f64>,
    typical: &dyn Fn(usize) -> f64,
    scale: f64,
    what: &str,
) -> Result<Vec<f64>> {
    let n = z.len();
    let norm = |r: &[f64]| dot(r, r).sqrt();
    let mut r = residual(&z);
    for _ in 0..NEWTON_ITERATIONS {
        if norm(&r) <= 1e-12 * scale {
            return Ok(z);
        }
        let mut jac = nalgebra::DMatrix::<f64>::zeros(n, n);
        for j in 0..n {
            let h = 1e-7 * z[j].abs().max(typical(j));
            let mut zp = z.clone();
            zp[j] += h;
            let rp = residual(&zp);
            zp[j] = z[j] - h;
            let rm = residual(&zp);
            for i in 0..n {
                jac[(i, j)] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        let rhs = nalgebra::DVector::from_iterator(n, r.iter().map(|v| -v));
        let step = jac.lu().solve(&rhs).ok_or_else(|| Error::Statics {
            what: format!("the static problem is singular ({what}; a DOF no element restrains?)"),
        })?;
        let r0 = norm(&r);
        let mut lambda = 1.0;
        loop {
            let trial: Vec<f64> = z
                .iter()
                .zip(step.iter())
                .map(|(x, s)| x + lambda * s)
                .collect();
            let rt = residual(&trial);
            if norm(&rt) < r0 || lambda < 1e-6 {
                z = trial;
                r = rt;
                break;
            }
            lambda *= 0.5;
        }
    }
    if norm(&r) <= 1e-9 * scale {
        return Ok(z);
    }
    Err(Error::NoConvergence {
        what: what.to_owned(),
        iterations: NEWTON_ITERATIONS,
        residual: norm(&r) / scale,
    })
}

/// The general route: Newton on `A(X) = 0` (velocities zero, `t = 0`) with a central-difference
/// Jacobian and backtracking on `|M A|`.
fn general(engine: &Engine) -> Result<Vec<f64>> {
    let n = engine.layout.len;
    let zero = vec![0.0; n];
    // Residual in force units (rigid DOFs scaled by their masses; modal and support DOFs by
    // their unit or level masses).
    let masses = state_masses(engine);
    let residual = |x: &[f64]| -> Vec<f64> {
        let (a, _) = engine.evaluate(0.0, x, &zero);
        a.iter().zip(&masses).map(|(a, m)| a * m).collect()
    };
    let scale = engine
        .model
        .loads
        .iter()
        .map(|l| l.force.abs())
        .sum::<f64>()
        .max(1.0);
    staged_newton(
        &residual,
        closed_contacts(engine),
        &|_| 1e-7,
        scale,
        "static equilibrium (Newton, general route)",
        &wheel_lateral(engine),
    )
}

/// Newton's starting point: zero, except that the upper body of every contact sits on the
/// profile under it, pressed by the deflection of a 1 N contact force. An open contact has no
/// stiffness (from the zero state a dip in the profile lifts its wheel), which makes the
/// Jacobian singular; a contact law is convex, so from the closed side the iterates stay
/// closed.
fn closed_contacts(engine: &Engine) -> Vec<f64> {
    let m = &engine.model;
    let c = &engine.config;
    let mut x = vec![0.0; engine.layout.len];
    let ramp = c.ramp(0.0);
    for el in &m.elements {
        let (true, ModelEnd::Body(t)) = (el.law.is_contact(), el.from) else {
            continue;
        };
        let Some(z) = t.z else { continue };
        let eta = match (el.profile, el.to) {
            (Some(p), ModelEnd::Moving(pt)) if ramp > 0.0 => {
                ramp * engine.profiles[p].at(c.x0 + m.points[pt].1)
            }
            _ => 0.0,
        };
        let closed = eta + el.law.static_deflection(1.0).unwrap_or(0.0);
        x[z] = if x[z] == 0.0 {
            closed
        } else {
            x[z].max(closed)
        };
    }
    x
}

/// A wheelset body's DOFs and, per wheel, its roll coefficient and the height its contact
/// point must reach (m).
struct WheelsetStart {
    z: usize,
    roll: Option<usize>,
    wheels: Vec<(f64, f64)>,
}

/// Newton's start of the condensed route for a vehicle on wheelsets: every wheel carries the
/// mean wheel load `W` of the vertical balance ([`contact_scale`]), the rails deflect under
/// those loads (`compliance`, per loaded point) and each wheelset's vertical position and roll
/// put both its wheels at the Hertz deflection of `W` on the rails' deflected, irregular
/// heads; the bodies above start at zero (their suspensions' preloads carry them there). `None`
/// without wheelsets or without a mean load, or when a loaded point is not a wheel's.
///
/// From the 1 N start of [`closed_contacts`] a wheelset's first Newton step rests on the
/// tangent of a 1 N Hertz contact (`dQ/dd ~ Q^(1/3)`, about 1/40 of the loaded one): it
/// overshoots to point forces of 1e6 N, the rails' deflection under those opens every contact
/// and the Jacobian is singular (8 % of the vehicle in space's parameter box). From here the
/// iterates start within a fraction of a millimetre of the solution.
fn wheelsets_loaded(
    engine: &Engine,
    loaded: &[usize],
    compliance: &[Vec<f64>],
    px: &[f64],
) -> Option<Vec<f64>> {
    if engine.wheels.is_empty() {
        return None;
    }
    let m = &engine.model;
    let press = contact_scale(&engine.system, m)?;
    let n_r = engine.layout.rigid;
    let ramp = engine.config.ramp(0.0);
    // Each loaded point's rail deflection under `press` at every loaded point.
    let w: Vec<f64> = compliance
        .iter()
        .map(|row| row.iter().map(|c| c * press).sum())
        .collect();
    // Per wheelset body (its `z`), the wheels' roll coefficients and the heights they must
    // reach: `z + c phi = eta + w + delta(press)` (the rolling-radius change is 0 at `u = 0`).
    let mut bodies: Vec<WheelsetStart> = Vec::new();
    for (el, wheel) in m.elements.iter().zip(&engine.wheels) {
        let (Some(_), ModelEnd::Body(t), ModelEnd::Moving(pt)) = (wheel, el.from, el.to) else {
            continue;
        };
        let i = loaded.iter().position(|&p| p == pt)?;
        let eta = match el.profile {
            Some(p) if ramp > 0.0 => ramp * engine.profiles[p].at(px[pt]),
            _ => 0.0,
        };
        let height = eta + w[i] + el.law.static_deflection(press)?;
        let (z, roll) = (t.z?, t.roll);
        let c = roll.map_or(0.0, |(_, c)| c);
        match bodies.iter_mut().find(|b| b.z == z) {
            Some(b) => b.wheels.push((c, height)),
            None => bodies.push(WheelsetStart {
                z,
                roll: roll.map(|(r, _)| r),
                wheels: vec![(c, height)],
            }),
        }
    }
    if bodies.iter().map(|b| b.wheels.len()).sum::<usize>() != loaded.len() {
        return None;
    }
    let mut z = vec![0.0; n_r];
    for b in bodies {
        match (b.roll, b.wheels.as_slice()) {
            (Some(r), &[(c1, h1), (c2, h2)]) if c1 != c2 => {
                let phi = (h1 - h2) / (c1 - c2);
                z[r] = phi;
                z[b.z] = h1 - c1 * phi;
            }
            (_, wheels) => z[b.z] = wheels.iter().map(|w| w.1).fold(f64::MIN, f64::max),
        }
    }
    z.extend(std::iter::repeat_n(press, loaded.len()));
    Some(z)
}

/// The diagonal of the mass matrix in state order.
pub fn state_masses(engine: &Engine) -> Vec<f64> {
    let mut m = vec![1.0; engine.layout.len];
    m[..engine.layout.rigid].copy_from_slice(&engine.model.dof_mass);
    for (b, beam) in engine.model.beams.iter().enumerate() {
        if let Some(s) = &beam.supports {
            let r = engine.layout.beams[b].supports.clone();
            for (l, level) in s.levels.iter().enumerate() {
                let start = r.start + l * s.count;
                m[start..start + s.count].fill(level.mass);
            }
        }
    }
    m
}

/// The force scale of a sample for learning (N): the mean static force of the elements that
/// rest on moving points (contacts with the track, road or deck: the wheel load `W` of every
/// wheel of the vehicle-track model), summed with compensation so that equal forces give
/// exactly their value. Where the rigid part is not statically determinate (a vehicle in space:
/// four wheelsets on eight wheels), the mean of the wheels' normal forces still is: the vertical
/// balance of the bodies. `None` when no element rests on a moving point, or the rigid part is
/// indeterminate and another element carries vertical load to the ground.
pub fn contact_scale(system: &System, model: &Model) -> Option<f64> {
    let Some(sf) = static_forces(system, model) else {
        return vertical_contact_mean(system, model);
    };
    let forces: Vec<f64> = model
        .elements
        .iter()
        .enumerate()
        .filter(|(_, e)| matches!(e.to, ModelEnd::Moving(_)))
        .map(|(i, _)| sf.force[i])
        .collect();
    if forces.is_empty() {
        return None;
    }
    // Neumaier's compensated sum.
    let (mut sum, mut c) = (0.0f64, 0.0f64);
    for &f in &forces {
        let t = sum + f;
        c += if sum.abs() >= f.abs() {
            (sum - t) + f
        } else {
            (f - t) + sum
        };
        sum = t;
    }
    Some((sum + c) / forces.len() as f64)
}

/// The mean static normal force of the wheels (N) by the vertical balance of all bodies: the
/// downward loads on the bodies' vertical DOFs (`z` positive down) summed, over the number of
/// wheel and Hertz contacts resting on moving points. Exact when those contacts are the only
/// elements that carry vertical force from a body to the ground or a moving point (the
/// lateral rails' fastenings, on bodies without a vertical DOF, carry none); `None` otherwise.
fn vertical_contact_mean(system: &System, model: &Model) -> Option<f64> {
    let vertical: Vec<bool> = system
        .dofs
        .iter()
        .map(|d| d.kind == mbd_system::schema::DofKind::Z)
        .collect();
    let on_vertical = |end: &ModelEnd| match end {
        ModelEnd::Body(t) => t.z.is_some_and(|i| vertical[i]),
        _ => false,
    };
    let mut contacts = 0usize;
    for e in &model.elements {
        let contact = matches!(
            e.law,
            mbd_system::model::ModelLaw::Wheel(_) | mbd_system::model::ModelLaw::Hertz { .. }
        ) && matches!(e.to, ModelEnd::Moving(_));
        if contact {
            contacts += 1;
        } else if on_vertical(&e.from) != on_vertical(&e.to)
            && (!matches!(e.from, ModelEnd::Body(_)) || !matches!(e.to, ModelEnd::Body(_)))
        {
            // A body's vertical DOF tied to the ground or a moving point by another element.
            return None;
        }
    }
    if contacts == 0 {
        return None;
    }
    let total: f64 = model
        .loads
        .iter()
        .filter(|l| on_vertical(&l.at))
        .map(|l| l.force)
        .sum();
    Some(total / contacts as f64)
}
