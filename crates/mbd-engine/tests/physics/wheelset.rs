//! A wheelset on two rails (`kind: wheelset`) against closed forms: Klingel's kinematic
//! wavelength, Kalker's linear creep at small creepage and the friction limit at large, creep
//! that never generates energy, flange contact under a lateral load no creep can hold, and the
//! solver's second order in `dt` with the contact's smooth laws.
//!
//! The wheelset runs on rigid rails (moving points on the ground) under its axle load `2 W`;
//! its DOFs are `y`, `z`, roll and yaw; vertical dampers at its axle boxes (0.5 % of critical
//! on the Hertz contacts) stand for the primary dampers, so its bounce does not ring for ever. [`wheelset`] writes the description with the few
//! values each test changes.

use crate::common::{config, load};
use mbd_engine::wheel::{Wheel, WheelMotion};
use mbd_engine::{Engine, Route, StartMode};
use mbd_system::System;
use std::sync::Arc;

/// Nominal rolling radius (m), half the distance of the contact points (m), axle load (N).
pub const R0: f64 = 0.46;
/// See [`R0`].
pub const E0: f64 = 0.75;
/// See [`R0`].
pub const AXLE_LOAD: f64 = 1.4e5;
/// Hertz constant of each wheel (m/N^(2/3)).
pub const HERTZ: f64 = 5.0e-8;

/// The values a test sets.
#[derive(Debug, Clone, Copy)]
pub struct Setup {
    /// Speed (m/s).
    pub speed: f64,
    /// Equivalent conicity (rad).
    pub conicity: f64,
    /// Lateral stiffness of each of the two suspension springs to the ground (N/m).
    pub k_y: f64,
    /// Longitudinal stiffness of each (N/m), at `+-b` from the centre.
    pub k_x: f64,
    /// Lateral damping of each (N s/m).
    pub c_y: f64,
    /// A constant lateral force on the wheelset (N, to the right).
    pub side: f64,
    /// Flange clearance (m).
    pub clearance: f64,
}

impl Default for Setup {
    fn default() -> Self {
        Self {
            speed: 30.0,
            conicity: 0.1,
            k_y: 0.0,
            k_x: 0.0,
            c_y: 0.0,
            side: 0.0,
            clearance: 0.008,
        }
    }
}

/// The wheelset description of `s`.
pub fn wheelset(s: &Setup) -> Arc<System> {
    let text = format!(
        r#"format: 1
name: wheelset on rigid rails
parameters:
  v: {{unit: m/s, value: {v:e}}}
  gamma: {{unit: rad, value: {gamma:e}}}
  k_y: {{unit: N/m, value: {k_y:e}}}
  k_x: {{unit: N/m, value: {k_x:e}}}
  c_y: {{unit: N s/m, value: {c_y:e}}}
  side: {{unit: N, value: {side:e}}}
  clearance: {{unit: m, value: {clearance:e}}}
bodies:
  w:
    mass: 1500
    inertia: {{roll: 900, yaw: 900}}
    dofs: [y, z, roll, yaw]
    points: {{left: [0, -1.0, 0], right: [0, 1.0, 0]}}
moving:
  speed: v
  points:
    rail: {{on: ground, offset: 0}}
elements:
  ws:
    kind: wheelset
    from: w
    rails: [rail, rail]
    half_gauge: {E0}
    radius: {R0}
    hertz: {HERTZ:e}
    conicity: gamma
    creep: {{young: 2.06e+11, poisson: 0.3, friction: 0.4, rail_radius: 0.3}}
    flange: {{clearance: clearance, stiffness: 1.5e+7}}
  y_l: {{kind: spring_damper, direction: y, from: w.left, to: ground, k: k_y, c: c_y}}
  y_r: {{kind: spring_damper, direction: y, from: w.right, to: ground, k: k_y, c: c_y}}
  x_l: {{kind: spring_damper, direction: x, from: w.left, to: ground, k: k_x}}
  x_r: {{kind: spring_damper, direction: x, from: w.right, to: ground, k: k_x}}
  z_l: {{kind: spring_damper, from: w.left, to: ground, k: 0, c: 2.0e+4}}
  z_r: {{kind: spring_damper, from: w.right, to: ground, k: 0, c: 2.0e+4}}
loads:
  weight: {{at: w, force: {AXLE_LOAD:e}}}
  push: {{at: w, force: side, direction: y}}
outputs: [p_ws_l, p_ws_r, fy_ws_l, fy_ws_r, ff_ws_l, ff_ws_r, dy_ws_r]
"#,
        v = s.speed,
        gamma = s.conicity,
        k_y = s.k_y,
        k_x = s.k_x,
        c_y = s.c_y,
        side = s.side,
        clearance = s.clearance,
    );
    load(&text, &[])
}

/// The engine of a setup with the run controls `(duration, dt, output_every)`, started from
/// the equilibrium.
pub fn engine(s: &Setup, duration: f64, dt: f64, every: usize) -> Engine {
    let system = wheelset(s);
    let model = system.instantiate(&system.nominal()).unwrap();
    let cfg = config(duration, dt, every, StartMode::Equilibrium, 0.0);
    Engine::with_route(system, model, &cfg, vec![], Route::Fast).unwrap_or_else(|e| panic!("{e}"))
}

/// The stored rows of `engine` from its equilibrium with `perturb` added to the state
/// (`(state index, displacement)`), as `(t, columns)`.
pub fn run_perturbed(engine: &Engine, perturb: &[(usize, f64)]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let mut x = engine.initial_state().unwrap();
    for &(i, d) in perturb {
        x[i] += d;
    }
    let v = vec![0.0; x.len()];
    let c = engine.config();
    let every = c.output_every;
    let steps = (c.n_outputs() - 1) * every;
    let channels = engine.system().channels.clone();
    let mut t = Vec::new();
    let mut cols = vec![Vec::new(); channels.len()];
    engine
        .run_observed_from(x, v, steps, None, |s| {
            if s.step % every == 0 {
                t.push(s.t);
                for (col, ch) in cols.iter_mut().zip(&channels) {
                    col.push(engine.channel_value(ch.quantity, s));
                }
            }
        })
        .unwrap_or_else(|f| panic!("{}", f.reason));
    (t, cols)
}

/// The column `name` of a run.
pub fn col<'a>(engine: &Engine, cols: &'a [Vec<f64>], name: &str) -> &'a [f64] {
    &cols[engine
        .system()
        .channel(name)
        .unwrap_or_else(|| panic!("no {name}"))]
}

/// Times of the zero crossings of `y` (linear between rows), after `from` (s).
fn crossings(t: &[f64], y: &[f64], from: f64) -> Vec<f64> {
    (1..t.len())
        .filter(|&i| t[i] > from && (y[i - 1] < 0.0) != (y[i] < 0.0))
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * y[i - 1] / (y[i - 1] - y[i]))
        .collect()
}

/// The kinematic wavelength (m) of a free wheelset of conicity `gamma` rolling at `speed`:
/// the distance between every other zero crossing of its lateral shift, from 1 mm.
fn free_wavelength(conicity: f64, speed: f64, periods: f64) -> f64 {
    let s = Setup {
        speed,
        conicity,
        ..Setup::default()
    };
    let klingel = 2.0 * std::f64::consts::PI * (R0 * E0 / conicity).sqrt();
    let e = engine(&s, periods * klingel / speed, 2e-5, 50);
    let (t, cols) = run_perturbed(&e, &[(0, 1e-3)]);
    let y = col(&e, &cols, "y_w");
    let amplitude = y.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    assert!(
        amplitude > 0.5e-3 && amplitude < 5e-3,
        "amplitude {amplitude}"
    );
    let zeros = crossings(&t, y, 0.0);
    assert!(zeros.len() >= 6, "{} crossings", zeros.len());
    let half = (zeros[zeros.len() - 1] - zeros[0]) / (zeros.len() - 1) as f64;
    2.0 * half * speed
}

/// Klingel: a free wheelset with a linear conicity, shifted 1 mm and rolling slowly, follows a
/// sinusoid of wavelength `2 pi sqrt(r0 e0 / gamma)` whatever its speed. Pure rolling of the
/// contact points (`xi_x = xi_y = 0`) gives it once the axle's roll is counted: shifted by
/// `y` the wheelset rolls by `-gamma y / e0`, which moves the contact points, `r0` below the
/// axle, laterally by `r0 gamma / e0` times as much again, so the wavelength is Klingel's
/// times `sqrt(1 + gamma r0 / e0)`. Measured against that to 0.2 % (creep, gravitational
/// stiffness and inertia move it by less at these speeds), independent of the speed to 0.1 %,
/// and against Klingel's own formula within 1 % where the roll's share is below it.
#[test]
fn klingel_wavelength() {
    for (conicity, speed) in [(0.05, 3.0), (0.2, 2.0)] {
        let klingel = 2.0 * std::f64::consts::PI * (R0 * E0 / conicity).sqrt();
        let want = klingel * (1.0 + conicity * R0 / E0).sqrt();
        let got = free_wavelength(conicity, speed, 4.5);
        assert!(
            (got - want).abs() < 2e-3 * want,
            "gamma {conicity}: wavelength {got} m, Klingel with the axle's roll {want} m"
        );
        if conicity == 0.05 {
            let slower = free_wavelength(conicity, 0.5 * speed, 3.2);
            assert!(
                (slower - got).abs() < 1e-3 * got,
                "{slower} at half the speed, {got}"
            );
        }
    }
    let conicity = 0.02;
    let klingel = 2.0 * std::f64::consts::PI * (R0 * E0 / conicity).sqrt();
    let got = free_wavelength(conicity, 4.0, 3.5);
    assert!(
        (got - klingel).abs() < 0.01 * klingel,
        "gamma {conicity}: wavelength {got} m, Klingel {klingel} m"
    );
}

/// A wheel of a hollow tread whose contact is a circle (the curvatures along and across the
/// rail are equal: `1/(2 r0) = 1/(2 R_rail) + 1/(2 R_tread)`), with no contact angle, on a
/// material of Poisson's ratio 1/4 (a node of Kalker's table).
fn circular_wheel() -> (Wheel, f64, f64) {
    let r_tread = 1.0 / (1.0 / R0 - 1.0 / 0.3);
    let system = wheelset(&Setup::default());
    let mut model = system.instantiate(&system.nominal()).unwrap();
    let Some(mbd_system::model::ModelLaw::Wheel(w)) = Some(model.elements[1].law.clone()) else {
        panic!("the right wheel")
    };
    let mut w = *w;
    w.geometry = mbd_system::model::ModelGeometry::Table {
        shift: vec![-0.1, 0.1],
        radius: vec![0.0, 0.0],
        angle: vec![0.0, 0.0],
    };
    w.poisson = 0.25;
    w.wheel_profile_radius = Some(r_tread);
    model.elements[1].law = mbd_system::model::ModelLaw::Wheel(Box::new(w.clone()));
    let wheel = Wheel::of(&w, "ws").unwrap();
    // Hertz's circle and Kalker's coefficients at a/b = 1, nu = 1/4, written out.
    let e_star = 2.06e11 / (2.0 * (1.0 - 0.25 * 0.25));
    let shear = 2.06e11 / (2.0 * 1.25);
    let q = 7.0e4;
    let a = (3.0 * q / (8.0 * (0.5 / R0) * e_star)).cbrt();
    (wheel, shear * a * a * 4.12, shear * a * a * 3.67)
}

/// Kalker's linear theory at small creepage, `mu Q` at large, never more: the wheel's creep
/// forces against `f11 = G a^2 C11`, `f22 = G a^2 C22` of the circular contact.
#[test]
fn creep_is_linear_small_and_saturates_at_mu_q() {
    let (wheel, f11, f22) = circular_wheel();
    let (q, speed) = (7.0e4, 30.0);
    let motion = |shift_rate: f64, yaw: f64, yaw_rate: f64| WheelMotion {
        shift: 0.0,
        shift_rate,
        roll: 0.0,
        roll_rate: 0.0,
        yaw,
        yaw_rate,
    };
    // Lateral creepage xi_y = -psi = 1e-7: F_y = f22 1e-7 within the saturation's x/3
    // (x = |F| / (mu Q) ~ 4e-6 here).
    let f = wheel.forces(q, &motion(0.0, -1e-7, 0.0), speed);
    let linear = -f22 * 1e-7;
    assert!(
        (f.lateral - linear).abs() < 1e-4 * linear.abs(),
        "{} vs {linear}",
        f.lateral
    );
    // Longitudinal creepage from the yaw rate: xi_x = -s e0 psi' / V (right wheel, s = 1).
    let yaw_rate = 30.0 * 1e-7 / E0;
    let f = wheel.forces(q, &motion(0.0, 0.0, yaw_rate), speed);
    let linear = f11 * 1e-7;
    assert!(
        (f.longitudinal - linear).abs() < 1e-4 * linear,
        "{} vs {linear}",
        f.longitudinal
    );
    // Saturation: the resultant rises to mu Q and stays there.
    let limit = 0.4 * q;
    let mut last = 0.0;
    for k in 1..=60 {
        let xi = 1e-4 * 1.2f64.powi(k);
        let f = wheel.forces(q, &motion(0.0, -xi, 0.0), speed);
        let resultant = f.lateral.hypot(f.longitudinal);
        assert!(
            resultant <= limit * (1.0 + 1e-12) && resultant >= last * (1.0 - 1e-12),
            "xi {xi}"
        );
        last = resultant;
    }
    assert!((last - limit).abs() < 1e-9 * limit, "{last} vs {limit}");
}

/// The power the creep forces take out of the motion, `-V (F_x xi_x + F_y xi_y + M_z spin)`,
/// is never negative, for creepages of every sign and size, spin included (a contact angle).
#[test]
fn creep_never_generates_energy() {
    let (mut wheel, _, _) = circular_wheel();
    wheel.geometry = mbd_engine::wheel::Geometry::Table {
        shift: vec![-0.1, 0.1],
        radius: vec![-0.01, 0.01],
        angle: vec![-0.3, 0.3],
    };
    let speed = 30.0;
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut worst = f64::INFINITY;
    for _ in 0..20000 {
        let scale = 10f64.powf(-6.0 + 5.0 * (uniform() + 1.0) / 2.0);
        let m = WheelMotion {
            shift: 0.05 * uniform(),
            shift_rate: speed * scale * uniform(),
            roll: 0.0,
            roll_rate: 0.0,
            yaw: scale * uniform(),
            yaw_rate: speed * scale * uniform(),
        };
        let q = 3e4 + 8e4 * (uniform() + 1.0) / 2.0;
        let f = wheel.forces(q, &m, speed);
        // The creepages written out (docs/model.md), right wheel.
        let u = m.shift;
        let (rho, delta) = (0.01 * u / 0.1, 0.3 * u / 0.1);
        let xi_x = -rho / R0 - E0 * m.yaw_rate / speed;
        let xi_y = m.shift_rate / speed - m.yaw;
        let spin = m.yaw_rate / speed - delta.sin() / R0;
        // The creep part of the lateral force: the total less the normal force's and the
        // flange's (right wheel: `F_Y = F_y + N_y - F_fl`).
        let normal = -q * delta.tan();
        let fy = f.lateral - normal + f.flange;
        let power = -speed * (f.longitudinal * xi_x + fy * xi_y + f.moment * spin);
        let scale = speed
            * (f.longitudinal.abs() * xi_x.abs()
                + fy.abs() * xi_y.abs()
                + f.moment.abs() * spin.abs());
        worst = worst.min(power / scale.max(1e-300));
        assert!(power >= -1e-9 * scale, "power {power} at {m:?}, q {q}");
    }
    assert!(
        worst < 0.5,
        "the sample must include coupled creepages ({worst})"
    );
}

/// Flange contact: a lateral force of 70 kN, half the axle load, beyond what creep can hold
/// (a yawed wheelset rolls against a steady load with lateral creep, at most `mu (Q_L + Q_R)
/// = 56 kN`) and what the gravitational stiffness holds (`2 W gamma / e0 ~ 1.9 kN` at the
/// clearance), applied as a step to the wheelset in equilibrium, drives the right wheel's
/// flange onto its rail: the shift passes the clearance, the flange takes what creep cannot,
/// the track takes the whole load as the wheelset's lateral force `Y_R - Y_L` (the flange
/// force part of the right wheel's `Y`), and the right wheel's derailment quotient `Y/Q`
/// rises from its small static value by more than half the load over the wheel load.
#[test]
fn a_lateral_load_beyond_creep_brings_the_flange_into_contact() {
    let side = 7.0e4;
    let free = Setup {
        k_x: 5.0e6,
        ..Setup::default()
    };
    let loaded = Setup { side, ..free };
    let start = engine(&free, 0.01, 1e-4, 10).initial_state().unwrap();
    let e = engine(&loaded, 3.0, 1e-4, 10);
    let mut perturb: Vec<(usize, f64)> = Vec::new();
    let equilibrium = e.initial_state().unwrap();
    for (i, (a, b)) in start.iter().zip(&equilibrium).enumerate() {
        perturb.push((i, a - b));
    }
    let (t, cols) = run_perturbed(&e, &perturb);
    let last = t.len() - 1;
    let get = |name: &str| col(&e, &cols, name);
    let (yl, yr) = (get("fy_ws_l"), get("fy_ws_r"));
    let (ql, qr) = (get("p_ws_l"), get("p_ws_r"));
    let flange = get("ff_ws_r");
    // At rest: no flange, Y/Q small (the normal force's tan(delta) = gamma less the spin
    // creep force).
    assert_eq!(flange[0], 0.0);
    assert!((yr[0] / qr[0]).abs() < 0.1, "Y/Q at rest {}", yr[0] / qr[0]);
    // Settled on the flange.
    assert!(
        get("dy_ws_r")[last] > loaded.clearance,
        "shift {}",
        get("dy_ws_r")[last]
    );
    assert!(
        get("ff_ws_l")[last] == 0.0 && flange[last] > 0.1 * side,
        "flange {}",
        flange[last]
    );
    let h = yr[last] - yl[last];
    assert!(
        (h - side).abs() < 0.01 * side,
        "wheelset lateral force {h} N for a load of {side} N"
    );
    let rise = yr[last] / qr[last] - yr[0] / qr[0];
    assert!(rise > 0.5 * side / qr[last], "Y/Q rose by {rise}");
    assert!(
        ql[last] < qr[last],
        "the load moves onto the flanging wheel"
    );
}

/// Second order in `dt`: a suspended wheelset at 70 % of its critical speed, shifted 2 mm and
/// yawed 1 mrad from its equilibrium (creep well below saturation, the flange clear, every law
/// smooth), integrated at `dt`, `dt/2`, `dt/4`: the differences of successive solutions fall
/// at least 3.5 times per halving (4 for a second-order method), in the lateral shift, the yaw
/// and a wheel's load.
#[test]
fn second_order_in_dt() {
    let s = Setup {
        speed: 49.0,
        conicity: 0.15,
        k_y: 3.0e5,
        c_y: 2.0e3,
        k_x: 1.5e6,
        ..Setup::default()
    };
    let runs: Vec<(Engine, Vec<Vec<f64>>)> = [4e-5, 2e-5, 1e-5]
        .iter()
        .enumerate()
        .map(|(k, &dt)| {
            let e = engine(&s, 0.4, dt, 25 << k);
            let (_, cols) = run_perturbed(&e, &[(0, 2e-3), (3, 1e-3)]);
            (e, cols)
        })
        .collect();
    for name in ["y_w", "psi_w", "p_ws_r"] {
        let c: Vec<&[f64]> = runs.iter().map(|(e, cols)| col(e, cols, name)).collect();
        let diff = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        };
        let (e1, e2) = (diff(c[0], c[1]), diff(c[1], c[2]));
        let spread = c[2].iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            e2 > 1e-12 * spread,
            "{name}: differences must be measurable"
        );
        assert!(e1 / e2 >= 3.5, "{name}: ratio {} ({e1:e}, {e2:e})", e1 / e2);
    }
}
