//! ODE residuals of the rigid DOFs for learning: `R_i = m_i a_i - F_i`, with `F_i` the
//! generalised force of DOF `i` computed by the engine's own element code
//! ([`crate::engine`]: the same deflections, laws and coefficient groups the time loop
//! integrates with). `R_i` (N, or N m for a pitch) vanishes on the exact solution.
//!
//! The residual reads what a learner predicts or is given: every rigid DOF's displacement,
//! velocity and acceleration, the deflection of the beam under each moving point an element
//! rests on (and its rate along the path, where a damper needs it), and the profile under each
//! element (and its rate). A DOF *has an equation* when every element acting on it has both
//! ends among those quantities ([`mbd_system::System::equation_dofs`]).
//!
//! For a gradient the residual is split into its linear part and its nonlinear elements
//! (Hertz contacts, tables): [`Equations::residuals_with`] takes the nonlinear elements' forces
//! as given, which makes the residual linear in the state and those forces (so a Jacobian by
//! unit vectors is exact), and [`Equations::deflection_terms`] gives each nonlinear element's
//! deflection as a linear combination of the state.

use crate::assembly::Assembly;
use crate::engine::{element_forces, Quantities};
use mbd_system::model::{Model, ModelEnd, ModelLaw};

/// One sample's equations of motion of the DOFs that have them.
#[derive(Debug, Clone)]
pub struct Equations {
    model: Model,
    assembly: Assembly,
    needs_rate: Vec<bool>,
    dofs: Vec<usize>,
    nonlinear: Vec<usize>,
}

/// The state the residual reads (physical units), each slice in its natural order.
#[derive(Debug, Clone, Copy)]
pub struct EquationState<'a> {
    /// Rigid DOF displacements (m, rad), every DOF.
    pub z: &'a [f64],
    /// Their velocities.
    pub v: &'a [f64],
    /// Their accelerations.
    pub a: &'a [f64],
    /// Beam deflection under each moving point (m; 0 where unknown or on the ground).
    pub point_w: &'a [f64],
    /// Its rate along the path (m/s).
    pub point_rate: &'a [f64],
    /// Profile under each element (m; 0 without one).
    pub eta: &'a [f64],
    /// Its rate (m/s).
    pub eta_rate: &'a [f64],
}

/// Scratch space of [`Equations::residuals`].
#[derive(Debug, Clone)]
pub struct Scratch {
    q: Quantities,
    total: Vec<f64>,
}

/// Where a deflection term comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateEntry {
    /// Rigid DOF displacement `i`.
    Dof(usize),
    /// Beam deflection under moving point `i`.
    Point(usize),
    /// The profile under element `i`.
    Eta(usize),
}

impl Equations {
    /// The equations of DOFs `dofs` (indices into the system's DOFs) of one sample's model.
    pub fn new(model: Model, dofs: Vec<usize>) -> Self {
        let needs_rate = model
            .elements
            .iter()
            .map(|e| e.law.damping() != 0.0)
            .collect();
        let nonlinear = (0..model.elements.len())
            .filter(|&e| !matches!(model.elements[e].law, ModelLaw::SpringDamper { .. }))
            .collect();
        Self {
            assembly: Assembly::of(&model),
            model,
            needs_rate,
            dofs,
            nonlinear,
        }
    }

    /// The DOFs with equations, in order.
    pub fn dofs(&self) -> &[usize] {
        &self.dofs
    }

    /// Elements with a nonlinear law (Hertz, table), in order.
    pub fn nonlinear(&self) -> &[usize] {
        &self.nonlinear
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Whether element `e` reads rates (a damper).
    pub fn needs_rate(&self, e: usize) -> bool {
        self.needs_rate[e]
    }

    /// Scratch for [`Equations::residuals`].
    pub fn scratch(&self) -> Scratch {
        let (n_e, n_p) = (self.model.elements.len(), self.model.points.len());
        Scratch {
            q: Quantities::zeros(n_e, n_p),
            total: vec![0.0; self.model.dof_mass.len()],
        }
    }

    fn load(&self, s: &EquationState, scratch: &mut Scratch) {
        let q = &mut scratch.q;
        q.point_w.copy_from_slice(s.point_w);
        q.point_rate.copy_from_slice(s.point_rate);
        q.eta.copy_from_slice(s.eta);
        q.eta_rate.copy_from_slice(s.eta_rate);
        // A wheel's tangential forces are left out: the DOFs a wheel acts on have no equation
        // (`System::equation_dofs`), and its vertical load reaches only those.
        element_forces(&self.model, &self.needs_rate, &[], s.z, s.v, q);
    }

    fn finish(&self, s: &EquationState, scratch: &mut Scratch, out: &mut [f64]) {
        self.assembly.forces(&scratch.q.force, &mut scratch.total);
        for (o, &i) in out.iter_mut().zip(&self.dofs) {
            *o = self.model.dof_mass[i] * s.a[i] - scratch.total[i];
        }
    }

    /// `R_i = m_i a_i - F_i` of every DOF with an equation (N, N m), into `out`.
    pub fn residuals(&self, s: &EquationState, scratch: &mut Scratch, out: &mut [f64]) {
        self.load(s, scratch);
        self.finish(s, scratch, out);
    }

    /// As [`Equations::residuals`] with the nonlinear elements' forces given
    /// (`forces[j]` for element `nonlinear()[j]`): linear in the state and in those forces.
    pub fn residuals_with(
        &self,
        s: &EquationState,
        forces: &[f64],
        scratch: &mut Scratch,
        out: &mut [f64],
    ) {
        self.load(s, scratch);
        for (&e, &f) in self.nonlinear.iter().zip(forces) {
            scratch.q.force[e] = f;
        }
        self.finish(s, scratch, out);
    }

    /// Force and deflection of nonlinear element `e` in the last evaluation.
    pub fn element(&self, scratch: &Scratch, e: usize) -> (f64, f64) {
        (scratch.q.force[e], scratch.q.deflection[e])
    }

    /// The law of element `e`.
    pub fn law(&self, e: usize) -> &ModelLaw {
        &self.model.elements[e].law
    }

    /// Element `e`'s deflection `d = (u_from - u_to) - eta` as `sum coef * entry`.
    pub fn deflection_terms(&self, e: usize) -> Vec<(StateEntry, f64)> {
        let el = &self.model.elements[e];
        let mut out = Vec::new();
        for (end, sign) in [(&el.from, 1.0), (&el.to, -1.0)] {
            match end {
                ModelEnd::Ground => {}
                ModelEnd::Body(t) => {
                    for (i, c) in t.terms() {
                        out.push((StateEntry::Dof(i), sign * c));
                    }
                }
                ModelEnd::Moving(p) => {
                    if self.model.points[*p].0.is_some() {
                        out.push((StateEntry::Point(*p), sign));
                    }
                }
            }
        }
        if el.profile.is_some() {
            out.push((StateEntry::Eta(e), -1.0));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "format: 1\nname: t\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n  k: {unit: N/m, value: 800}\n  c: {unit: N s/m, value: 3}\n  g: {unit: m/N^(2/3), value: 1e-4}\nbodies:\n  b: {mass: m, inertia: m, dofs: [z, pitch], points: {f: 1, r: -2}}\nelements:\n  s: {kind: spring_damper, from: b.f, to: ground, k: k, c: c}\n  h: {kind: hertz, from: b.r, to: ground, g: g}\nloads:\n  w: {at: b, force: 5}\n";

    /// By hand: d_s = z - beta (point at x = 1), d_h = z + 2 beta (x = -2); F_z = W - f_s - f_h,
    /// F_beta = -(1) (-f_s) ... written out: a point at x moves by z - x beta, so a force f
    /// pushing it up gives -f on z and x f on beta.
    #[test]
    fn residual_is_the_hand_computed_equation() {
        let s = mbd_system::load_str(TEXT, "t.yaml", &Default::default()).unwrap();
        let model = s.instantiate(&s.sampled_values([2.0]).unwrap()).unwrap();
        let eq = Equations::new(model, vec![0, 1]);
        let (z, beta, vz, vb, az, ab) = (1e-3, 2e-4, 0.01, -0.02, 3.0, -4.0);
        let state = EquationState {
            z: &[z, beta],
            v: &[vz, vb],
            a: &[az, ab],
            point_w: &[],
            point_rate: &[],
            eta: &[0.0, 0.0],
            eta_rate: &[0.0, 0.0],
        };
        let mut scratch = eq.scratch();
        let mut r = [0.0; 2];
        eq.residuals(&state, &mut scratch, &mut r);
        let f_s = 800.0 * (z - beta) + 3.0 * (vz - vb);
        let d_h: f64 = z + 2.0 * beta;
        let f_h = (d_h / 1e-4).powf(1.5);
        let want_z = 2.0 * az - (5.0 - f_s - f_h);
        let want_b = 2.0 * ab - (1.0 * f_s - 2.0 * f_h);
        assert!(
            (r[0] - want_z).abs() < 1e-9 * want_z.abs(),
            "{} vs {want_z}",
            r[0]
        );
        assert!(
            (r[1] - want_b).abs() < 1e-9 * want_b.abs(),
            "{} vs {want_b}",
            r[1]
        );
        // With the contact's force given, the residual is linear in it.
        eq.residuals_with(&state, &[f_h + 10.0], &mut scratch, &mut r);
        assert!((r[0] - (want_z + 10.0)).abs() < 1e-9 * want_z.abs());
        assert_eq!(
            eq.deflection_terms(1),
            [(StateEntry::Dof(0), 1.0), (StateEntry::Dof(1), 2.0)]
        );
    }
}
