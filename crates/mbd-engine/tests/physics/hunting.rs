//! Linear stability: a suspended wheelset and a two-axle bogie, each on rigid rails.
//!
//! The test writes out the equations of `docs/model.md` ("Wheelset on two rails") itself:
//! every spring-damper's generalised forces from its incidence `(e, r x e)` (small rotations),
//! every wheel's Hertz load, creepages, Kalker forces with the Shen-Hedrick-Elkins factor, the
//! normal force's lateral part; linearises them about the equilibrium (central differences of
//! this transcription, not of the engine) and takes the eigenvalues of the first-order system
//! with nalgebra. The critical speed is where the largest real part crosses zero (bisection).
//! The engine, started from its equilibrium with a 10 micrometre lateral shift (creep far from
//! saturation, the response linear), must decay at 0.99 of that speed and grow at 1.01 of it,
//! and its growth rate must have the sign of the eigenvalue's real part and its size within 5 %
//! (measured: 0.1-0.3 %; the suspended wheelset's critical speed is 70.0 m/s, the bogie's 43.5
//! m/s).
//!
//! The only values taken from the engine are the creep coefficients per unit load
//! ([`mbd_engine::wheel::Creep::of`]: the Hertz ellipse and Kalker's table, checked against
//! closed forms in `wheelset.rs` and the crate's unit tests).

use crate::common::{config, load};
use crate::wheelset::{col, run_perturbed, AXLE_LOAD, E0, HERTZ, R0};
use mbd_engine::wheel::Creep;
use mbd_engine::{Engine, Route, StartMode};
use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

/// One rigid DOF of the transcription: `(body, kind)` with `kind` 0..6 for `x, y, z, roll,
/// pitch, yaw` (the order of the incidence `(e, r x e)`).
type Dof = (usize, usize);

/// A spring-damper of the transcription: from body point `(body, r)` to body point or ground,
/// along the unit vector `e`.
struct Spring {
    from: (usize, [f64; 3]),
    to: Option<(usize, [f64; 3])>,
    e: [f64; 3],
    k: f64,
    c: f64,
}

/// A vehicle of the transcription: bodies' DOFs, masses, springs, wheelsets (body index).
struct Vehicle {
    dofs: Vec<Dof>,
    mass: Vec<f64>,
    springs: Vec<Spring>,
    wheelsets: Vec<usize>,
    conicity: f64,
    creep: Creep,
}

fn incidence(r: [f64; 3], e: [f64; 3]) -> [f64; 6] {
    [
        e[0],
        e[1],
        e[2],
        r[1] * e[2] - r[2] * e[1],
        r[2] * e[0] - r[0] * e[2],
        r[0] * e[1] - r[1] * e[0],
    ]
}

impl Vehicle {
    fn index(&self, body: usize, kind: usize) -> Option<usize> {
        self.dofs.iter().position(|d| *d == (body, kind))
    }

    /// `K` and `C` of the springs: `sum k b b^T`.
    fn springs(&self) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = self.dofs.len();
        let (mut k, mut c) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        for s in &self.springs {
            let mut b = DVector::zeros(n);
            for (end, sign) in [(Some(s.from), 1.0), (s.to, -1.0)] {
                let Some((body, r)) = end else { continue };
                for (kind, v) in incidence(r, s.e).iter().enumerate() {
                    if let Some(i) = self.index(body, kind) {
                        b[i] += sign * v;
                    }
                }
            }
            k += s.k * &b * b.transpose();
            c += s.c * &b * b.transpose();
        }
        (k, c)
    }

    /// The wheels' generalised forces (and the axle loads) at `(q, qd)`, speed `v`.
    fn wheel_forces(&self, q: &[f64], qd: &[f64], v: f64) -> Vec<f64> {
        let mut out = vec![0.0; q.len()];
        let g = self.conicity;
        let sin_delta = g.atan().sin();
        for &w in &self.wheelsets {
            let at = |kind| self.index(w, kind).expect("a wheelset DOF");
            let (iy, iz, iphi, ipsi) = (at(1), at(2), at(3), at(5));
            out[iz] += AXLE_LOAD;
            for s in [-1.0f64, 1.0] {
                let u = s * q[iy];
                let d = q[iz] + s * E0 * q[iphi] + g * u;
                let load = if d > 0.0 { (d / HERTZ).powf(1.5) } else { 0.0 };
                let (f11, f22, f23) = (
                    self.creep.k11 * load.powf(2.0 / 3.0),
                    self.creep.k22 * load.powf(2.0 / 3.0),
                    self.creep.k23 * load,
                );
                let xi_x = -g * u / R0 - s * E0 * qd[ipsi] / v;
                let xi_y = (qd[iy] - R0 * qd[iphi]) / v - q[ipsi];
                let spin = qd[ipsi] / v - s * sin_delta / R0;
                let (mut fx, mut fy, mut mz) = (-f11 * xi_x, -f22 * xi_y - f23 * spin, f23 * xi_y);
                let x = fx.hypot(fy) / (self.creep.friction * load);
                let eps = if x <= 3.0 {
                    1.0 - x / 3.0 + x * x / 27.0
                } else {
                    1.0 / x
                };
                fx *= eps;
                fy *= eps;
                mz *= eps;
                let lateral = fy - s * load * (g.atan() - s * q[iphi]).tan();
                out[iy] += lateral;
                out[iz] -= load;
                out[iphi] += -s * E0 * load - R0 * lateral;
                out[ipsi] += -s * E0 * fx + mz;
            }
        }
        out
    }

    /// The equilibrium: every wheelset at the Hertz compression of its wheel load.
    fn equilibrium(&self) -> Vec<f64> {
        let mut q = vec![0.0; self.dofs.len()];
        for &w in &self.wheelsets {
            q[self.index(w, 2).unwrap()] = HERTZ * (AXLE_LOAD / 2.0).powf(2.0 / 3.0);
        }
        q
    }

    /// The largest real part of the eigenvalues of the linearised system at speed `v`.
    fn growth(&self, v: f64) -> f64 {
        let n = self.dofs.len();
        let q0 = self.equilibrium();
        let zero = vec![0.0; n];
        let f0 = self.wheel_forces(&q0, &zero, v);
        assert!(
            f0.iter().all(|f| f.abs() < 1e-6 * AXLE_LOAD),
            "not an equilibrium: {f0:?}"
        );
        let (ks, cs) = self.springs();
        let (mut k, mut c) = (ks, cs);
        for j in 0..n {
            for (is_rate, h) in [(false, 1e-9), (true, 1e-7)] {
                let (mut qp, mut qm) = (q0.clone(), q0.clone());
                let (mut dp, mut dm) = (zero.clone(), zero.clone());
                if is_rate {
                    dp[j] += h;
                    dm[j] -= h;
                } else {
                    qp[j] += h;
                    qm[j] -= h;
                }
                let fp = self.wheel_forces(&qp, &dp, v);
                let fm = self.wheel_forces(&qm, &dm, v);
                for i in 0..n {
                    let derivative = -(fp[i] - fm[i]) / (2.0 * h);
                    if is_rate {
                        c[(i, j)] += derivative;
                    } else {
                        k[(i, j)] += derivative;
                    }
                }
            }
        }
        let mut a = DMatrix::zeros(2 * n, 2 * n);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
            for j in 0..n {
                a[(n + i, j)] = -k[(i, j)] / self.mass[i];
                a[(n + i, n + j)] = -c[(i, j)] / self.mass[i];
            }
        }
        // The wheelsets' bounce on their Hertz springs is undamped (nothing dissipates
        // vertically): its eigenvalues sit on the imaginary axis, their real parts round-off.
        a.complex_eigenvalues()
            .iter()
            .map(|l| l.re)
            .filter(|re| re.abs() > 1e-6)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The critical speed: bisection of the growth's sign between `lo` (stable) and `hi`.
    fn critical_speed(&self, lo: f64, hi: f64) -> f64 {
        assert!(self.growth(lo) < 0.0, "stable at {lo} m/s");
        assert!(self.growth(hi) > 0.0, "unstable at {hi} m/s");
        let (mut lo, mut hi) = (lo, hi);
        while hi - lo > 1e-5 * hi {
            let mid = 0.5 * (lo + hi);
            if self.growth(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// The growth rate (1/s) of `y` in a run: the slope of the log of its half-cycle peaks over
/// the second half of the run (least squares).
fn measured_growth(t: &[f64], y: &[f64]) -> f64 {
    let start = t.len() / 2;
    let mut peaks = Vec::new();
    let mut i = start + 1;
    while i + 1 < t.len() {
        if y[i].abs() >= y[i - 1].abs() && y[i].abs() > y[i + 1].abs() && y[i].abs() > 0.0 {
            peaks.push((t[i], y[i].abs().ln()));
        }
        i += 1;
    }
    assert!(peaks.len() >= 6, "{} peaks", peaks.len());
    let n = peaks.len() as f64;
    let (mt, ml) = peaks
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, l)| (a + t / n, b + l / n));
    let (num, den) = peaks.iter().fold((0.0, 0.0), |(a, b), (t, l)| {
        (a + (t - mt) * (l - ml), b + (t - mt) * (t - mt))
    });
    num / den
}

/// The engine at speed `v` from its equilibrium with `y` of the first wheelset shifted 10 um:
/// the growth rate of that wheelset's lateral motion.
fn engine_growth(system: &Arc<mbd_system::System>, duration: f64) -> f64 {
    let model = system.instantiate(&system.nominal()).unwrap();
    let cfg = config(duration, 1e-4, 20, StartMode::Equilibrium, 0.0);
    let engine = Engine::with_route(system.clone(), model, &cfg, vec![], Route::Fast)
        .unwrap_or_else(|e| panic!("{e}"));
    let y = engine.system().channel("y_w1").unwrap();
    let (t, cols) = run_perturbed(&engine, &[(y, 1e-5)]);
    measured_growth(&t, col(&engine, &cols, "y_w1"))
}

const CREEP: &str = "{young: 2.06e+11, poisson: 0.3, friction: 0.4, rail_radius: 0.3}";

/// The wheelset `w<i>` and its contact, text of a description.
fn wheelset_yaml(i: usize) -> (String, String) {
    (
        format!("  w{i}:\n    mass: 1500\n    inertia: {{roll: 900, yaw: 900}}\n    dofs: [y, z, roll, yaw]\n    points: {{left: [0, -1.0, 0], right: [0, 1.0, 0]}}\n"),
        format!("  ws{i}:\n    kind: wheelset\n    from: w{i}\n    rails: [rail, rail]\n    half_gauge: {E0}\n    radius: {R0}\n    hertz: {HERTZ:e}\n    conicity: gamma\n    creep: {CREEP}\n    flange: {{clearance: 0.008, stiffness: 1.5e+7}}\n"),
    )
}

/// The creep coefficients the engine uses for these wheels.
fn creep(system: &mbd_system::System) -> Creep {
    let model = system.instantiate(&system.nominal()).unwrap();
    let w = model.elements.iter().find_map(|e| e.law.wheel()).unwrap();
    Creep::of(w, "ws1").unwrap()
}

const GAMMA: f64 = 0.15;

/// A wheelset held laterally and in yaw by springs (and laterally by dampers) to a frame
/// moving at the speed (the ground of the moving frame).
fn suspended(v: f64) -> (Arc<mbd_system::System>, Vehicle) {
    let (body, contact) = wheelset_yaml(1);
    let (k_y, c_y, k_x) = (3.0e5, 2.0e3, 1.5e6);
    let text = format!(
        "format: 1\nname: suspended wheelset\nparameters:\n  v: {{unit: m/s, value: {v:e}}}\n  gamma: {{unit: rad, value: {GAMMA}}}\nbodies:\n{body}moving:\n  speed: v\n  points:\n    rail: {{on: ground, offset: 0}}\nelements:\n{contact}  yl: {{kind: spring_damper, direction: y, from: w1.left, to: ground, k: {k_y:e}, c: {c_y:e}}}\n  yr: {{kind: spring_damper, direction: y, from: w1.right, to: ground, k: {k_y:e}, c: {c_y:e}}}\n  xl: {{kind: spring_damper, direction: x, from: w1.left, to: ground, k: {k_x:e}}}\n  xr: {{kind: spring_damper, direction: x, from: w1.right, to: ground, k: {k_x:e}}}\nloads:\n  weight: {{at: w1, force: {AXLE_LOAD:e}}}\n"
    );
    let system = load(&text, &[]);
    let (x, y) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let vehicle = Vehicle {
        dofs: vec![(0, 1), (0, 2), (0, 3), (0, 5)],
        mass: vec![1500.0, 1500.0, 900.0, 900.0],
        springs: [-1.0, 1.0]
            .iter()
            .flat_map(|&s| {
                [
                    Spring {
                        from: (0, [0.0, s, 0.0]),
                        to: None,
                        e: y,
                        k: k_y,
                        c: c_y,
                    },
                    Spring {
                        from: (0, [0.0, s, 0.0]),
                        to: None,
                        e: x,
                        k: k_x,
                        c: 0.0,
                    },
                ]
            })
            .collect(),
        wheelsets: vec![0],
        conicity: GAMMA,
        creep: creep(&system),
    };
    (system, vehicle)
}

/// A two-axle bogie frame (lateral and yaw) on two wheelsets through primary springs at the
/// axle boxes, held to the (moving) car body by a lateral spring and two yaw dampers.
fn bogie(v: f64) -> (Arc<mbd_system::System>, Vehicle) {
    let (a, b, bs) = (1.25, 1.0, 1.2);
    let (k_px, k_py, k_sy, c_yaw) = (4.0e6, 1.0e6, 3.0e5, 6.0e4);
    let (b1, c1) = wheelset_yaml(1);
    let (b2, c2) = wheelset_yaml(2);
    let mut text = format!(
        "format: 1\nname: bogie\nparameters:\n  v: {{unit: m/s, value: {v:e}}}\n  gamma: {{unit: rad, value: {GAMMA}}}\nbodies:\n{b1}{b2}  f:\n    mass: 2500\n    inertia: {{yaw: 2600}}\n    dofs: [y, yaw]\n    points: {{fl: [{a}, -{b}, 0], fr: [{a}, {b}, 0], rl: [-{a}, -{b}, 0], rr: [-{a}, {b}, 0], dl: [0, -{bs}, 0], dr: [0, {bs}, 0]}}\nmoving:\n  speed: v\n  points:\n    rail: {{on: ground, offset: 0}}\nelements:\n{c1}{c2}"
    );
    for (w, front) in [(1, "f"), (2, "r")] {
        for side in ["l", "r"] {
            let wp = if side == "l" { "left" } else { "right" };
            for (dir, k) in [("x", k_px), ("y", k_py)] {
                text += &format!("  p{dir}{w}{side}: {{kind: spring_damper, direction: {dir}, from: f.{front}{side}, to: w{w}.{wp}, k: {k:e}}}\n");
            }
        }
    }
    text += &format!("  sy: {{kind: spring_damper, direction: y, from: f, to: ground, k: {k_sy:e}}}\n  dl: {{kind: spring_damper, direction: x, from: f.dl, to: ground, k: 0, c: {c_yaw:e}}}\n  dr: {{kind: spring_damper, direction: x, from: f.dr, to: ground, k: 0, c: {c_yaw:e}}}\n");
    text += &format!(
        "loads:\n  w1: {{at: w1, force: {AXLE_LOAD:e}}}\n  w2: {{at: w2, force: {AXLE_LOAD:e}}}\n"
    );
    let system = load(&text, &[]);
    let (x, y) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
    let mut springs = Vec::new();
    for (w, xa) in [(0, a), (1, -a)] {
        for s in [-1.0, 1.0] {
            for (e, k) in [(x, k_px), (y, k_py)] {
                springs.push(Spring {
                    from: (2, [xa, s * b, 0.0]),
                    to: Some((w, [0.0, s * b, 0.0])),
                    e,
                    k,
                    c: 0.0,
                });
            }
        }
    }
    springs.push(Spring {
        from: (2, [0.0; 3]),
        to: None,
        e: y,
        k: k_sy,
        c: 0.0,
    });
    for s in [-1.0, 1.0] {
        springs.push(Spring {
            from: (2, [0.0, s * bs, 0.0]),
            to: None,
            e: x,
            k: 0.0,
            c: c_yaw,
        });
    }
    let mut dofs = Vec::new();
    let mut mass = Vec::new();
    for w in 0..2 {
        dofs.extend([(w, 1), (w, 2), (w, 3), (w, 5)]);
        mass.extend([1500.0, 1500.0, 900.0, 900.0]);
    }
    dofs.extend([(2, 1), (2, 5)]);
    mass.extend([2500.0, 2600.0]);
    let vehicle = Vehicle {
        dofs,
        mass,
        springs,
        wheelsets: vec![0, 1],
        conicity: GAMMA,
        creep: creep(&system),
    };
    (system, vehicle)
}

/// Decays at 0.99 of the critical speed, grows at 1.01 of it, at the eigenvalue's rate.
fn check_critical_speed(build: impl Fn(f64) -> (Arc<mbd_system::System>, Vehicle), duration: f64) {
    let (_, vehicle) = build(10.0);
    let vc = vehicle.critical_speed(5.0, 300.0);
    assert!(vc > 15.0 && vc < 250.0, "critical speed {vc} m/s");
    for factor in [0.99, 1.01] {
        let v = factor * vc;
        let (system, vehicle) = build(v);
        let want = vehicle.growth(v);
        let got = engine_growth(&system, duration);
        assert!(
            got.signum() == want.signum() && (got - want).abs() < 0.05 * want.abs(),
            "at {factor} x {vc:.3} m/s: engine growth {got:.5} 1/s, eigenvalue {want:.5} 1/s"
        );
    }
}

#[test]
fn suspended_wheelset_critical_speed() {
    check_critical_speed(suspended, 30.0);
}

#[test]
fn bogie_critical_speed() {
    check_critical_speed(bogie, 30.0);
}
