//! The coupled vehicle-track model and its time loop (`docs/model.md`, all sections).
//!
//! **State.** One vector for displacements `X`, one for velocities `V`, one for accelerations
//! `A`, each laid out as
//! ```text
//! [ vehicle (10: z_c, beta_c, z_t1, beta_t1, z_t2, beta_t2, z_w1..z_w4) | rail modes q_1..q_N_M
//!   | sleepers Z_s0..Z_s(N_f-1) | ballast blocks Z_b0..Z_b(N_f-1) ]
//! ```
//! (m, rad, and sqrt(kg) m for the mass-normalised modal coordinates). The mass matrix is
//! diagonal (lumped bodies, unit modal masses), so `A = M^-1 F(X, V, t)` is explicit.
//!
//! **Forces at time t.** Wheel positions `x_wi(t) = x0 + v t + o_i` with the rear wheel 4 at
//! `x0` when `t = 0`: `o_4 = 0`, `o_3 = 2 l_t`, `o_2 = 2 l_c`, `o_1 = 2 l_c + 2 l_t` (m).
//! Rail under wheel `i`: `z_ri = sum_k Y_k(x_wi) q_k`; irregularity `eta_i = r(t) eta(x_wi)`
//! (profile linearly interpolated); contact `P_i = Hertz(z_wi - z_ri - eta_i)`; vehicle
//! accelerations from [`Vehicle::accelerations`]; rail-seat forces
//! `k_f Z_r(x_j) + c_f Z_r'(x_j) = DST(k_f q + c_f q')` and modal fastener loads
//! `sum_j F_fj Y_k(x_j) = DST(F_f)` (two sine transforms per evaluation, see
//! [`crate::rail::SineTransform`]); substructure by [`crate::track::substructure`].
//!
//! **Start.** [`StartMode::Equilibrium`] (the default): the run begins at the static solution
//! of the coupled model at `t = 0` with zero velocities ([`Simulation::initial_state`]): the
//! track deflected by the four static wheel loads `W` at the wheels' starting positions
//! ([`crate::statics`]), each wheel `G W^(2/3)` (the static Hertz compression) below the rail
//! and the irregularity under it, bogies and car body on undeflected suspensions. Every
//! contact force then equals `W` and no drop transient exists. [`StartMode::Rest`] (the paper's
//! protocol): from the zero state, the vehicle at its rigid-track equilibrium dropping onto the
//! track (about 1 mm of car-body bounce, decaying over seconds).
//!
//! **Irregularity start-up.** The irregularity factor `r(t)` is 0 for `t < z T`, rises
//! linearly to 1 over the next `r T` and stays 1 (`z`, `r` the start-up fractions, 0.1 and 0.1
//! by default; `T` the duration).
//!
//! **Outputs.** Every `output_every` steps (including `t = 0`), the row
//! `t, z (10), z_r (4), z' (10), z'' (10), eta (4), P (4)` where `z''` is the acceleration
//! evaluated at the stored state, so the stored rows satisfy the vehicle equations to
//! round-off. `n_out = floor(round(T/dt) / output_every)` rows, `t = n output_every dt`.
//!
//! **Failure.** A non-finite contact force, vehicle acceleration or track state ends the
//! sample with a [`Failure`] naming what and when.

use serde::{Deserialize, Serialize};

use crate::contact;
use crate::integrator;
use crate::params::SampleParams;
use crate::rail::{Rail, SineTransform};
use crate::stability;
use crate::track::{self, TrackParams};
use crate::vehicle::{Vehicle, FIRST_WHEEL, NUM_DOFS};
use crate::{Error, Result};

/// Number of stored signal columns after `t`: 10 + 4 + 10 + 10 + 4 + 4.
pub const NUM_SIGNALS: usize = 42;
/// Offsets of the signal groups inside a row (after `t`).
pub mod col {
    /// Vehicle displacements `z_c..z_w4`.
    pub const Z: usize = 0;
    /// Rail under wheels `z_r1..z_r4`.
    pub const Z_R: usize = 10;
    /// Vehicle velocities.
    pub const V: usize = 14;
    /// Vehicle accelerations.
    pub const A: usize = 24;
    /// Irregularity under wheels.
    pub const ETA: usize = 34;
    /// Contact forces.
    pub const P: usize = 38;
}

/// How a run starts (`docs/model.md`, start protocols).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", try_from = "String")]
pub enum StartMode {
    /// Static equilibrium of vehicle and track under the wheel loads, zero velocities.
    #[default]
    Equilibrium,
    /// The zero state: the vehicle is dropped onto the undeflected track (the paper's data).
    Rest,
}

impl TryFrom<String> for StartMode {
    type Error = String;
    fn try_from(s: String) -> std::result::Result<Self, String> {
        match s.as_str() {
            "equilibrium" => Ok(Self::Equilibrium),
            "rest" => Ok(Self::Rest),
            other => Err(format!(
                "`start` = \"{other}\" is not a start mode; allowed: \"equilibrium\" (static \
                 solution under the wheel loads) or \"rest\" (zero state, the paper's protocol)"
            )),
        }
    }
}

/// Everything fixed for a run: time stepping, start-up, vehicle placement and track. These are
/// the `simulate` stage's parameters, flat (the track's fields sit beside the others, so each
/// can be overridden alone: `n_f`, `k_b`, ...); every field has the spec's default
/// ([`Default`]: the values documented on each field and on [`TrackParams`]) and unknown names
/// are refused.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimulationConfig {
    /// Simulated time `T` (s). Default 5 (paper).
    pub duration: f64,
    /// Time step (s). Default 1e-4.
    pub dt: f64,
    /// Keep every this many steps (10 gives 1 kHz at dt = 1e-4). Default 10.
    pub output_every: usize,
    /// Initial state: `equilibrium` (default) or `rest`.
    pub start: StartMode,
    /// Fraction of `T` with the irregularity off. Default 0.1.
    pub startup_zero_fraction: f64,
    /// Fraction of `T` over which the irregularity fades in linearly. Default 0.1.
    pub startup_ramp_fraction: f64,
    /// Rear-wheel position at `t = 0` (m). Default 20.
    pub x0: f64,
    /// Gravity `g` (m/s^2), for the static wheel load. Default 9.81.
    pub gravity: f64,
    /// Wheel radius `R` (m) of the Hertz constant `G = 4.57 R^-0.149 1e-8`. Default 0.43.
    pub wheel_radius: f64,
    /// The track constants (defaults: [`TrackParams::default`]); flattened, so in a parameter
    /// file they are the keys `n_f`, `n_m`, `s`, `m_r`, ... beside the others.
    #[serde(flatten)]
    pub track: TrackParams,
}

impl Default for SimulationConfig {
    fn default() -> Self {
        Self {
            duration: 5.0,
            dt: 1e-4,
            output_every: 10,
            start: StartMode::default(),
            startup_zero_fraction: 0.1,
            startup_ramp_fraction: 0.1,
            x0: 20.0,
            gravity: 9.81,
            wheel_radius: 0.43,
            track: TrackParams::default(),
        }
    }
}

fn out_of_range(name: &str, value: f64, allowed: impl Into<String>) -> Error {
    Error::OutOfRange {
        name: name.to_owned(),
        value,
        allowed: allowed.into(),
    }
}

impl SimulationConfig {
    /// Number of time steps `round(T / dt)`.
    pub fn steps(&self) -> usize {
        (self.duration / self.dt).round() as usize
    }

    /// Number of stored rows per sample.
    pub fn n_outputs(&self) -> usize {
        self.steps() / self.output_every.max(1)
    }

    /// Checks every field (names the field and its allowed range). The time-step limit
    /// depends on the vehicle and is checked per sample by [`Simulation::new`].
    pub fn validate(&self) -> Result<()> {
        for (name, value) in [
            ("duration", self.duration),
            ("dt", self.dt),
            ("gravity", self.gravity),
            ("wheel_radius", self.wheel_radius),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(out_of_range(name, value, "finite and > 0"));
            }
        }
        if self.output_every == 0 {
            return Err(out_of_range(
                "output_every",
                0.0,
                "an integer >= 1 (steps between stored rows)",
            ));
        }
        if self.n_outputs() < 1 {
            let allowed = format!(
                "at least output_every * dt = {} s",
                self.output_every as f64 * self.dt
            );
            return Err(out_of_range("duration", self.duration, allowed));
        }
        for (name, value) in [
            ("startup_zero_fraction", self.startup_zero_fraction),
            ("startup_ramp_fraction", self.startup_ramp_fraction),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(out_of_range(name, value, "in [0, 1]"));
            }
        }
        let sum = self.startup_zero_fraction + self.startup_ramp_fraction;
        if sum > 1.0 {
            return Err(out_of_range(
                "startup_ramp_fraction",
                self.startup_ramp_fraction,
                format!(
                    "<= 1 - startup_zero_fraction = {}",
                    1.0 - self.startup_zero_fraction
                ),
            ));
        }
        if !(self.x0.is_finite() && self.x0 > 0.0) {
            return Err(out_of_range(
                "x0",
                self.x0,
                "finite and > 0 (inside the rail)",
            ));
        }
        self.track.validate()
    }

    /// Irregularity factor `r(t)` of the start-up protocol.
    pub fn ramp(&self, t: f64) -> f64 {
        let start = self.startup_zero_fraction * self.duration;
        let width = self.startup_ramp_fraction * self.duration;
        if t < start {
            0.0
        } else if width <= 0.0 || t >= start + width {
            1.0
        } else {
            (t - start) / width
        }
    }
}

/// A vertical irregularity profile `eta(x)` (m, positive downward) on increasing positions.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    x: Vec<f64>,
    eta: Vec<f64>,
}

impl Profile {
    /// Checks lengths (equal, >= 2), strictly increasing finite `x` and finite `eta`.
    pub fn new(x: Vec<f64>, eta: Vec<f64>) -> Result<Self> {
        if x.len() != eta.len() || x.len() < 2 {
            return Err(Error::Shape {
                name: "eta".to_owned(),
                found: eta.len(),
                expected: x.len().max(2),
            });
        }
        if let Some(w) = x.windows(2).find(|w| {
            w[1] <= w[0] || w[0].is_nan() || w[1].is_nan() || !w[1].is_finite() || !w[0].is_finite()
        }) {
            return Err(out_of_range(
                "x",
                w[1],
                format!("finite and strictly increasing (after {})", w[0]),
            ));
        }
        if let Some(e) = eta.iter().find(|e| !e.is_finite()) {
            return Err(out_of_range("eta", *e, "finite"));
        }
        Ok(Self { x, eta })
    }

    /// Covered positions `[x_first, x_last]` (m).
    pub fn range(&self) -> [f64; 2] {
        [self.x[0], self.x[self.x.len() - 1]]
    }

    /// `eta` at `x` by linear interpolation (clamped to the ends; callers check coverage).
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        let i = self
            .x
            .partition_point(|&p| p <= x)
            .clamp(1, self.x.len() - 1);
        let (x0, x1) = (self.x[i - 1], self.x[i]);
        let w = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        self.eta[i - 1] + w * (self.eta[i] - self.eta[i - 1])
    }
}

/// The wheel-rail contact law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactLaw {
    /// Hertz `P = (delta/G)^(3/2)` for `delta > 0`, else 0 (the spec's law).
    Hertz,
    /// `P = preload + stiffness delta` for every `delta` (no lift-off): the contact linearised
    /// at a static point, used by the energy test.
    Linear {
        /// Tangent stiffness (N/m).
        stiffness: f64,
        /// Force at `delta = 0` (N).
        preload: f64,
    },
}

/// Why a sample failed.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    /// Time of detection (s).
    pub t: f64,
    /// What was not finite.
    pub reason: String,
}

/// Stored rows of one sample: `t` and [`NUM_SIGNALS`] columns in schema order (see [`col`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Output times (s).
    pub t: Vec<f64>,
    /// Signal columns, each `t.len()` long.
    pub columns: Vec<Vec<f64>>,
}

/// What an observer sees at each step: the full state and the wheel quantities.
#[derive(Debug)]
pub struct StepView<'a> {
    /// Step index `n`.
    pub step: usize,
    /// Time `n dt` (s).
    pub t: f64,
    /// Displacements (state layout of the module doc).
    pub x: &'a [f64],
    /// Velocities.
    pub v: &'a [f64],
    /// Accelerations at `(x, v, t)`.
    pub a: &'a [f64],
    /// Wheel quantities at this state.
    pub wheels: &'a Wheels,
}

/// Per-wheel quantities of one evaluation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Wheels {
    /// Wheel positions (m).
    pub x: [f64; 4],
    /// Rail displacement under each wheel (m).
    pub z_r: [f64; 4],
    /// Irregularity under each wheel (m).
    pub eta: [f64; 4],
    /// Contact forces (N).
    pub p: [f64; 4],
}

/// One sample's coupled model, ready to run. Built and checked by [`Simulation::new`]
/// (configuration, parameters, rail and profile coverage, the time step against the stability
/// bound); its parts are read through accessors and cannot be changed afterwards, so a
/// `Simulation` always satisfies the checks it was built with.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// Run configuration (its `track` is the track of this model).
    config: SimulationConfig,
    /// The sample's parameters.
    params: SampleParams,
    /// The half vehicle.
    vehicle: Vehicle,
    /// The modal rail.
    rail: Rail,
    /// Contact law (Hertz unless a test of this module changes it).
    contact: ContactLaw,
    /// Hertz constant `G` (m/N^(2/3)).
    hertz_g: f64,
    /// Running speed (m/s).
    speed: f64,
    /// Wheel offsets from the rear wheel (m), wheels 1..4.
    offsets: [f64; 4],
    profile: Option<Profile>,
}

/// Scratch space of the force evaluation.
struct Workspace {
    dst: SineTransform,
    shapes: Vec<[f64; 4]>,
    seat_in: Vec<f64>,
    seat: Vec<f64>,
    fastener: Vec<f64>,
    modal: Vec<f64>,
}

impl Simulation {
    /// Builds and checks one sample's model: configuration, parameters (masses, stiffnesses and
    /// lengths > 0 with `l_t < l_c` so the wheels keep their order; dampings and speed >= 0, zero
    /// for the tests' undamped or standing vehicles), that the wheels stay on the rail and,
    /// while the irregularity is on, on the profile, and the time step against the stability
    /// bound.
    pub fn new(
        params: &SampleParams,
        config: &SimulationConfig,
        profile: Option<Profile>,
    ) -> Result<Self> {
        config.validate()?;
        for (name, value) in crate::params::PARAMETER_NAMES.iter().zip(params.to_array()) {
            let damping = matches!(*name, "c_p" | "c_s" | "c_f");
            let ok = value.is_finite()
                && if damping {
                    value >= 0.0
                } else {
                    value > 0.0 || *name == "v_kmh" && value == 0.0
                };
            if !ok {
                return Err(out_of_range(
                    name,
                    value,
                    if damping {
                        "finite and >= 0"
                    } else {
                        "finite and > 0"
                    },
                ));
            }
        }
        if params.l_t >= params.l_c {
            let allowed = format!("< l_c = {} (the bogies must not overlap)", params.l_c);
            return Err(out_of_range("l_t", params.l_t, allowed));
        }
        let track = config.track;
        let vehicle = Vehicle::new(params, config.gravity);
        let hertz_g = contact::hertz_constant(config.wheel_radius);

        let (lc, lt) = (params.l_c, params.l_t);
        let offsets = [2.0 * (lc + lt), 2.0 * lc, 2.0 * lt, 0.0];
        let sim = Self {
            config: *config,
            params: *params,
            vehicle,
            rail: Rail::new(&track),
            contact: ContactLaw::Hertz,
            hertz_g,
            speed: params.speed(),
            offsets,
            profile,
        };
        let t_end =
            config.n_outputs().saturating_sub(1) as f64 * config.output_every as f64 * config.dt;
        let span = |t0: f64| {
            [
                config.x0 + sim.speed * t0,
                config.x0 + sim.speed * t_end + offsets[0],
            ]
        };
        let need = span(0.0);
        let length = track.length();
        if !(need[0] > 0.0 && need[1] < length) {
            return Err(Error::TooShort {
                what: format!("the rail (n_f * s = {} * {} m)", track.n_f, track.s),
                have_lo: 0.0,
                have_hi: length,
                need_lo: need[0],
                need_hi: need[1],
                hint: "lengthen the track (n_f), shorten the run (duration) or move x0".to_owned(),
            });
        }
        stability::spectrum_bound(&vehicle, &track, params.k_f, params.c_f, hertz_g, need)
            .check(config.dt)?;
        if let Some(p) = &sim.profile {
            let t_on = config.startup_zero_fraction * config.duration;
            let need = span(t_on.min(t_end));
            let have = p.range();
            if t_on <= t_end && (need[0] < have[0] || need[1] > have[1]) {
                return Err(Error::TooShort {
                    what: "the irregularity profile".to_owned(),
                    have_lo: have[0],
                    have_hi: have[1],
                    need_lo: need[0],
                    need_hi: need[1],
                    hint: "generate profiles that cover the whole run plus the vehicle length"
                        .to_owned(),
                });
            }
        }
        Ok(sim)
    }

    /// The run configuration.
    pub fn config(&self) -> &SimulationConfig {
        &self.config
    }

    /// The track constants (`config().track`).
    pub fn track(&self) -> &TrackParams {
        &self.config.track
    }

    /// The sample's parameters.
    pub fn params(&self) -> &SampleParams {
        &self.params
    }

    /// The half vehicle.
    pub fn vehicle(&self) -> &Vehicle {
        &self.vehicle
    }

    /// The modal rail.
    pub fn rail(&self) -> &Rail {
        &self.rail
    }

    /// The contact law (Hertz).
    pub fn contact(&self) -> ContactLaw {
        self.contact
    }

    /// Hertz constant `G` (m/N^(2/3)).
    pub fn hertz_g(&self) -> f64 {
        self.hertz_g
    }

    /// Running speed (m/s).
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Wheel offsets from the rear wheel (m), wheels 1..4.
    pub fn offsets(&self) -> [f64; 4] {
        self.offsets
    }

    /// Length of the state vectors: `10 + N_M + 2 N_f`.
    pub fn state_len(&self) -> usize {
        NUM_DOFS + self.config.track.n_m + 2 * self.config.track.n_f
    }

    /// Ranges of the vehicle, rail-mode, sleeper and ballast parts of the state.
    pub fn layout(&self) -> [std::ops::Range<usize>; 4] {
        let (nm, nf) = (self.config.track.n_m, self.config.track.n_f);
        let q = NUM_DOFS..NUM_DOFS + nm;
        let s = q.end..q.end + nf;
        let b = s.end..s.end + nf;
        [0..NUM_DOFS, q, s, b]
    }

    fn workspace(&self) -> Workspace {
        let (nm, nf) = (self.config.track.n_m, self.config.track.n_f);
        Workspace {
            dst: SineTransform::new(nf),
            shapes: vec![[0.0; 4]; nm],
            seat_in: vec![0.0; nm],
            seat: vec![0.0; nf],
            fastener: vec![0.0; nf],
            modal: vec![0.0; nm],
        }
    }

    /// Wheel positions at time `t` (m).
    pub fn wheel_positions(&self, t: f64) -> [f64; 4] {
        let rear = self.config.x0 + self.speed * t;
        self.offsets.map(|o| rear + o)
    }

    #[inline]
    fn contact_force(&self, delta: f64) -> f64 {
        match self.contact {
            ContactLaw::Hertz => contact::contact_force(delta, self.hertz_g),
            ContactLaw::Linear { stiffness, preload } => preload + stiffness * delta,
        }
    }

    /// `A = M^-1 F(X, V, t)`; returns the wheel quantities.
    fn accelerations(
        &self,
        ws: &mut Workspace,
        t: f64,
        x: &[f64],
        v: &[f64],
        a: &mut [f64],
    ) -> Wheels {
        let [_, rq, rs, rb] = self.layout();
        let (q, qd) = (&x[rq.clone()], &v[rq.clone()]);
        let mut w = Wheels {
            x: self.wheel_positions(t),
            ..Default::default()
        };
        let mut z = [0.0; NUM_DOFS];
        let mut zd = [0.0; NUM_DOFS];
        z.copy_from_slice(&x[..NUM_DOFS]);
        zd.copy_from_slice(&v[..NUM_DOFS]);
        w.z_r = self.rail.wheel_shapes(&w.x, q, &mut ws.shapes);
        w.eta = self.wheel_irregularity(t, &w.x);
        for i in 0..4 {
            w.p[i] = self.contact_force(z[FIRST_WHEEL + i] - w.z_r[i] - w.eta[i]);
        }
        let av = self.vehicle.accelerations(&z, &zd, &w.p);
        a[..NUM_DOFS].copy_from_slice(&av);

        // Rail-seat share of the fastener forces: k_f Z_r(x_j) + c_f Z_r'(x_j), j = 1..N_f-1
        // (x_0 = 0 is a node of every mode).
        let (k_f, c_f, scale) = (self.params.k_f, self.params.c_f, self.rail.shape_scale);
        for ((s, q), qd) in ws.seat_in.iter_mut().zip(q).zip(qd) {
            *s = scale * (k_f * q + c_f * qd);
        }
        ws.seat[0] = 0.0;
        ws.dst.apply(&ws.seat_in, &mut ws.seat[1..]);
        let (a_s, a_b) = a[rs.start..].split_at_mut(rs.len());
        track::substructure(
            &self.config.track,
            k_f,
            c_f,
            &ws.seat,
            &x[rs.clone()],
            &v[rs.clone()],
            &x[rb.clone()],
            &v[rb.clone()],
            &mut ws.fastener,
            a_s,
            &mut a_b[..rb.len()],
        );
        // Modal loads: -sum_j F_fj Y_k(x_j) + sum_i P_i Y_k(x_wi).
        ws.dst.apply(&ws.fastener[1..], &mut ws.modal);
        let aq = &mut a[rq];
        let p = w.p;
        for (k, ((ak, y), (&qk, &w2))) in aq
            .iter_mut()
            .zip(&ws.shapes)
            .zip(q.iter().zip(&self.rail.omega2))
            .enumerate()
        {
            *ak = -w2 * qk - scale * ws.modal[k]
                + (p[0] * y[0] + p[1] * y[1] + p[2] * y[2] + p[3] * y[3]);
        }
        w
    }

    /// Runs from the initial state ([`Simulation::initial_state`]) for the configured duration,
    /// calling `observe` at every step
    /// (including step 0) with the state and accelerations at that step. Stops with a
    /// [`Failure`] on a non-finite contact force or vehicle acceleration (checked every step)
    /// or track state (checked at every output step).
    pub fn run_observed(
        &self,
        steps: usize,
        mut observe: impl FnMut(&StepView),
    ) -> std::result::Result<(), Failure> {
        let n = self.state_len();
        let mut ws = self.workspace();
        let mut x = self.initial_state().map_err(|e| Failure {
            t: 0.0,
            reason: format!("initial state: {e}"),
        })?;
        let mut v = vec![0.0; n];
        let (mut a, mut a_prev) = (vec![0.0; n], vec![0.0; n]);
        let dt = self.config.dt;
        let every = self.config.output_every;
        let mut wheels = self.accelerations(&mut ws, 0.0, &x, &v, &mut a);
        for step in 0..=steps {
            let t = step as f64 * dt;
            if step > 0 {
                integrator::predict(&mut x, &mut v, &a, &a_prev, dt, step == 1);
                std::mem::swap(&mut a, &mut a_prev);
                wheels = self.accelerations(&mut ws, t, &x, &v, &mut a);
            }
            check_wheels(t, &wheels, &a)?;
            if step % every == 0 {
                check_state(t, &x, &v, &a)?;
            }
            observe(&StepView {
                step,
                t,
                x: &x,
                v: &v,
                a: &a,
                wheels: &wheels,
            });
        }
        Ok(())
    }

    /// Irregularity under the wheels at positions `x` and time `t` (m): the ramped profile.
    #[inline]
    fn wheel_irregularity(&self, t: f64, x: &[f64; 4]) -> [f64; 4] {
        let ramp = self.config.ramp(t);
        std::array::from_fn(|i| match (&self.profile, ramp > 0.0) {
            (Some(p), true) => ramp * p.at(x[i]),
            _ => 0.0,
        })
    }

    /// Contact compression (m) at which the contact force equals `load` (N): `G load^(2/3)`
    /// for Hertz.
    pub fn static_compression(&self, load: f64) -> f64 {
        match self.contact {
            ContactLaw::Hertz => contact::static_compression(load, self.hertz_g),
            ContactLaw::Linear { stiffness, preload } => (load - preload) / stiffness,
        }
    }

    /// Displacements at `t = 0` (state layout of the module doc; velocities are zero).
    /// [`StartMode::Rest`]: all zero. [`StartMode::Equilibrium`]: the static solution under the
    /// four wheel loads `W` (`docs/model.md`, start protocols): the track from
    /// [`crate::statics::track_deflection`]; wheel `i` at `Z_r(x_i) + eta_i(0) + delta_W`
    /// (`delta_W` the contact compression at load `W`; `eta_i(0)` is zero unless both start-up
    /// fractions are zero); bogies and car body with every suspension deflection zero:
    /// `Z_t1 = (Z_w1 + Z_w2) / 2`, `beta_t1 = (Z_w2 - Z_w1) / (2 l_t)` (bogie 2 likewise with
    /// wheels 3, 4), `Z_c = (Z_t1 + Z_t2) / 2`, `beta_c = (Z_t2 - Z_t1) / (2 l_c)`. Then every
    /// suspension force is zero, every contact force is `W` and every acceleration vanishes to
    /// round-off (tested).
    pub fn initial_state(&self) -> Result<Vec<f64>> {
        let mut x = vec![0.0; self.state_len()];
        if self.config.start == StartMode::Rest {
            return Ok(x);
        }
        let w = self.vehicle.w;
        let xw = self.wheel_positions(0.0);
        let track = crate::statics::track_deflection(
            &self.rail,
            &self.config.track,
            self.params.k_f,
            &xw,
            &[w; 4],
        )?;
        let [_, rq, rs, rb] = self.layout();
        x[rq].copy_from_slice(&track.q);
        x[rs].copy_from_slice(&track.sleepers);
        x[rb].copy_from_slice(&track.ballast);
        let eta = self.wheel_irregularity(0.0, &xw);
        let delta = self.static_compression(w);
        let mut y = vec![0.0; self.config.track.n_m];
        let mut zw = [0.0; 4];
        for i in 0..4 {
            self.rail.shapes_at(xw[i], &mut y);
            zw[i] = Rail::displacement(&y, &track.q) + eta[i] + delta;
        }
        let (lt, lc) = (self.vehicle.l_t, self.vehicle.l_c);
        let (zt1, bt1) = ((zw[0] + zw[1]) / 2.0, (zw[1] - zw[0]) / (2.0 * lt));
        let (zt2, bt2) = ((zw[2] + zw[3]) / 2.0, (zw[3] - zw[2]) / (2.0 * lt));
        let (zc, bc) = ((zt1 + zt2) / 2.0, (zt2 - zt1) / (2.0 * lc));
        x[..NUM_DOFS].copy_from_slice(&[zc, bc, zt1, bt1, zt2, bt2, zw[0], zw[1], zw[2], zw[3]]);
        Ok(x)
    }

    /// Runs the configured duration and returns the stored rows.
    pub fn run(&self) -> std::result::Result<Trajectory, Failure> {
        let n_out = self.config.n_outputs();
        let every = self.config.output_every;
        let mut t_col = Vec::with_capacity(n_out);
        let mut columns: Vec<Vec<f64>> = (0..NUM_SIGNALS)
            .map(|_| Vec::with_capacity(n_out))
            .collect();
        self.run_observed((n_out - 1) * every, |s| {
            if s.step % every != 0 {
                return;
            }
            t_col.push(s.t);
            let vehicle = |c: &mut [Vec<f64>], src: &[f64]| {
                for (col, val) in c.iter_mut().zip(&src[..NUM_DOFS]) {
                    col.push(*val);
                }
            };
            vehicle(&mut columns[col::Z..col::Z + NUM_DOFS], s.x);
            vehicle(&mut columns[col::V..col::V + NUM_DOFS], s.v);
            vehicle(&mut columns[col::A..col::A + NUM_DOFS], s.a);
            for i in 0..4 {
                columns[col::Z_R + i].push(s.wheels.z_r[i]);
                columns[col::ETA + i].push(s.wheels.eta[i]);
                columns[col::P + i].push(s.wheels.p[i]);
            }
        })?;
        Ok(Trajectory { t: t_col, columns })
    }

    /// Total mechanical energy (J) of state `(x, v)` with wheels at `wheel_x`: kinetic energy,
    /// suspension, rail bending, fastener, ballast, shear and subgrade springs, the contact
    /// potential (`P0 delta + k delta^2 / 2` for [`ContactLaw::Linear`], `(2/5) delta^(5/2) /
    /// G^(3/2)` for Hertz) and the work potential `-W sum z_wi` of the static wheel loads. It is
    /// conserved when every damper is off, the wheels stand still and the irregularity is off.
    pub fn energy(&self, x: &[f64], v: &[f64], wheel_x: &[f64; 4]) -> f64 {
        let [_, rq, rs, rb] = self.layout();
        let tp = &self.config.track;
        let veh = &self.vehicle;
        let m = veh.masses();
        let mut kinetic: f64 = (0..NUM_DOFS).map(|i| 0.5 * m[i] * v[i] * v[i]).sum();
        kinetic += v[rq.clone()].iter().map(|q| 0.5 * q * q).sum::<f64>();
        kinetic += v[rs.clone()]
            .iter()
            .map(|s| 0.5 * tp.m_s * s * s)
            .sum::<f64>();
        kinetic += v[rb.clone()]
            .iter()
            .map(|b| 0.5 * tp.m_b * b * b)
            .sum::<f64>();
        let mut z = [0.0; NUM_DOFS];
        z.copy_from_slice(&x[..NUM_DOFS]);
        let susp = veh.suspension_forces(&z, &[0.0; NUM_DOFS]);
        let mut potential: f64 = susp
            .secondary
            .iter()
            .map(|f| 0.5 * f * f / veh.k_s)
            .sum::<f64>()
            + susp
                .primary
                .iter()
                .map(|f| 0.5 * f * f / veh.k_p)
                .sum::<f64>();
        let q = &x[rq];
        potential += q
            .iter()
            .zip(&self.rail.omega2)
            .map(|(q, w2)| 0.5 * w2 * q * q)
            .sum::<f64>();
        let mut seat = vec![0.0; tp.n_f];
        let scaled: Vec<f64> = q.iter().map(|q| self.rail.shape_scale * q).collect();
        SineTransform::new(tp.n_f).apply(&scaled, &mut seat[1..]);
        let (zs, zb) = (&x[rs], &x[rb]);
        for j in 0..tp.n_f {
            let left = if j == 0 { 0.0 } else { zb[j - 1] };
            potential += 0.5 * self.params.k_f * (seat[j] - zs[j]).powi(2)
                + 0.5 * tp.k_b * (zs[j] - zb[j]).powi(2)
                + 0.5 * tp.k_g * zb[j] * zb[j]
                + 0.5 * tp.k_w * (zb[j] - left).powi(2);
        }
        potential += 0.5 * tp.k_w * zb[tp.n_f - 1].powi(2);
        let mut y = vec![0.0; tp.n_m];
        for i in 0..4 {
            self.rail.shapes_at(wheel_x[i], &mut y);
            let delta = z[FIRST_WHEEL + i] - Rail::displacement(&y, q);
            potential += match self.contact {
                ContactLaw::Linear { stiffness, preload } => {
                    preload * delta + 0.5 * stiffness * delta * delta
                }
                ContactLaw::Hertz => {
                    if delta > 0.0 {
                        0.4 * delta.powf(2.5) / self.hertz_g.powf(1.5)
                    } else {
                        0.0
                    }
                }
            };
            potential -= veh.w * z[FIRST_WHEEL + i];
        }
        kinetic + potential
    }
}

fn check_wheels(t: f64, w: &Wheels, a: &[f64]) -> std::result::Result<(), Failure> {
    if let Some(i) = w.p.iter().position(|p| !p.is_finite()) {
        return Err(Failure {
            t,
            reason: format!(
                "non-finite contact force p_{} = {} at t = {t:.4} s",
                i + 1,
                w.p[i]
            ),
        });
    }
    if let Some(i) = a[..NUM_DOFS].iter().position(|x| !x.is_finite()) {
        return Err(Failure {
            t,
            reason: format!(
                "non-finite vehicle acceleration (dof {}) = {} at t = {t:.4} s",
                i + 1,
                a[i]
            ),
        });
    }
    Ok(())
}

fn check_state(t: f64, x: &[f64], v: &[f64], a: &[f64]) -> std::result::Result<(), Failure> {
    // Any NaN or infinity makes the sum non-finite (an overflow of finite values too, which is
    // just as much a blow-up at these magnitudes).
    for (name, s) in [("displacement", x), ("velocity", v), ("acceleration", a)] {
        if !s.iter().sum::<f64>().is_finite() {
            let i = s.iter().position(|x| !x.is_finite()).unwrap_or(0);
            return Err(Failure {
                t,
                reason: format!(
                    "non-finite track/vehicle {name} (state index {i}) at t = {t:.4} s"
                ),
            });
        }
    }
    Ok(())
}

/// One sample to simulate: its id, parameters and irregularity profile.
#[derive(Debug, Clone)]
pub struct SampleInput {
    /// Sample id.
    pub id: u64,
    /// The 14 parameters.
    pub params: SampleParams,
    /// Its irregularity profile (`None`: a perfectly smooth track).
    pub profile: Option<Profile>,
}

/// Builds every sample's model in parallel, checking the configuration, the parameters,
/// the time step and the profile coverage of each before anything runs. The error of the
/// first bad sample (in input order) is returned, prefixed with its id.
pub fn prepare(
    config: &SimulationConfig,
    inputs: Vec<SampleInput>,
) -> std::result::Result<Vec<(u64, Simulation)>, (u64, Error)> {
    use rayon::prelude::*;
    config
        .validate()
        .map_err(|e| (inputs.first().map_or(0, |s| s.id), e))?;
    inputs
        .into_par_iter()
        .map(|s| {
            Simulation::new(&s.params, config, s.profile)
                .map(|sim| (s.id, sim))
                .map_err(|e| (s.id, e))
        })
        .collect()
}

/// Runs prepared samples in parallel (rayon), `chunk` at a time, and hands each outcome to
/// `sink` in input order (so the output never depends on the thread count). `done` is called
/// once per finished sample from the worker threads (progress reporting). Memory holds at most
/// `chunk` trajectories.
pub fn run_all<E>(
    sims: &[(u64, Simulation)],
    chunk: usize,
    done: &(dyn Fn() + Sync),
    mut sink: impl FnMut(u64, std::result::Result<Trajectory, Failure>) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    use rayon::prelude::*;
    for block in sims.chunks(chunk.max(1)) {
        let outcomes: Vec<_> = block
            .par_iter()
            .map(|(id, sim)| {
                let out = sim.run();
                done();
                (*id, out)
            })
            .collect();
        for (id, out) in outcomes {
            sink(id, out)?;
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "simulation_tests.rs"]
mod tests;
