//! A rigid body in space on springs along all three axes, against its modal solution written
//! out here.
//!
//! The block has all six DOFs; springs act vertically at four corners, laterally at two points
//! above and below the centre and longitudinally at two points beside it, so every DOF couples
//! to others through the lever arms. The test assembles the stiffness independently of the
//! description: a spring of stiffness `k` along the unit vector `e` at the point `r` has the
//! incidence `b = (e, r x e)` on `(x, y, z, roll, pitch, yaw)` (small rotations move `r` by
//! `theta x r`), `K = sum k b b^T`, and constant loads `f` along `e` at `r` give `F = f b`.
//! From rest under `F` the undamped response is `q(t) = sum_i phi_i (phi_i^T F) / w_i^2
//! (1 - cos w_i t)` with the mass-orthonormal modes of `K phi = w^2 M phi` (nalgebra); the
//! engine's must match it to Zhai's O((w dt)^2) (here about 1e-6 of the peak, tolerance 1e-4),
//! and the static equilibrium start must be `K^-1 F` with zero accelerations.

use crate::common::{column, config, load, replace_once, system_text};
use mbd_engine::{Engine, Route, StartMode};
use nalgebra::{DMatrix, DVector, SymmetricEigen};

const BLOCK: &str = r#"format: 1
name: block on springs
parameters:
  m: {unit: kg, nominal: 1200, range: [1000, 1400]}
bodies:
  b:
    mass: m
    inertia: {roll: 500, pitch: 900, yaw: 1100}
    dofs: [x, y, z, roll, pitch, yaw]
    points:
      c1: [1.2, 0.7, -0.3]
      c2: [-1.1, 0.6, 0.2]
      c3: [0.9, -0.8, 0.4]
      c4: [-1.0, -0.5, -0.6]
      top: [0.3, 0.1, -0.8]
      low: [-0.2, -0.3, 0.5]
elements:
  z1: {kind: spring_damper, from: b.c1, to: ground, k: 2.0e+5}
  z2: {kind: spring_damper, from: b.c2, to: ground, k: 3.0e+5}
  z3: {kind: spring_damper, from: b.c3, to: ground, k: 2.5e+5}
  z4: {kind: spring_damper, from: b.c4, to: ground, k: 1.5e+5}
  y1: {kind: spring_damper, direction: y, from: b.top, to: ground, k: 1.2e+5}
  y2: {kind: spring_damper, direction: y, from: b.low, to: ground, k: 0.8e+5}
  x1: {kind: spring_damper, direction: x, from: b.c1, to: ground, k: 1.0e+5}
  x2: {kind: spring_damper, direction: x, from: b.c3, to: ground, k: 0.7e+5}
loads:
  down: {at: b.c2, force: 3000}
  side: {at: b.top, force: -1500, direction: y}
  push: {at: b.c4, force: 800, direction: x}
"#;

/// A point `r` of the block, a unit vector `e` and a magnitude (a stiffness or a force).
type Directed = ([f64; 3], [f64; 3], f64);

/// `(r, e, k)` of every spring and `(r, e, f)` of every load, as written in [`BLOCK`].
fn springs_and_loads() -> (Vec<Directed>, Vec<Directed>) {
    let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    let c1 = [1.2, 0.7, -0.3];
    let c2 = [-1.1, 0.6, 0.2];
    let c3 = [0.9, -0.8, 0.4];
    let c4 = [-1.0, -0.5, -0.6];
    let top = [0.3, 0.1, -0.8];
    let low = [-0.2, -0.3, 0.5];
    (
        vec![
            (c1, z, 2.0e5),
            (c2, z, 3.0e5),
            (c3, z, 2.5e5),
            (c4, z, 1.5e5),
            (top, y, 1.2e5),
            (low, y, 0.8e5),
            (c1, x, 1.0e5),
            (c3, x, 0.7e5),
        ],
        vec![(c2, z, 3000.0), (top, y, -1500.0), (c4, x, 800.0)],
    )
}

/// `(e, r x e)` on `(x, y, z, roll, pitch, yaw)`.
fn incidence(r: [f64; 3], e: [f64; 3]) -> DVector<f64> {
    DVector::from_vec(vec![
        e[0],
        e[1],
        e[2],
        r[1] * e[2] - r[2] * e[1],
        r[2] * e[0] - r[0] * e[2],
        r[0] * e[1] - r[1] * e[0],
    ])
}

fn stiffness_and_load() -> (DMatrix<f64>, DVector<f64>) {
    let (springs, loads) = springs_and_loads();
    let mut k = DMatrix::zeros(6, 6);
    for (r, e, ks) in springs {
        let b = incidence(r, e);
        k += ks * &b * b.transpose();
    }
    let mut f = DVector::zeros(6);
    for (r, e, fl) in loads {
        f += fl * incidence(r, e);
    }
    (k, f)
}

const MASSES: [f64; 6] = [1200.0, 1200.0, 1200.0, 500.0, 900.0, 1100.0];
const COLUMNS: [&str; 6] = ["x_b", "y_b", "z_b", "phi_b", "beta_b", "psi_b"];

/// The response from rest under the step loads against the modal closed form.
#[test]
fn step_response_matches_the_modal_solution() {
    let system = load(BLOCK, &[]);
    let (k, f) = stiffness_and_load();
    let m_half = DMatrix::from_diagonal(&DVector::from_iterator(
        6,
        MASSES.iter().map(|m| 1.0 / m.sqrt()),
    ));
    let eig = SymmetricEigen::new(&m_half * &k * &m_half);
    let omegas: Vec<f64> = eig.eigenvalues.iter().map(|l| l.sqrt()).collect();
    // Every DOF moves (the coupled modes all take part) and the frequencies are distinct.
    assert!(omegas.iter().all(|&w| w > 5.0 && w < 60.0), "{omegas:?}");
    let phi = &m_half * &eig.eigenvectors;
    let exact = |t: f64| -> DVector<f64> {
        let mut q = DVector::zeros(6);
        for (i, w) in omegas.iter().enumerate() {
            let p = phi.column(i);
            let g = p.dot(&f) / (w * w);
            q += p * (g * (1.0 - (w * t).cos()));
        }
        q
    };
    let cfg = config(2.0, 1e-4, 10, StartMode::Rest, 0.0);
    let model = system.instantiate(&system.nominal()).unwrap();
    let engine = Engine::with_route(system.clone(), model, &cfg, vec![], Route::Fast).unwrap();
    let traj = engine.run().unwrap();
    for (d, name) in COLUMNS.iter().enumerate() {
        let got = column(&system, &traj, name);
        let want: Vec<f64> = traj.t.iter().map(|&t| exact(t)[d]).collect();
        let peak = want.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        let err = got
            .iter()
            .zip(&want)
            .fold(0.0f64, |a, (g, w)| a.max((g - w).abs()));
        assert!(peak > 1e-4, "{name}: the DOF must move ({peak:e})");
        assert!(err < 1e-4 * peak, "{name}: error {err:e} of peak {peak:e}");
    }
}

/// The equilibrium start under the loads is `K^-1 F` and every acceleration vanishes.
#[test]
fn equilibrium_is_the_static_solution() {
    let system = load(BLOCK, &[]);
    let (k, f) = stiffness_and_load();
    let want = k.lu().solve(&f).unwrap();
    let cfg = config(0.01, 1e-4, 10, StartMode::Equilibrium, 0.0);
    let model = system.instantiate(&system.nominal()).unwrap();
    let engine = Engine::with_route(system.clone(), model, &cfg, vec![], Route::Fast).unwrap();
    let x = engine.initial_state().unwrap();
    let scale = want.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    for d in 0..6 {
        assert!(
            (x[d] - want[d]).abs() < 1e-9 * scale,
            "DOF {d}: {} vs {}",
            x[d],
            want[d]
        );
    }
    let (a, _) = engine.evaluate(0.0, &x, &[0.0; 6]);
    for (d, m) in MASSES.iter().enumerate() {
        assert!(
            (a[d] * m).abs() < 1e-6,
            "DOF {d}: residual force {}",
            a[d] * m
        );
    }
}

/// A wheelset on two supported rails with a frame above it, the frame's lateral spring to the
/// ground `frame_lateral` (N/m; `None`: the frame held laterally by the wheelset alone), a
/// lateral load of 2 kN on the frame.
fn wheelset_and_frame(frame_lateral: Option<f64>) -> std::sync::Arc<mbd_system::System> {
    let rail = "    length: 12\n    modes: 10\n    mass_per_length: 60\n    bending_stiffness: 6.6e+6\n    supports:\n      spacing: 0.6\n      count: 20\n      levels:\n        - {name: sleeper, mass: 120, link: {k: 6.0e+7, c: 5.0e+4}}\n      ground: {k: 1.2e+8, c: 6.0e+4}\n";
    let fy = frame_lateral.map_or(String::new(), |k| {
        format!("  fy: {{kind: spring_damper, direction: y, from: f, to: ground, k: {k:e}}}\n")
    });
    let text = format!(
        r#"format: 1
name: wheelset on rails
parameters:
  v: {{unit: m/s, nominal: 20, range: [10, 30]}}
bodies:
  w:
    mass: 1500
    inertia: {{roll: 900, yaw: 900}}
    dofs: [y, z, roll, yaw]
    points: {{left: [0, -1, 0], right: [0, 1, 0]}}
  f:
    mass: 2000
    inertia: {{roll: 1500, yaw: 2000}}
    dofs: [y, z, roll, yaw]
    points: {{left: [0, -1, -0.3], right: [0, 1, -0.3]}}
beams:
  rl:
{rail}  rr:
{rail}moving:
  speed: v
  points:
    pl: {{on: rl, offset: 0}}
    pr: {{on: rr, offset: 0}}
profiles:
  bump: {{kind: harmonic, amplitude: 5.0e-4, wavelength: 3}}
elements:
  ws:
    kind: wheelset
    from: w
    rails: [pl, pr]
    profiles: [bump, bump]
    half_gauge: 0.75
    radius: 0.43
    hertz: 5.18e-8
    conicity: 0.1
    creep: {{young: 2.06e+11, poisson: 0.3, friction: 0.4, rail_radius: 0.3}}
  zl: {{kind: spring_damper, from: f.left, to: w.left, k: 1.0e+6, c: 1.0e+4}}
  zr: {{kind: spring_damper, from: f.right, to: w.right, k: 1.2e+6, c: 1.0e+4}}
  yl: {{kind: spring_damper, direction: y, from: f.left, to: w.left, k: 5.0e+5}}
  yr: {{kind: spring_damper, direction: y, from: f.right, to: w.right, k: 5.0e+5}}
  xl: {{kind: spring_damper, direction: x, from: f.left, to: w.left, k: 5.0e+6}}
  xr: {{kind: spring_damper, direction: x, from: f.right, to: w.right, k: 5.0e+6}}
{fy}  fz: {{kind: spring_damper, from: f.left, to: ground, k: 4.0e+5}}
  fz2: {{kind: spring_damper, from: f.right, to: ground, k: 4.0e+5}}
  fx: {{kind: spring_damper, direction: x, from: f.left, to: ground, k: 3.0e+5}}
loads:
  wheelset: {{at: w, force: 1.4e+5}}
  frame: {{at: f, force: 3.0e+4}}
  side: {{at: f.left, force: 2.0e+3, direction: y}}
"#
    );
    load(&text, &[])
}

/// The equilibrium start of `system` on `route`: the state, the accelerations there and the
/// number of rigid DOFs.
fn equilibrium_on(
    system: &std::sync::Arc<mbd_system::System>,
    route: Route,
) -> mbd_engine::Result<(Vec<f64>, Vec<f64>, usize)> {
    let cfg = config(0.01, 5e-5, 10, StartMode::Equilibrium, 4.0);
    let model = system.instantiate(&system.nominal()).unwrap();
    let e = Engine::with_route(system.clone(), model, &cfg, vec![], route)?;
    let x = e.initial_state()?;
    let (a, _) = e.evaluate(0.0, &x, &vec![0.0; x.len()]);
    Ok((x, a, e.layout().rigid))
}

/// The equilibrium start on both routes: equal to 1e-9 of the largest displacement, every
/// rigid acceleration vanishing (forces of ~1e5 N balanced to round-off over masses of ~1e3
/// kg).
fn assert_routes_agree(system: &std::sync::Arc<mbd_system::System>) -> Vec<f64> {
    let (fast, a, rigid) = equilibrium_on(system, Route::Fast).unwrap_or_else(|e| panic!("{e}"));
    let (general, _, _) = equilibrium_on(system, Route::General).unwrap_or_else(|e| panic!("{e}"));
    let scale = general.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(scale > 1e-4, "the system must deflect ({scale})");
    for (i, (f, g)) in fast.iter().zip(&general).enumerate() {
        assert!((f - g).abs() < 1e-9 * scale, "state {i}: {f} vs {g}");
    }
    for (i, a) in a[..rigid].iter().enumerate() {
        assert!(a.abs() < 1e-6, "DOF {i}: acceleration {a}");
    }
    fast
}

/// A wheelset on two supported rails with a frame above it: a rigid part that is not
/// statically determinate (six elements on the wheelset's four DOFs) on beams, which the
/// equilibrium start solves on the condensed route (rigid DOFs and point forces, the beams by
/// superposition of unit responses); the general route (Newton on the whole state) must agree
/// to 1e-9 of the largest displacement, and every acceleration vanish.
#[test]
fn condensed_equilibrium_equals_the_general_route() {
    assert_routes_agree(&wheelset_and_frame(Some(2.0e5)));
}

/// The same frame held laterally by its wheelset alone, as a vehicle is: the frame's 2 kN
/// side load reaches the ground only through the wheel-rail contact, whose lateral stiffness
/// (gravitational, `2 Q gamma (1 + gamma^2) / e0`, and the creep forces, both growing with the
/// wheel load `Q`) vanishes at zero load. Both routes must find the equilibrium (the wheelset
/// shifted toward the load, every acceleration vanishing) and agree.
#[test]
fn a_frame_held_laterally_by_its_wheelset_alone_finds_its_equilibrium() {
    let system = wheelset_and_frame(None);
    let x = assert_routes_agree(&system);
    let y = system.bodies[0].y.expect("the wheelset's lateral DOF");
    assert!(
        x[y] > 1e-6,
        "the wheelset shifts toward the load: y = {}",
        x[y]
    );
}

/// The vehicle in space stands on eight wheels: its rigid part is not statically determinate,
/// yet the mean of the wheels' normal forces is the static wheel load `W` by the vertical
/// balance of the whole vehicle (the force scale of the learners' global ODE loss). A vertical
/// spring from the car body to the ground takes part of the weight: then there is no scale.
#[test]
fn the_mean_wheel_load_of_the_vehicle_in_space_is_w() {
    let text = system_text("vtcd-3d.yaml");
    let system = load(&text, &[]);
    let model = system.instantiate(&system.nominal()).unwrap();
    assert!(mbd_engine::statics::static_forces(&system, &model).is_none());
    let w = model.values[system.parameter("W").unwrap()];
    let scale = mbd_engine::statics::contact_scale(&system, &model).unwrap();
    assert!((scale - w).abs() <= 1e-12 * w, "{scale} vs W = {w}");
    let grounded = replace_once(
        &text,
        "  # Secondary lateral dampers",
        "  tie: {kind: spring_damper, from: c.d1, to: ground, k: 1.0e+5}\n  # Secondary lateral dampers",
    );
    let system = load(&grounded, &[]);
    let model = system.instantiate(&system.nominal()).unwrap();
    assert_eq!(mbd_engine::statics::contact_scale(&system, &model), None);
}

/// The vehicle in space reads each profile part once per wheelset and point (the two rails'
/// combinations share the vertical profile and the cross-level; a level and its slope come from
/// one search): every element's `eta` and, for a damper, its rate are still the values of
/// [`mbd_engine::ProfileSource::ramped`] and `ramped_rate` of its own profile at its own point,
/// to the bit, through the start-up's zero, ramp and full phases.
#[test]
fn the_profiles_under_the_vehicle_in_space_are_each_elements_own_reading() {
    let system = load(&system_text("vtcd-3d.yaml"), &[]);
    let model = system.instantiate(&system.nominal()).unwrap();
    let params = mbd_dataset::ProfileParams {
        seed: 5,
        dx: 0.1,
        length: 240.0,
    };
    let profiles: Vec<Option<mbd_engine::Profile>> =
        mbd_dataset::profile_generators(&system, &params)
            .unwrap()
            .into_iter()
            .map(|g| g.map(|g| mbd_engine::Profile::new(g.positions(), g.profile(3)).unwrap()))
            .collect();
    assert_eq!(
        profiles.iter().flatten().count(),
        3,
        "vertical, alignment, cross-level"
    );
    let mut cfg = config(0.06, 1e-4, 10, StartMode::Rest, 20.0);
    cfg.startup_zero_fraction = 0.2;
    cfg.startup_ramp_fraction = 0.5;
    let engine = Engine::with_route(system.clone(), model.clone(), &cfg, profiles, Route::Fast)
        .unwrap_or_else(|e| panic!("{e}"));
    let mut checked = [0usize; 2];
    engine
        .run_observed(600, None, |s| {
            let (ramp, ramp_rate) = (cfg.ramp(s.t), cfg.ramp_rate(s.t));
            for (e, el) in model.elements.iter().enumerate() {
                let (Some(p), mbd_system::model::ModelEnd::Moving(pt)) = (el.profile, el.to) else {
                    continue;
                };
                let (source, x) = (engine.profile(p), s.q.point_x[pt]);
                let eta = source.ramped(ramp, x);
                assert_eq!(s.q.eta[e].to_bits(), eta.to_bits(), "eta of {e} at {}", s.t);
                checked[0] += 1;
                if el.law.damping() != 0.0 {
                    let rate = source.ramped_rate(ramp, ramp_rate, model.speed, x);
                    assert_eq!(s.q.eta_rate[e].to_bits(), rate.to_bits(), "rate of {e}");
                    checked[1] += (rate != 0.0) as usize;
                }
            }
        })
        .unwrap();
    // 8 wheels and 8 lateral fastenings on 601 evaluations; rates nonzero after the zero phase.
    assert_eq!(checked[0], 16 * 601);
    assert!(checked[1] > 8 * 400, "{checked:?}");
}

/// Two designs of the vehicle in space's parameter box (the job's samples 34 and 59: stiff
/// suspensions, conicity 0.34 and 0.24) on their own TB/T 3352 irregularities, whose static
/// start failed from a 1 N press of every wheel (the first Newton step on the 1 N Hertz
/// tangent overshot to point forces of 1e6 N, the rails' deflection opened every contact and
/// the Jacobian was singular). From every wheel loaded with the mean wheel load on the rails'
/// deflected heads the start solves: every rigid acceleration vanishes and each wheelset's
/// eight wheel loads sum to the vehicle's weight.
#[test]
fn the_static_start_of_the_vehicle_in_space_solves_where_a_light_press_failed() {
    let designs: [(u64, [(&str, f64); 16]); 2] = [
        (
            34,
            [
                ("m_c", 40174.656030374244),
                ("j_c", 2196614.58114552),
                ("m_t", 2771.029324017984),
                ("j_t", 3391.3452976018393),
                ("m_w", 1676.596137974117),
                ("k_p", 1644061.6860963001),
                ("c_p", 21164.909087600914),
                ("k_s", 491172.31010802824),
                ("c_s", 23646.331515786704),
                ("l_c", 10.055407353329702),
                ("l_t", 1.2951008121939676),
                ("v_kmh", 312.849931049806),
                ("k_f", 38392986.43218979),
                ("c_f", 44935.03866902855),
                ("gamma", 0.3438680047786915),
                ("c_yaw", 192052.69597215846),
            ],
        ),
        (
            59,
            [
                ("m_c", 41476.108806288445),
                ("j_c", 1878842.530513613),
                ("m_t", 3668.7485887824546),
                ("j_t", 3380.344630732053),
                ("m_w", 1361.6892379071805),
                ("k_p", 2077238.4194692709),
                ("c_p", 19304.749720852073),
                ("k_s", 409851.7321914899),
                ("c_s", 17344.128219919607),
                ("l_c", 9.906933483428897),
                ("l_t", 1.0171512857376974),
                ("v_kmh", 336.00947977539926),
                ("k_f", 36883105.79887365),
                ("c_f", 46549.38660977408),
                ("gamma", 0.23864685395030905),
                ("c_yaw", 180170.9459402928),
            ],
        ),
    ];
    let system = load(&system_text("vtcd-3d.yaml"), &[]);
    let params = mbd_dataset::ProfileParams {
        seed: 1,
        dx: 0.1,
        length: 240.0,
    };
    let generators = mbd_dataset::profile_generators(&system, &params).unwrap();
    for (id, values) in designs {
        let mut sampled = system.nominal();
        for (name, value) in values {
            assert!(sampled.set(name, value), "{name}");
        }
        let model = system.instantiate(&sampled).unwrap();
        let profiles = generators
            .iter()
            .map(|g| {
                g.as_ref()
                    .map(|g| mbd_engine::Profile::new(g.positions(), g.profile(id)).unwrap())
            })
            .collect();
        let cfg = config(0.01, 1e-4, 10, StartMode::Equilibrium, 20.0);
        let engine = Engine::with_route(system.clone(), model.clone(), &cfg, profiles, Route::Fast)
            .unwrap_or_else(|e| panic!("{e}"));
        let x = engine
            .initial_state()
            .unwrap_or_else(|e| panic!("design {id}: {e}"));
        let (a, q) = engine.evaluate(0.0, &x, &vec![0.0; x.len()]);
        for (i, a) in a[..engine.layout().rigid].iter().enumerate() {
            assert!(a.abs() < 1e-6, "design {id}, DOF {i}: acceleration {a}");
        }
        let weight: f64 = model.loads.iter().map(|l| l.force).sum();
        let wheels: f64 = model
            .elements
            .iter()
            .zip(&q.force)
            .filter(|(e, _)| e.law.wheel().is_some())
            .map(|(_, f)| f)
            .sum();
        assert!(
            (wheels - weight).abs() < 1e-6 * weight,
            "design {id}: wheel loads {wheels} vs weight {weight}"
        );
    }
}
