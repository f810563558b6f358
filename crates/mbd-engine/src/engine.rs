//! One sample's described system, assembled and ready to integrate.
//!
//! **State.** Displacements `X`, velocities `V`, accelerations `A`, each laid out as
//! ```text
//! [ rigid DOFs (System::dofs order) | beam 0: modes q_1..q_N | beam 0 supports: level 0 (N_s),
//!   level 1 (N_s), ... | beam 1 ... ]
//! ```
//! (m, rad; sqrt(kg) m for mass-normalised modal coordinates). The mass matrix is diagonal
//! (lumped bodies, unit modal masses), so `A = M^-1 F(X, V, t)` is explicit.
//!
//! **Forces at time t.** Moving point `i` is at `x_i(t) = (x0 + v t) + offset_i`; on a beam the
//! deflection under it is `w(x_i) = sum_k Y_k(x_i) q_k` (and, when a damper needs it, its total
//! rate `w_t + v w_x`); on the ground it is 0. An element reads the profile under its lower end,
//! `eta = r(t) profile(x)`, has the deflection `d = (u_from - u_to) - eta` (compression
//! positive) and the force of its law; it pushes its upper end up and its lower end down. The
//! rigid DOFs receive their generalised forces group by group ([`mbd_system::system::Group`]);
//! each moving point's net force loads its beam, `sum_i F_i Y_k(x_i)`; the supports couple
//! through [`crate::supports`], by sine transforms on the fast path.
//!
//! **Routes.** Uniform supports starting at `x = 0` and filling the beam (`N_s s = L`, fewer
//! modes than supports) take the fast path: the seat terms and modal loads are two sine
//! transforms ([`crate::dst`]). Anything else, or [`Route::General`] on request, takes the
//! general route: dense products with the mode shapes at the supports. Both are tested equal.
//!
//! **Outputs.** Every `output_every` steps (including `t = 0`) one row of the stored channels
//! ([`mbd_system::system::System::channels`]); accelerations are evaluated at the stored state,
//! so stored rows satisfy the equations of motion to round-off.
//!
//! **Failure.** A non-finite element force or rigid acceleration (checked every step) or state
//! (every output step) ends the sample with a [`Failure`] naming what and when.

use crate::assembly::Assembly;
use crate::beam::{ModalBeam, LANES};
use crate::config::RunConfig;
use crate::coverage::check_coverage;
use crate::dst::SineTransform;
use crate::integrator;
use crate::profile::{Profile, ProfileSource};
use crate::reads::{Evaluation, ProfileReads};
use crate::wheel::{Wheel, WheelForces};
use crate::Result;
use mbd_system::model::{Model, ModelEnd, ModelProfile, ModelSupports};
use mbd_system::system::{Quantity, Source};
use mbd_system::System;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// How the beam-support coupling is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Route {
    /// Sine transforms where the structure allows, dense products elsewhere (the default).
    Fast,
    /// Dense products everywhere (the reference the fast path is tested against).
    General,
}

/// Where each part of the state lives.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Rigid DOFs `0..rigid`.
    pub rigid: usize,
    /// Per beam: its modes and its support levels.
    pub beams: Vec<BeamLayout>,
    /// Length of the state vectors.
    pub len: usize,
}

/// State ranges of one beam.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamLayout {
    /// Modal coordinates.
    pub modes: Range<usize>,
    /// All support levels (level-major), empty without supports.
    pub supports: Range<usize>,
}

/// How one beam couples to its supports.
#[derive(Debug, Clone)]
pub(crate) enum Coupling {
    /// No supports.
    None,
    /// Sine transforms of size `count`.
    Fast(ModelSupports),
    /// Dense: mode shapes at the supports, `shapes[j * modes + k] = Y_k(x_j)`.
    Dense(ModelSupports, Vec<f64>),
}

/// A beam at run time.
#[derive(Debug, Clone)]
pub(crate) struct BeamRuntime {
    pub(crate) modal: ModalBeam,
    /// Moving points on this beam, in declaration order.
    pub(crate) points: Vec<usize>,
    pub(crate) coupling: Coupling,
    /// Whether some element needs the rate of the deflection under a point.
    pub(crate) rates: bool,
    /// An earlier beam with the same modes and its points at the same offsets (two rails
    /// under one vehicle): the mode shapes under the points are that beam's, computed once.
    pub(crate) shares: Option<usize>,
}

/// Why a sample failed.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    /// Time of detection (s).
    pub t: f64,
    /// What was not finite.
    pub reason: String,
}

/// Quantities of one force evaluation besides the accelerations.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Quantities {
    /// Moving point positions (m).
    pub point_x: Vec<f64>,
    /// Deflection of the beam under each moving point (m; 0 on the ground).
    pub point_w: Vec<f64>,
    /// Its rate along the path (m/s), where needed.
    pub point_rate: Vec<f64>,
    /// Profile under each element (m; 0 without one).
    pub eta: Vec<f64>,
    /// Its rate (m/s).
    pub eta_rate: Vec<f64>,
    /// Element deflections (m).
    pub deflection: Vec<f64>,
    /// Element forces (N).
    pub force: Vec<f64>,
    /// Net downward force at each moving point (N).
    pub point_force: Vec<f64>,
    /// Each wheel's tangential forces (zero for other elements; empty without wheels).
    pub wheel: Vec<WheelForces>,
    /// The profile reads' level and slope of the last evaluation (scratch).
    pub(crate) reads: Vec<[f64; 2]>,
}

impl Quantities {
    /// Zeros for `elements` force elements and `points` moving points.
    pub fn zeros(elements: usize, points: usize) -> Self {
        Self {
            point_x: vec![0.0; points],
            point_w: vec![0.0; points],
            point_rate: vec![0.0; points],
            eta: vec![0.0; elements],
            eta_rate: vec![0.0; elements],
            deflection: vec![0.0; elements],
            force: vec![0.0; elements],
            point_force: vec![0.0; points],
            wheel: Vec::new(),
            reads: Vec::new(),
        }
    }

    /// As [`Quantities::zeros`], with room for the wheels' tangential forces when `wheels`.
    pub fn with_wheels(elements: usize, points: usize, wheels: bool) -> Self {
        let mut q = Self::zeros(elements, points);
        if wheels {
            q.wheel = vec![WheelForces::default(); elements];
        }
        q
    }
}

/// What an observer sees at each step.
#[derive(Debug)]
pub struct StepView<'a> {
    /// Step index.
    pub step: usize,
    /// Time (s).
    pub t: f64,
    /// Displacements.
    pub x: &'a [f64],
    /// Velocities.
    pub v: &'a [f64],
    /// Accelerations at `(x, v, t)`.
    pub a: &'a [f64],
    /// The quantities of that evaluation.
    pub q: &'a Quantities,
}

/// Scratch space of the force evaluation.
pub(crate) struct Workspace {
    pub(crate) q: Quantities,
    /// Per beam, per chunk of four points, the shapes `[mode][lane]`.
    shapes: Vec<Vec<Vec<[f64; LANES]>>>,
    /// One sine transform per support count, shared by the beams of that count (two rails):
    /// the tables and buffers of one size are read once per step, not once per beam.
    dst: Vec<SineTransform>,
    /// Per beam, the index of its transform in `dst` (fast path only).
    dst_of: Vec<Option<usize>>,
    /// Per beam, per chunk of four points, the points' net forces.
    lanes: Vec<Vec<[f64; LANES]>>,
    seat_in: Vec<f64>,
    seat: Vec<f64>,
    link: Vec<f64>,
    modal: Vec<f64>,
}

/// One sample's assembled system, ready to run. Built and checked by [`Engine::new`] (run
/// controls, coverage of beams and profiles, the time step against the stability bound).
#[derive(Debug, Clone)]
pub struct Engine {
    pub(crate) system: Arc<System>,
    pub(crate) model: Model,
    pub(crate) config: RunConfig,
    pub(crate) layout: Layout,
    pub(crate) beams: Vec<BeamRuntime>,
    pub(crate) profiles: Vec<ProfileSource>,
    /// Per moving point, the terms of its net force, in accumulation order.
    point_terms: Vec<Vec<(Source, f64)>>,
    /// Per element, whether its rates are needed (a damper).
    pub(crate) needs_rate: Vec<bool>,
    /// Sensor shapes.
    sensor_shapes: Vec<Vec<f64>>,
    pub(crate) route: Route,
    /// Per element, the wheel of a wheelset at run time (empty without wheels).
    pub(crate) wheels: Vec<Option<Wheel>>,
    /// The profiles under the elements, each part read once per position.
    reads: ProfileReads,
    /// The rigid DOFs' coefficient groups, compiled.
    assembly: Assembly,
}

fn fast_structure(beam: &mbd_system::model::ModelBeam, s: &ModelSupports) -> bool {
    s.first == 0.0
        && s.count as f64 * s.spacing == beam.length
        && beam.modes < s.count
        && s.count >= 2
}

impl Engine {
    /// As [`Engine::with_route`] without the time-step check (for bounds over many models).
    pub fn assemble(
        system: Arc<System>,
        model: Model,
        config: &RunConfig,
        profiles: Vec<Option<Profile>>,
        route: Route,
    ) -> Result<Self> {
        config.validate()?;
        let sources = profile_sources(&model, profiles)?;
        let needs_rate: Vec<bool> = model
            .elements
            .iter()
            .map(|e| e.law.damping() != 0.0)
            .collect();
        // Per element, whether its profile's rate is evaluated: its force reads it or it is
        // a stored column ([`mbd_system::system::Element::reads_profile_rate`]).
        let profile_rate: Vec<bool> = system
            .elements
            .iter()
            .zip(&needs_rate)
            .map(|(e, &needed)| needed || e.reads_profile_rate())
            .collect();
        let (layout, beams) = beam_layout(&model, &needs_rate, route);
        let point_terms = point_terms(&model);
        let wheels = run_wheels(&system, &model)?;
        let reads = ProfileReads::of(&model, &profile_rate);
        let assembly = Assembly::of(&model);
        let sensor_shapes = model
            .sensors
            .iter()
            .map(|&(b, x)| {
                let mut y = vec![0.0; model.beams[b].modes];
                beams[b].modal.shapes_at(x, &mut y);
                y
            })
            .collect();
        let engine = Self {
            system,
            model,
            config: *config,
            layout,
            beams,
            profiles: sources,
            point_terms,
            needs_rate,
            sensor_shapes,
            route,
            wheels,
            reads,
            assembly,
        };
        check_coverage(
            &engine.system,
            &engine.model,
            &engine.config,
            &engine.profiles,
        )?;
        Ok(engine)
    }

    /// The compiled system.
    pub fn system(&self) -> &System {
        &self.system
    }

    /// The sample's model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The run controls.
    pub fn config(&self) -> &RunConfig {
        &self.config
    }

    /// The state layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The route in use.
    pub fn route(&self) -> Route {
        self.route
    }

    /// Whether beam `b` couples to its supports by sine transforms.
    pub fn uses_fast_path(&self, b: usize) -> bool {
        matches!(self.beams[b].coupling, Coupling::Fast(_))
    }

    /// Modal data of beam `b`.
    pub fn beam(&self, b: usize) -> &ModalBeam {
        &self.beams[b].modal
    }

    /// The profile of index `p`.
    pub fn profile(&self, p: usize) -> &ProfileSource {
        &self.profiles[p]
    }

    pub(crate) fn workspace(&self) -> Workspace {
        let m = &self.model;
        let n_e = m.elements.len();
        let n_p = m.points.len();
        let max_count = m
            .beams
            .iter()
            .filter_map(|b| b.supports.as_ref())
            .map(|s| s.count * s.levels.len())
            .max()
            .unwrap_or(0);
        let max_modes = m.beams.iter().map(|b| b.modes).max().unwrap_or(0);
        let mut dst: Vec<SineTransform> = Vec::new();
        let dst_of = self
            .beams
            .iter()
            .map(|b| match &b.coupling {
                Coupling::Fast(s) => Some(
                    dst.iter()
                        .position(|t| t.len() == s.count)
                        .unwrap_or_else(|| {
                            dst.push(SineTransform::new(s.count));
                            dst.len() - 1
                        }),
                ),
                _ => None,
            })
            .collect();
        Workspace {
            q: Quantities::with_wheels(n_e, n_p, !self.wheels.is_empty()),
            shapes: self
                .beams
                .iter()
                .map(|b| vec![vec![[0.0; LANES]; b.modal.modes()]; b.points.len().div_ceil(LANES)])
                .collect(),
            lanes: self
                .beams
                .iter()
                .map(|b| vec![[0.0; LANES]; b.points.len().div_ceil(LANES)])
                .collect(),
            dst,
            dst_of,
            seat_in: vec![0.0; max_modes],
            seat: vec![0.0; max_count],
            link: vec![0.0; max_count],
            modal: vec![0.0; max_modes],
        }
    }

    /// The part of [`Engine::accelerations`] above the beams, given the points' positions,
    /// deflections and rates in `q`: the profiles under the elements, every element's force,
    /// the rigid DOFs' accelerations (into `a[..rigid]`) and each moving point's net force.
    #[inline]
    pub(crate) fn rigid_part(
        &self,
        q: &mut Quantities,
        t: f64,
        x: &[f64],
        v: &[f64],
        a: &mut [f64],
    ) {
        let m = &self.model;
        self.reads.evaluate(
            &self.profiles,
            Evaluation {
                point_x: &q.point_x,
                eta: &mut q.eta,
                eta_rate: &mut q.eta_rate,
                ramp: self.config.ramp(t),
                ramp_rate: self.config.ramp_rate(t),
                speed: m.speed,
            },
            &mut q.reads,
        );
        element_forces(m, &self.needs_rate, &self.wheels, x, v, q);
        self.assembly.forces(&q.force, a);
        wheel_forces(&self.wheels, q, a);
        for (ai, mass) in a[..m.dof_mass.len()].iter_mut().zip(&m.dof_mass) {
            *ai /= mass;
        }
        let value = |s: &Source, q: &Quantities| match *s {
            Source::Element(i) => q.force[i],
            Source::Load(i) => m.loads[i].force,
        };
        // Net point forces.
        for (p, terms) in self.point_terms.iter().enumerate() {
            let mut it = terms.iter();
            q.point_force[p] = match it.next() {
                None => 0.0,
                Some((s0, _)) => it.fold(value(s0, q), |acc, (s, _)| acc + value(s, q)),
            };
        }
    }

    /// `A = M^-1 F(X, V, t)`; the point and element quantities go to `ws.q`.
    pub(crate) fn accelerations(
        &self,
        ws: &mut Workspace,
        t: f64,
        x: &[f64],
        v: &[f64],
        a: &mut [f64],
    ) {
        let m = &self.model;
        let q = &mut ws.q;
        let origin = self.config.x0 + m.speed * t;
        for (px, (_, offset)) in q.point_x.iter_mut().zip(&m.points) {
            *px = origin + offset;
        }
        // Deflection under the moving points.
        for (b, beam) in self.beams.iter().enumerate() {
            let modes = self.layout.beams[b].modes.clone();
            let (qs, qd) = (&x[modes.clone()], &v[modes]);
            for (c, chunk) in beam.points.chunks(LANES).enumerate() {
                if let Some(other) = beam.shares {
                    let w = ModalBeam::lane_deflection(&ws.shapes[other][c], qs);
                    for (i, &p) in chunk.iter().enumerate() {
                        q.point_w[p] = w[i];
                    }
                    continue;
                }
                let xs: [f64; LANES] =
                    std::array::from_fn(|i| chunk.get(i).map_or(0.0, |&p| q.point_x[p]));
                let shapes = &mut ws.shapes[b][c];
                if beam.rates {
                    let (w, rate) =
                        beam.modal
                            .lane_shapes_moving(&xs, chunk.len(), m.speed, qs, qd, shapes);
                    for (i, &p) in chunk.iter().enumerate() {
                        q.point_w[p] = w[i];
                        q.point_rate[p] = rate[i];
                    }
                } else {
                    let w = beam.modal.lane_shapes(&xs, chunk.len(), qs, shapes);
                    for (i, &p) in chunk.iter().enumerate() {
                        q.point_w[p] = w[i];
                    }
                }
            }
        }
        self.rigid_part(q, t, x, v, a);
        // Beams.
        for (b, beam) in self.beams.iter().enumerate() {
            let lay = &self.layout.beams[b];
            let modes = lay.modes.clone();
            let scale = beam.modal.shape_scale;
            let nm = beam.modal.modes();
            let modal = &mut ws.modal[..nm];
            let mut has_modal = true;
            match &beam.coupling {
                Coupling::None => has_modal = false,
                Coupling::Fast(s) => {
                    let top = &s.levels[0];
                    let (k0, c0) = (top.k, top.c);
                    let seat_in = &mut ws.seat_in[..nm];
                    for ((si, qk), qdk) in seat_in
                        .iter_mut()
                        .zip(&x[modes.clone()])
                        .zip(&v[modes.clone()])
                    {
                        *si = scale * (k0 * qk + c0 * qdk);
                    }
                    let n = s.count;
                    let seat = &mut ws.seat[..n];
                    seat[0] = 0.0;
                    let dst = &mut ws.dst[ws.dst_of[b].expect("a transform per fast beam")];
                    dst.apply(seat_in, &mut seat[1..]);
                    let sup = lay.supports.clone();
                    let link = &mut ws.link[..sup.len()];
                    crate::supports::chain(
                        s,
                        seat,
                        &x[sup.clone()],
                        &v[sup.clone()],
                        &mut a[sup],
                        link,
                    );
                    dst.apply(&link[1..n], modal);
                }
                Coupling::Dense(s, shapes) => {
                    let top = &s.levels[0];
                    let (k0, c0) = (top.k, top.c);
                    let n = s.count;
                    let seat = &mut ws.seat[..n];
                    let (qs, qd) = (&x[modes.clone()], &v[modes.clone()]);
                    for (j, st) in seat.iter_mut().enumerate() {
                        let y = &shapes[j * nm..(j + 1) * nm];
                        let (w, wd) = y
                            .iter()
                            .zip(qs.iter().zip(qd))
                            .fold((0.0, 0.0), |(w, wd), (y, (q, qd))| (w + y * q, wd + y * qd));
                        *st = k0 * w + c0 * wd;
                    }
                    let sup = lay.supports.clone();
                    let link = &mut ws.link[..sup.len()];
                    crate::supports::chain(
                        s,
                        seat,
                        &x[sup.clone()],
                        &v[sup.clone()],
                        &mut a[sup],
                        link,
                    );
                    modal.fill(0.0);
                    for (j, &f) in link[..n].iter().enumerate() {
                        let y = &shapes[j * nm..(j + 1) * nm];
                        for (mk, yk) in modal.iter_mut().zip(y) {
                            *mk += f * yk;
                        }
                    }
                }
            }
            // Modal loads of the points (fast path: `scale` applied to the transform's sines).
            let modal_scale = if matches!(beam.coupling, Coupling::Fast(_)) {
                scale
            } else {
                1.0
            };
            let lanes = &mut ws.lanes[b];
            for (l, chunk) in lanes.iter_mut().zip(beam.points.chunks(LANES)) {
                *l = std::array::from_fn(|i| chunk.get(i).map_or(0.0, |&p| q.point_force[p]));
            }
            let shapes = &ws.shapes[beam.shares.unwrap_or(b)];
            let qs = &x[modes.clone()];
            let qd = &v[modes.clone()];
            let aq = &mut a[modes];
            let last = beam.points.len() % LANES;
            if lanes.len() == 1 && last == 0 && has_modal && beam.modal.damping.is_empty() {
                // One full lane of points on a supported, undamped beam (a vehicle on a track):
                // one zipped pass, vectorised.
                let p = lanes[0];
                let rows = aq
                    .iter_mut()
                    .zip(&shapes[0])
                    .zip(qs.iter().zip(&beam.modal.omega2))
                    .zip(modal.iter());
                for (((ak, y), (&qk, &w2)), &mk) in rows {
                    *ak = -w2 * qk - modal_scale * mk
                        + (p[0] * y[0] + p[1] * y[1] + p[2] * y[2] + p[3] * y[3]);
                }
                continue;
            }
            for k in 0..nm {
                // Each point's force times its shape, summed in point order.
                let mut load = 0.0;
                for (c, p) in lanes.iter().enumerate() {
                    let y = &shapes[c][k];
                    let n = if c + 1 == lanes.len() && last != 0 {
                        last
                    } else {
                        LANES
                    };
                    let part = if n == LANES {
                        p[0] * y[0] + p[1] * y[1] + p[2] * y[2] + p[3] * y[3]
                    } else {
                        (1..n).fold(p[0] * y[0], |s, i| s + p[i] * y[i])
                    };
                    load = if c == 0 { part } else { load + part };
                }
                let mut ak = -beam.modal.omega2[k] * qs[k];
                if !beam.modal.damping.is_empty() {
                    ak -= beam.modal.damping[k] * qd[k];
                }
                if has_modal {
                    ak -= modal_scale * modal[k];
                }
                aq[k] = ak + load;
            }
        }
    }

    /// As [`Engine::run_observed`] from the state `(x, v)` at `t = 0` (each [`Layout::len`]
    /// long) instead of the start of the run controls: a perturbed equilibrium, a state
    /// carried over from another run.
    pub fn run_observed_from(
        &self,
        mut x: Vec<f64>,
        mut v: Vec<f64>,
        steps: usize,
        cancel: Option<&AtomicBool>,
        mut observe: impl FnMut(&StepView),
    ) -> std::result::Result<(), Failure> {
        let n = self.layout.len;
        assert!(
            x.len() == n && v.len() == n,
            "a state of the layout's length"
        );
        let mut ws = self.workspace();
        let (mut a, mut a_prev) = (vec![0.0; n], vec![0.0; n]);
        let dt = self.config.dt;
        let every = self.config.output_every;
        self.accelerations(&mut ws, 0.0, &x, &v, &mut a);
        for step in 0..=steps {
            let t = step as f64 * dt;
            if step > 0 {
                integrator::predict(&mut x, &mut v, &a, &a_prev, dt, step == 1);
                std::mem::swap(&mut a, &mut a_prev);
                self.accelerations(&mut ws, t, &x, &v, &mut a);
            }
            self.check_step(t, &ws.q, &a)?;
            if step % every == 0 {
                check_state(t, &x, &v, &a)?;
                if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return Err(Failure {
                        t,
                        reason: format!("cancelled at t = {t:.4} s"),
                    });
                }
            }
            observe(&StepView {
                step,
                t,
                x: &x,
                v: &v,
                a: &a,
                q: &ws.q,
            });
        }
        Ok(())
    }

    fn check_step(&self, t: f64, q: &Quantities, a: &[f64]) -> std::result::Result<(), Failure> {
        // Only when a sum is not finite is the culprit searched.
        if finite_sum(&q.force) && finite_sum(&a[..self.layout.rigid]) {
            return Ok(());
        }
        if let Some(e) = q.force.iter().position(|f| !f.is_finite()) {
            let el = &self.system.elements[e];
            let sym = if el.law.is_contact() { "p" } else { "f" };
            return Err(Failure {
                t,
                reason: format!(
                    "non-finite force {sym}_{} = {} at t = {t:.4} s",
                    el.name, q.force[e]
                ),
            });
        }
        if let Some(i) = a[..self.layout.rigid].iter().position(|x| !x.is_finite()) {
            return Err(Failure {
                t,
                reason: format!(
                    "non-finite acceleration of {} = {} at t = {t:.4} s",
                    self.system.dofs[i].name, a[i]
                ),
            });
        }
        Ok(())
    }

    /// The value of a stored quantity at a step.
    pub fn channel_value(&self, quantity: Quantity, s: &StepView) -> f64 {
        match quantity {
            Quantity::Dof(i, 0) => s.x[i],
            Quantity::Dof(i, 1) => s.v[i],
            Quantity::Dof(i, _) => s.a[i],
            Quantity::Point(p) => s.q.point_w[p],
            Quantity::Sensor(i, d) => {
                let (b, _) = self.model.sensors[i];
                let modes = self.layout.beams[b].modes.clone();
                let src = match d {
                    0 => &s.x[modes],
                    1 => &s.v[modes],
                    _ => &s.a[modes],
                };
                ModalBeam::deflection(&self.sensor_shapes[i], src)
            }
            Quantity::Excitation(e) => s.q.eta[e],
            Quantity::ExcitationRate(e) => s.q.eta_rate[e],
            Quantity::Force(e) => s.q.force[e],
            Quantity::Deflection(e) => s.q.deflection[e],
            Quantity::WheelLateral(e) => s.q.wheel[e].y,
            Quantity::Flange(e) => s.q.wheel[e].flange,
            Quantity::Creep(e) => s.q.wheel[e].longitudinal,
            Quantity::Shift(e) => s.q.wheel[e].shift,
        }
    }

    /// One force evaluation at `(t, x, v)`: the accelerations and the quantities.
    pub fn evaluate(&self, t: f64, x: &[f64], v: &[f64]) -> (Vec<f64>, Quantities) {
        let mut ws = self.workspace();
        let mut a = vec![0.0; self.layout.len];
        self.accelerations(&mut ws, t, x, v, &mut a);
        (a, ws.q)
    }
}

/// The state layout (rigid DOFs, then per beam its modes and support levels) and every beam at
/// run time: its modes, points, coupling to its supports by `route`, and whether it shares the
/// mode shapes of an earlier beam.
fn beam_layout(model: &Model, needs_rate: &[bool], route: Route) -> (Layout, Vec<BeamRuntime>) {
    let rigid = model.dof_mass.len();
    let mut at = rigid;
    let mut layout_beams = Vec::new();
    let mut beams = Vec::new();
    for (b, mb) in model.beams.iter().enumerate() {
        let modes = at..at + mb.modes;
        at = modes.end;
        let n_sup = mb.supports.as_ref().map_or(0, |s| s.count * s.levels.len());
        let supports = at..at + n_sup;
        at = supports.end;
        layout_beams.push(BeamLayout { modes, supports });
        let beam = beam_runtime(model, b, needs_rate, route, &beams);
        beams.push(beam);
    }
    let layout = Layout {
        rigid,
        beams: layout_beams,
        len: at,
    };
    (layout, beams)
}

/// Beam `b` at run time, after the `earlier` beams (the first of which with the same modes and
/// point offsets, neither needing deflection rates, lends it its mode shapes).
fn beam_runtime(
    model: &Model,
    b: usize,
    needs_rate: &[bool],
    route: Route,
    earlier: &[BeamRuntime],
) -> BeamRuntime {
    let mb = &model.beams[b];
    let modal = ModalBeam::new(
        mb.length,
        mb.mass_per_length,
        mb.bending_stiffness,
        mb.modes,
        mb.damping_ratio,
    );
    let coupling = match &mb.supports {
        None => Coupling::None,
        Some(s) if route == Route::Fast && fast_structure(mb, s) => Coupling::Fast(s.clone()),
        Some(s) => {
            let mut shapes = vec![0.0; s.count * mb.modes];
            for (j, x) in crate::supports::positions(s).into_iter().enumerate() {
                modal.shapes_at(x, &mut shapes[j * mb.modes..(j + 1) * mb.modes]);
            }
            Coupling::Dense(s.clone(), shapes)
        }
    };
    let points: Vec<usize> = model
        .points
        .iter()
        .enumerate()
        .filter(|(_, p)| p.0 == Some(b))
        .map(|(i, _)| i)
        .collect();
    let rates =
        model.elements.iter().zip(needs_rate).any(|(e, &r)| {
            r && matches!(e.to, ModelEnd::Moving(p) if model.points[p].0 == Some(b))
        });
    let offsets = |pts: &[usize]| -> Vec<f64> { pts.iter().map(|&p| model.points[p].1).collect() };
    let shares = earlier.iter().position(|other: &BeamRuntime| {
        !rates
            && !other.rates
            && other.shares.is_none()
            && other.modal.length == modal.length
            && other.modal.modes() == modal.modes()
            && other.modal.shape_scale == modal.shape_scale
            && offsets(&other.points) == offsets(&points)
    });
    BeamRuntime {
        modal,
        points,
        coupling,
        rates,
        shares,
    }
}

/// Per moving point, the terms of its net force in the accumulation order of the assembly:
/// the non-contact elements, then the loads, then the contacts.
fn point_terms(model: &Model) -> Vec<Vec<(Source, f64)>> {
    let mut point_terms = vec![Vec::new(); model.points.len()];
    let kinds = [false, true];
    for contact in kinds {
        if contact {
            for (i, l) in model.loads.iter().enumerate() {
                if let ModelEnd::Moving(p) = l.at {
                    point_terms[p].push((Source::Load(i), 1.0));
                }
            }
        }
        for (i, e) in model.elements.iter().enumerate() {
            if e.law.is_contact() == contact {
                if let ModelEnd::Moving(p) = e.to {
                    point_terms[p].push((Source::Element(i), 1.0));
                }
            }
        }
    }
    point_terms
}

/// The profile each of `model`'s profiles reads: its analytic form, the points `profiles[p]`
/// supply for a generated one, read by the description's interpolation, or a level profile
/// where none is given. Refuses a cubic profile of fewer than 4 points.
pub(crate) fn profile_sources(
    model: &Model,
    mut profiles: Vec<Option<Profile>>,
) -> Result<Vec<ProfileSource>> {
    profiles.resize(model.profiles.len(), None);
    let mut sources: Vec<ProfileSource> = model
        .profiles
        .iter()
        .zip(profiles)
        .map(|(m, p)| match (m, p) {
            (ModelProfile::Combination(_), _) => Ok(ProfileSource::Level),
            (
                ModelProfile::Harmonic {
                    amplitude,
                    wavelength,
                    phase,
                },
                _,
            ) => Ok(ProfileSource::Harmonic {
                amplitude: *amplitude,
                wavelength: *wavelength,
                phase: *phase,
            }),
            (ModelProfile::Generated { interpolation }, Some(p)) => {
                Ok(ProfileSource::Points(p.interpolated(*interpolation)?))
            }
            (ModelProfile::Generated { .. }, None) => Ok(ProfileSource::Level),
        })
        .collect::<Result<_>>()?;
    // Profiles that end.
    for (i, ends) in model.profile_ends.iter().enumerate() {
        if let Some([end, taper]) = *ends {
            let inner = std::mem::replace(&mut sources[i], ProfileSource::Level);
            sources[i] = ProfileSource::Until {
                inner: Box::new(inner),
                end,
                taper,
            };
        }
    }
    // Combinations of the others, once those are built.
    for (i, m) in model.profiles.iter().enumerate() {
        if let ModelProfile::Combination(terms) = m {
            sources[i] = ProfileSource::Sum(
                terms
                    .iter()
                    .map(|&(p, w)| (w, sources[p].clone()))
                    .collect(),
            );
        }
    }
    Ok(sources)
}

/// Per element, its run-time wheel (creep coefficients from the contact ellipse), or an empty
/// list when the system has no wheels.
pub(crate) fn run_wheels(system: &System, model: &Model) -> Result<Vec<Option<Wheel>>> {
    if !model.elements.iter().any(|e| e.law.wheel().is_some()) {
        return Ok(Vec::new());
    }
    model
        .elements
        .iter()
        .zip(&system.elements)
        .map(
            |(e, described)| match (e.law.wheel(), described.law.wheel()) {
                (Some(w), Some(d)) => Wheel::of(w, &d.wheelset).map(Some),
                _ => Ok(None),
            },
        )
        .collect()
}

/// Displacement of an end given the rigid state and the point quantities.
#[inline]
fn end_u(end: &ModelEnd, x: &[f64], q: &Quantities) -> f64 {
    match end {
        ModelEnd::Ground => 0.0,
        ModelEnd::Body(t) => t.displacement(x),
        ModelEnd::Moving(p) => q.point_w[*p],
    }
}

#[inline]
fn end_rate(end: &ModelEnd, v: &[f64], q: &Quantities) -> f64 {
    match end {
        ModelEnd::Ground => 0.0,
        ModelEnd::Body(t) => t.displacement(v),
        ModelEnd::Moving(p) => q.point_rate[*p],
    }
}

/// Every element's deflection and force, from the rigid state `(x, v)` (the rigid DOFs lead
/// the state) and the point and profile quantities already in `q`: `d = (u_from - u_to) -
/// eta`, its rate where `needs_rate` says so, and the law's force. The one element code of the
/// engine: the time loop and the residuals of [`crate::residual`] both call it.
pub(crate) fn element_forces(
    m: &Model,
    needs_rate: &[bool],
    wheels: &[Option<Wheel>],
    x: &[f64],
    v: &[f64],
    q: &mut Quantities,
) {
    for (e, el) in m.elements.iter().enumerate() {
        let mut d = end_u(&el.from, x, q) - end_u(&el.to, x, q);
        if el.profile.is_some() {
            d -= q.eta[e];
        }
        if let Some(Some(wheel)) = wheels.get(e) {
            // A wheel: its rolling radius at the wheelset's shift enters the vertical contact,
            // its tangential forces follow from the normal load.
            let motion = wheel.motion(x, v);
            let (d, load, forces) = wheel.contact(d, &motion, m.speed);
            q.deflection[e] = d;
            q.force[e] = load;
            q.wheel[e] = forces;
            continue;
        }
        let rate = if needs_rate[e] {
            let mut r = end_rate(&el.from, v, q) - end_rate(&el.to, v, q);
            if el.profile.is_some() {
                r -= q.eta_rate[e];
            }
            r
        } else {
            0.0
        };
        q.deflection[e] = d;
        q.force[e] = el.law.force(d, rate);
    }
}

/// Adds every wheel's tangential generalised forces (from `q.wheel`) to the rigid DOFs' `out`
/// ([`Wheel::apply`]), after the coefficient groups of [`Assembly::forces`].
pub(crate) fn wheel_forces(wheels: &[Option<Wheel>], q: &Quantities, out: &mut [f64]) {
    for (e, wheel) in wheels.iter().enumerate() {
        if let Some(w) = wheel {
            w.apply(&q.wheel[e], out);
        }
    }
}

/// Whether the sum of `s` is finite: false exactly when an entry is NaN or infinite, or when
/// finite entries overflow (as much a blow-up at a state's magnitudes). Eight running sums
/// side by side: one sum in order waits on every addition's latency, and at the length of a
/// track's state that wait was a twentieth of the step.
fn finite_sum(s: &[f64]) -> bool {
    const WAYS: usize = 8;
    let mut sums = [0.0f64; WAYS];
    let chunks = s.chunks_exact(WAYS);
    let rest: f64 = chunks.remainder().iter().sum();
    for c in chunks {
        for (acc, x) in sums.iter_mut().zip(c) {
            *acc += x;
        }
    }
    (sums.iter().sum::<f64>() + rest).is_finite()
}

fn check_state(t: f64, x: &[f64], v: &[f64], a: &[f64]) -> std::result::Result<(), Failure> {
    for (name, s) in [("displacement", x), ("velocity", v), ("acceleration", a)] {
        if !finite_sum(s) {
            let i = s.iter().position(|x| !x.is_finite()).unwrap_or(0);
            return Err(Failure {
                t,
                reason: format!("non-finite {name} (state index {i}) at t = {t:.4} s"),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::finite_sum;

    #[test]
    fn finite_sum_flags_every_non_finite_entry_wherever_it_sits() {
        // Lengths around the eight running sums: none, part of one, several and a remainder.
        for n in [0usize, 1, 7, 8, 9, 23, 4539] {
            let s: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() * 1e5).collect();
            assert!(finite_sum(&s), "n = {n}");
            for i in 0..n {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut t = s.clone();
                    t[i] = bad;
                    assert!(!finite_sum(&t), "n = {n}, entry {i} = {bad}");
                }
            }
        }
        // Opposite infinities in different running sums, and finite values that overflow.
        let mut s = vec![0.0; 16];
        (s[0], s[1]) = (f64::INFINITY, f64::NEG_INFINITY);
        assert!(!finite_sum(&s));
        assert!(!finite_sum(&[f64::MAX; 10]));
        assert!(finite_sum(&[f64::MAX, -f64::MAX, 1.0]));
    }
}
