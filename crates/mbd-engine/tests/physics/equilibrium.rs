//! The static-equilibrium start and the stored rows of the vehicle-track model (short track),
//! checked against the equations of `docs/model.md` written out here, not the engine's
//! assembly.
//!
//! - The equilibrium start balances every force: at `t = 0` every generalised force (`M A`) is
//!   round-off of the forces acting (measured 6e-15 fast, 1.3e-14 general, of the wheel load; asserted 1e-9),
//!   on both routes, with the profile on; a run at standstill on a level track stays at the
//!   start state (no drop transient: 3e-16 of the static deflection, asserted 1e-9; the rest start departs by 1.6 times it).
//! - Stored rows satisfy the vehicle's ten equations of motion, and each contact force its
//!   Hertz law, from the stored displacements, velocities, accelerations, rail deflections and
//!   profile values alone (to 1e-12 of the wheel load; round-off measured at 1.5e-17 and 2.3e-16).
//! - Under each wheel the static Hertz compression is `G W^(2/3)` and the contact force `W`
//!   (1e-12 relative: one `powf` and a subtraction of millimetre displacements).

use crate::common::*;
use mbd_engine::{Route, StartMode};

/// The static wheel load `W` and the Hertz constant `G` of a short-track sample.
fn load_and_g(system: &mbd_system::System) -> (f64, f64) {
    let model = system.instantiate(&system.nominal()).unwrap();
    (value(system, &model, "W"), value(system, &model, "hertz_g"))
}

#[test]
fn equilibrium_start_balances_every_force() {
    let system = short_track(&system_text("vtcd.yaml"), &[]);
    let (w, _) = load_and_g(&system);
    for route in [Route::Fast, Route::General] {
        let cfg = config(0.05, 1e-4, 10, StartMode::Equilibrium, SHORT_X0);
        let e = engine(
            &system,
            &system.nominal(),
            &cfg,
            vec![Some(track_profile(5))],
            route,
        );
        let x = e.initial_state().unwrap();
        let zero = vec![0.0; x.len()];
        let (a, q) = e.evaluate(0.0, &x, &zero);
        let masses = mbd_engine::statics::state_masses(&e);
        let layout = e.layout();
        let shape = e.beam(0).shape_scale;
        // Residual forces over the scale of the forces at each DOF: W at the rigid z DOFs and
        // the supports, W l_t at the pitch DOFs, W max|Y_k| at the modes.
        let l_t = value(&system, e.model(), "l_t");
        let mut worst = 0.0f64;
        for (i, (a, m)) in a.iter().zip(&masses).enumerate() {
            let scale = if i < layout.rigid {
                if system.dofs[i].name.starts_with("beta") {
                    w * l_t
                } else {
                    w
                }
            } else if layout.beams[0].modes.contains(&i) {
                w * shape
            } else {
                w
            };
            worst = worst.max((a * m).abs() / scale);
        }
        println!("{route:?}: largest residual force at t = 0: {worst:.2e} of the load");
        assert!(worst < 1e-9, "{route:?}: {worst:e}");
        // Meaningful: the contacts carry the load and the profile is on under them.
        assert!(
            q.force
                .iter()
                .filter(|f| (**f - w).abs() < 1e-6 * w)
                .count()
                == 4
        );
        assert!(q.eta.iter().filter(|e| e.abs() > 1e-6).count() == 4);
    }
    // At standstill on a level track the start state is kept; the rest start drops.
    let system = short_track(&standstill(&system_text("vtcd.yaml")), &[]);
    let mut drift = Vec::new();
    for start in [StartMode::Equilibrium, StartMode::Rest] {
        let cfg = config(0.1, 1e-4, 10, start, SHORT_X0);
        let e = engine(&system, &system.nominal(), &cfg, vec![None], Route::Fast);
        let x0 = mbd_engine::statics::equilibrium(&e).unwrap();
        let start_state = e.initial_state().unwrap();
        let scale = peak(&x0);
        let mut largest = 0.0f64;
        e.run_observed(cfg.steps(), None, |s| {
            let d =
                s.x.iter()
                    .zip(&start_state)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
            largest = largest.max(d / scale);
        })
        .unwrap();
        println!("{start:?} at standstill: largest departure from the start {largest:.2e} of the static deflection");
        drift.push(largest);
    }
    assert!(drift[0] < 1e-9, "equilibrium start moved by {:e}", drift[0]);
    assert!(
        drift[1] > 0.5,
        "the rest start should drop onto the track: {:e}",
        drift[1]
    );
}

#[test]
fn stored_rows_satisfy_the_equations_of_motion() {
    let system = short_track(&system_text("vtcd.yaml"), &[]);
    let sampled = system.nominal();
    let model = system.instantiate(&sampled).unwrap();
    let p = |n: &str| value(&system, &model, n);
    // docs/model.md: one-rail model, half of each whole-vehicle mass and inertia.
    let (m_c, j_c, m_t, j_t, m_w) = (
        p("m_c") / 2.0,
        p("j_c") / 2.0,
        p("m_t") / 2.0,
        p("j_t") / 2.0,
        p("m_w") / 2.0,
    );
    let (k_p, c_p, k_s, c_s, l_c, l_t) =
        (p("k_p"), p("c_p"), p("k_s"), p("c_s"), p("l_c"), p("l_t"));
    let (w, g) = (p("W"), p("hertz_g"));
    let cfg = config(0.1, 1e-4, 10, StartMode::Equilibrium, SHORT_X0);
    let e = engine(
        &system,
        &sampled,
        &cfg,
        vec![Some(track_profile(2))],
        Route::Fast,
    );
    let traj = e.run().unwrap();
    let col = |n: &str| column(&system, &traj, n);
    let (mut worst_eom, mut worst_hertz) = (0.0f64, 0.0f64);
    for i in 0..traj.t.len() {
        let x = |n: &str| col(n)[i];
        let v = |n: &str| col(&format!("{n}_v"))[i];
        let a = |n: &str| col(&format!("{n}_a"))[i];
        // Suspension compressions and forces F = k d + c d'.
        let spring = |k: f64, c: f64, up: (&str, &str, f64), down: &str| {
            let d = x(up.0) - up.2 * x(up.1) - x(down);
            let dv = v(up.0) - up.2 * v(up.1) - v(down);
            k * d + c * dv
        };
        let f_s1 = spring(k_s, c_s, ("z_c", "beta_c", l_c), "z_t1");
        let f_s2 = spring(k_s, c_s, ("z_c", "beta_c", -l_c), "z_t2");
        let f_p = [
            spring(k_p, c_p, ("z_t1", "beta_t1", l_t), "z_w1"),
            spring(k_p, c_p, ("z_t1", "beta_t1", -l_t), "z_w2"),
            spring(k_p, c_p, ("z_t2", "beta_t2", l_t), "z_w3"),
            spring(k_p, c_p, ("z_t2", "beta_t2", -l_t), "z_w4"),
        ];
        let contact: Vec<f64> = (1..=4).map(|j| x(&format!("p_{j}"))).collect();
        let residuals = [
            m_c * a("z_c") + f_s1 + f_s2,
            (j_c * a("beta_c") - l_c * (f_s1 - f_s2)) / l_c,
            m_t * a("z_t1") - (f_s1 - f_p[0] - f_p[1]),
            (j_t * a("beta_t1") - l_t * (f_p[0] - f_p[1])) / l_t,
            m_t * a("z_t2") - (f_s2 - f_p[2] - f_p[3]),
            (j_t * a("beta_t2") - l_t * (f_p[2] - f_p[3])) / l_t,
            m_w * a("z_w1") - (f_p[0] + w - contact[0]),
            m_w * a("z_w2") - (f_p[1] + w - contact[1]),
            m_w * a("z_w3") - (f_p[2] + w - contact[2]),
            m_w * a("z_w4") - (f_p[3] + w - contact[3]),
        ];
        for r in residuals {
            worst_eom = worst_eom.max(r.abs() / w);
        }
        for j in 1..=4 {
            let delta = x(&format!("z_w{j}")) - x(&format!("z_r{j}")) - x(&format!("eta_{j}"));
            let hertz = if delta > 0.0 {
                (delta / g).powf(1.5)
            } else {
                0.0
            };
            worst_hertz = worst_hertz.max((hertz - contact[j - 1]).abs() / w);
        }
    }
    // Meaningful: the run is dynamic (contact forces vary by percent of W).
    let swing = (1..=4)
        .map(|j| {
            let c = col(&format!("p_{j}"));
            c.iter().fold(0.0f64, |m, p| m.max((p - w).abs()))
        })
        .fold(0.0, f64::max);
    println!(
        "{} rows: equations of motion {worst_eom:.2e}, Hertz law {worst_hertz:.2e} of W; contact \
         forces swing by {:.1} % of W",
        traj.t.len(),
        100.0 * swing / w
    );
    assert!(swing > 0.01 * w);
    assert!(
        worst_eom < 1e-12 && worst_hertz < 1e-12,
        "{worst_eom:e} {worst_hertz:e}"
    );
}

#[test]
fn static_hertz_compression_under_each_wheel_is_g_w_to_the_two_thirds() {
    let system = short_track(&system_text("vtcd.yaml"), &[]);
    let (w, g) = load_and_g(&system);
    let cfg = config(0.001, 1e-4, 10, StartMode::Equilibrium, SHORT_X0);
    let e = engine(
        &system,
        &system.nominal(),
        &cfg,
        vec![Some(track_profile(4))],
        Route::Fast,
    );
    let traj = e.run().unwrap();
    let at0 = |n: &str| column(&system, &traj, n)[0];
    let expected = g * w.powf(2.0 / 3.0);
    for j in 1..=4 {
        let delta = at0(&format!("z_w{j}")) - at0(&format!("z_r{j}")) - at0(&format!("eta_{j}"));
        println!(
            "wheel {j}: compression {delta:.6e} m (G W^(2/3) = {expected:.6e}), rail {:.4e} m",
            at0(&format!("z_r{j}"))
        );
        assert!(
            (delta / expected - 1.0).abs() < 1e-12,
            "wheel {j}: {delta:e}"
        );
        assert!((at0(&format!("p_{j}")) / w - 1.0).abs() < 1e-12);
        // Meaningful: the rail is deflected under the wheel (a modal, supported beam).
        assert!(at0(&format!("z_r{j}")) > 5.0 * expected);
    }
}
