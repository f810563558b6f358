//! The bridge of `systems/bridge.yaml`: a simply supported modal deck (no discrete supports)
//! crossed by a constant moving force and by a sprung-mass vehicle, against mathematics no one
//! here wrote (`mbd_test_models::beam`, `mbd_test_models::moving_mass`).
//!
//! - **Moving constant force** (Fryba): the deck alone, a `loads:` entry at a moving point, the
//!   beam at rest, no damping. Fryba's series truncated to the engine's modes differs from the
//!   engine only by Zhai's integration error, about 1.5e-5 of the peak at dt = 1e-4
//!   (`systems-interfaces.md`, "about 1e-5"), at three speed parameters from a road bridge's 0.1
//!   to the first resonance `alpha = 1`.
//! - **Crawling force**: at `alpha = 1e-5` the peak mid-span deflection is the static
//!   `P L^3 / (48 E I)`; 15 modes leave a truncation of 4.0e-5 (the series' tail `(96 / pi^4)
//!   sum_(odd n > 15) n^-4`) and the dynamic excess is about `alpha`.
//! - **Moving sprung mass** (Biggs 1964; Yang and Yau 1997): `systems/bridge.yaml` (a) without
//!   deck profile and without any damping, the Yang-Yau case, and (b) with its 2 % modal and
//!   suspension damping and a harmonic deck profile, against the same modal ODEs written out
//!   and solved by Dormand-Prince 5(4) at rtol 1e-12 (~1e-9 of the peak). The vehicle starts on
//!   the rigid approach, enters, crosses and leaves (`outside: rigid`).

use crate::common::*;
use mbd_engine::{Route, StartMode};
use mbd_system::system::Quantity;
use mbd_test_models::beam::{static_midspan, SimpleBeam};
use mbd_test_models::moving_mass::{Harmonic, MovingSprungMass, Sample};
use std::sync::Arc;

/// The deck of `systems/bridge.yaml`.
const BEAM: SimpleBeam = SimpleBeam {
    length: 25.0,
    mass_per_length: 2303.0,
    bending_stiffness: 8.323e9,
};
/// The force: the bridge vehicle's weight `M_v g` (N).
const P: f64 = 5750.0 * 9.81;

/// A constant force `P` on a moving point of the bare deck (no bodies) at speed `v` (m/s).
fn moving_force(modes: usize, v: f64) -> Arc<mbd_system::System> {
    let text = format!(
        "
format: 1
name: moving-force
parameters:
  span: {{unit: m, value: {l}}}
  ei: {{unit: N m^2, value: {ei}}}
  mu: {{unit: kg/m, value: {mu}}}
  modes: {{unit: '1', value: {modes}}}
  p: {{unit: N, value: {P}}}
  v: {{unit: m/s, value: {v}}}
beams:
  b: {{length: span, modes: modes, mass_per_length: mu, bending_stiffness: ei, outside: rigid}}
sensors:
  mid: {{on: b, x: span / 2}}
moving:
  speed: v
  points:
    b1: {{on: b, offset: 0}}
loads:
  force: {{at: b1, force: p}}
outputs: [z_mid, z_b1]
",
        l = BEAM.length,
        ei = BEAM.bending_stiffness,
        mu = BEAM.mass_per_length,
    );
    load(&text, &[])
}

/// The force enters at `t = 0`, the beam at rest; mid-span and under-the-force deflections
/// follow Fryba's series truncated to the same 12 modes while the force is on the beam.
#[test]
fn constant_moving_force_follows_frybas_series() {
    let modes = 12;
    for alpha in [0.1, 0.5, 1.0] {
        let v = BEAM.speed_for(alpha);
        let t_cross = BEAM.length / v;
        let system = moving_force(modes, v);
        let e = engine(
            &system,
            &system.nominal(),
            &config(t_cross, 1e-4, 10, StartMode::Rest, 0.0),
            vec![],
            Route::Fast,
        );
        // The setup: the engine's beam is Fryba's, the run covers the crossing.
        let w1 = e.beam(0).omega2[0].sqrt();
        assert!((w1 - BEAM.omega(1)).abs() < 1e-12 * w1);
        let traj = e.run().unwrap();
        assert!(*traj.t.last().unwrap() > 0.98 * t_cross);
        let mid = column(&system, &traj, "z_mid");
        let under = column(&system, &traj, "z_b1");
        let half = 0.5 * BEAM.length;
        let fryba_mid: Vec<f64> = traj
            .t
            .iter()
            .map(|&t| BEAM.fryba(P, v, half, t, modes))
            .collect();
        let fryba_under: Vec<f64> = traj
            .t
            .iter()
            .map(|&t| BEAM.fryba(P, v, v * t, t, modes))
            .collect();
        // Meaningful: the dynamic part (Fryba minus the static influence line) is far above the
        // tolerance, from 10 % of the peak at alpha 0.1 to all of it at resonance.
        let quasi_static: Vec<f64> = traj
            .t
            .iter()
            .map(|&t| BEAM.static_series(P, v * t, half, modes))
            .collect();
        assert!(relative_error(&quasi_static, &fryba_mid) > 0.05);
        let (e_mid, e_under) = (
            relative_error(mid, &fryba_mid),
            relative_error(under, &fryba_under),
        );
        println!(
            "alpha {alpha}: DAF {:.4}; engine - Fryba: mid-span {e_mid:.2e}, under the force \
             {e_under:.2e} of the peak",
            peak(&fryba_mid) / static_midspan(P, BEAM.length, BEAM.bending_stiffness)
        );
        // The issue asks 1e-3 of the peak; Zhai's error is measured at 1.4e-5 to 2.3e-5 here
        // (dt = 1e-4; halving dt cuts it 3-4x), so 1e-4 keeps a 4x margin and also catches a
        // physics error of 0.01 %.
        assert!(
            e_mid < 1e-4 && e_under < 1e-4,
            "alpha {alpha}: {e_mid:e} {e_under:e}"
        );
    }
}

/// At `alpha = 1e-5` with 15 modes, entering from the support with the beam at rest, the
/// largest mid-span deflection is `P L^3 / (48 E I)` to 1e-4: measured -3.0e-5 (truncation
/// -4.0e-5, dynamic excess +1e-5 ~ alpha). 2.1e7 steps at dt 2.5e-4 (the 15-mode limit is
/// 2.96e-4): the half crossing takes 5232 s.
#[test]
fn crawling_force_gives_the_static_midspan_deflection() {
    let modes = 15;
    let v = BEAM.speed_for(1e-5);
    let system = moving_force(modes, v);
    let dt = 2.5e-4;
    let t_mid = 0.5 * BEAM.length / v;
    let duration = t_mid + 40.0 * dt;
    let steps = (duration / dt).round() as usize;
    let e = engine(
        &system,
        &system.nominal(),
        &config(duration, dt, steps, StartMode::Rest, 0.0),
        vec![],
        Route::Fast,
    );
    // The setup: the speed parameter from the engine's own first frequency.
    let alpha = v * std::f64::consts::PI / (e.beam(0).omega2[0].sqrt() * BEAM.length);
    assert!((alpha / 1e-5 - 1.0).abs() < 1e-9, "{alpha}");
    let (mut best, mut at) = (0.0f64, 0.0);
    e.run_observed(steps, None, |s| {
        let w = e.channel_value(Quantity::Sensor(0, 0), s);
        if w > best {
            (best, at) = (w, s.t);
        }
    })
    .unwrap();
    let statics = static_midspan(P, BEAM.length, BEAM.bending_stiffness);
    let truncated = BEAM.static_series(P, 0.5 * BEAM.length, 0.5 * BEAM.length, modes);
    println!(
        "crawl: peak {best:.6e} m at x = {:.4} m, {:+.2e} of P L^3/48EI ({:+.2e} truncation)",
        v * at,
        best / statics - 1.0,
        truncated / statics - 1.0
    );
    // The peak is the one of the load at mid-span (within 1 mm of travel either way).
    assert!((v * at - 0.5 * BEAM.length).abs() < 1e-3);
    assert!((best / statics - 1.0).abs() < 1e-4);
}

/// `systems/bridge.yaml` as a reference problem: `damped = false` without deck profile and
/// without any damping (the Yang-Yau case), else with its damping and a harmonic deck profile.
fn sprung(damped: bool) -> (Arc<mbd_system::System>, Option<Harmonic>) {
    let text = system_text("bridge.yaml");
    let block = "profiles:\n  deck:\n    kind: generated\n    psd: {iso8608: A}\n    \
                 wavelengths: [0.5, 50.0]\n    interpolation: cubic   # the suspension damper \
                 reads the profile's rate: a continuous slope\n";
    if damped {
        let h = Harmonic {
            amplitude: 1e-3,
            wavelength: 6.0,
            phase: 0.4,
        };
        let harmonic = format!(
            "profiles:\n  deck: {{kind: harmonic, amplitude: {}, wavelength: {}, phase: {}}}\n",
            h.amplitude, h.wavelength, h.phase
        );
        (load(&replace_once(&text, block, &harmonic), &[]), Some(h))
    } else {
        let text = replace_once(&text, block, "");
        let text = replace_once(&text, ", profile: deck", "");
        let text = replace_once(&text, " eta_suspension,", "");
        let text = replace_once(
            &text,
            "c_v: {unit: N s/m, nominal: 1.0e+4, range: {factor: [0.5, 1.5]},",
            "c_v: {unit: N s/m, value: 0.0,",
        );
        (load(&text, &[("zeta", 0.0)]), None)
    }
}

/// The reference problem of a compiled bridge variant at its nominal values.
fn reference_of(
    system: &mbd_system::System,
    profile: Option<Harmonic>,
    start: f64,
) -> MovingSprungMass {
    let model = system.instantiate(&system.nominal()).unwrap();
    let value = |n: &str| model.values[system.parameter(n).unwrap()];
    assert_eq!(value("span"), BEAM.length);
    assert_eq!(value("ei"), BEAM.bending_stiffness);
    assert_eq!(value("mu"), BEAM.mass_per_length);
    MovingSprungMass {
        beam: BEAM,
        modes: model.beams[0].modes,
        damping_ratio: value("zeta"),
        mass: value("m_v"),
        stiffness: value("k_v"),
        damping: value("c_v"),
        gravity: value("g"),
        speed: model.speed,
        start,
        profile,
        sensor: 0.5 * BEAM.length,
    }
}

/// Per compared column: the engine's name and the reference's value.
type Extract = fn(&Sample) -> f64;

/// The sprung mass starts in static equilibrium 5 m before the deck, crosses it and runs 0.6 s
/// beyond. Against the Runge-Kutta solution of the same modal ODEs, at dt = 5e-5 and 2.5e-5:
///
/// | | displacements (`z_v`, `z_mid`, `z_b1`) | `f_suspension` | `z_v_a` |
/// |---|---|---|---|
/// | undamped, measured at 2.5e-5 | 2.3e-8, 1.5e-6, 2.1e-6 | 1.4e-7 | 9.1e-6 |
/// | damped, on the deck | 2.8e-8, 6.8e-8, 5.4e-8 | 1.0e-8 | 1.5e-7 |
///
/// of each column's peak: the ~1e-6 aim, with second-order convergence (halving dt divides the
/// error by 3.4-4.0; asserted > 3). In the damped case the damper force jumps by `c v w_x(L)`
/// when the vehicle leaves the deck; Zhai's two-step formulas carry an O(dt) error across a
/// jump, so after the exit the displacement error converges at first order (6e-7 of the peak
/// at 2.5e-5; asserted < 3e-6). The undamped deck's acceleration is not compared: it is carried
/// by modes 10-12 (w dt ~ 0.1), whose phase error ~ (w dt)^2 / 24 per radian accumulates over
/// ~7000 rad of free vibration (7 % at dt 2.5e-5, converging).
#[test]
fn sprung_mass_crossing_matches_the_runge_kutta_reference() {
    let start = -5.0;
    for damped in [false, true] {
        let (system, profile) = sprung(damped);
        let case = reference_of(&system, profile, start);
        let (t_in, t_out) = (-start / case.speed, (BEAM.length - start) / case.speed);
        let duration = t_out + 0.6;
        let mut columns: Vec<(&str, Extract, f64)> = vec![
            ("z_v", |s| s.z, 5e-6),
            ("z_mid", |s| s.w_sensor, 5e-6),
            ("z_b1", |s| s.w_contact, 5e-6),
            ("f_suspension", |s| s.force, 5e-7),
            ("z_v_a", |s| s.z_a, 3e-5),
        ];
        if damped {
            columns.push(("z_mid_a", |s| s.w_sensor_a, 1e-3));
        }
        let mut errors: Vec<Vec<f64>> = Vec::new();
        let mut reference: Option<Vec<Sample>> = None;
        for dt in [5e-5f64, 2.5e-5] {
            let every = (1e-3 / dt).round() as usize;
            let cfg = config(duration, dt, every, StartMode::Equilibrium, start);
            let e = engine(&system, &system.nominal(), &cfg, vec![], Route::Fast);
            let traj = e.run().unwrap();
            let r = reference.get_or_insert_with(|| case.solve(&traj.t, 1e-12).0);
            let on: Vec<usize> = (0..traj.t.len()).filter(|&i| traj.t[i] <= t_out).collect();
            let pick = |x: &[f64]| on.iter().map(|&i| x[i]).collect::<Vec<f64>>();
            let mut at_dt = Vec::new();
            for (name, extract, tol) in &columns {
                let a = column(&system, &traj, name);
                let b: Vec<f64> = r.iter().map(extract).collect();
                let (e_on, e_all) = (relative_error(&pick(a), &pick(&b)), relative_error(a, &b));
                println!("damped {damped}, dt {dt:e}: {name} {e_on:.2e} on the deck, {e_all:.2e} overall");
                at_dt.push(e_on);
                if dt == 2.5e-5 {
                    assert!(e_on < *tol, "{name}: {e_on:e} on the deck");
                    // After the exit: no jump without damping; first order across it.
                    let after = if damped { 3e-6f64.max(*tol) } else { *tol };
                    assert!(e_all < after, "{name}: {e_all:e} overall");
                }
            }
            errors.push(at_dt);
            if dt == 2.5e-5 {
                // Entering and leaving (`outside: rigid`): before the deck the beam is exactly at
                // rest and (without a profile) the vehicle exactly in its static position; after
                // it the point reads the rigid ground while the deck vibrates freely.
                let mid = column(&system, &traj, "z_mid");
                let under = column(&system, &traj, "z_b1");
                let z_v = column(&system, &traj, "z_v");
                let before: Vec<usize> = (0..traj.t.len()).filter(|&i| traj.t[i] < t_in).collect();
                let after: Vec<usize> = (0..traj.t.len()).filter(|&i| traj.t[i] > t_out).collect();
                assert!(before.len() > 100 && after.len() > 500);
                assert!(before.iter().all(|&i| mid[i] == 0.0 && under[i] == 0.0));
                if !damped {
                    assert!(before.iter().all(|&i| z_v[i] == 0.0));
                }
                assert!(after.iter().all(|&i| under[i] == 0.0));
                let ringing = after.iter().map(|&i| mid[i].abs()).fold(0.0, f64::max);
                assert!(ringing > 0.05 * peak(mid), "{ringing:e} of {:e}", peak(mid));
            }
        }
        for (c, (name, ..)) in columns.iter().enumerate() {
            let ratio = errors[0][c] / errors[1][c];
            assert!(
                ratio > 3.0,
                "{name}: halving dt cut the error by {ratio:.2} only"
            );
        }
    }
}

/// A reading, not a check: the Yang-Yau case (`systems/bridge.yaml` without damping or profile,
/// at its nominal values) through the engine, the 12-mode reference and Biggs's one-mode
/// treatment (the same ODEs with one mode), for comparison with the published figures by a
/// reader with the papers at hand.
#[test]
fn yang_yau_case_reading() {
    let (system, _) = sprung(false);
    let case = reference_of(&system, None, 0.0);
    assert_eq!(case, mbd_test_models::moving_mass::yang_yau_1997());
    let t_out = BEAM.length / case.speed;
    let e = engine(
        &system,
        &system.nominal(),
        &config(t_out, 1e-4, 1, StartMode::Equilibrium, 0.0),
        vec![],
        Route::Fast,
    );
    let traj = e.run().unwrap();
    let statics = static_midspan(
        case.mass * case.gravity,
        BEAM.length,
        BEAM.bending_stiffness,
    );
    let (twelve, _) = case.solve(&traj.t, 1e-12);
    let one_mode = MovingSprungMass {
        modes: 1,
        ..case.clone()
    };
    let (one, _) = one_mode.solve(&traj.t, 1e-12);
    let daf = |x: &[f64]| peak(x) / statics;
    let w = |s: &[Sample]| s.iter().map(|s| s.w_sensor).collect::<Vec<_>>();
    let a = |s: &[Sample]| peak(&s.iter().map(|s| s.z_a).collect::<Vec<_>>());
    println!(
        "Yang-Yau case, 100 km/h, while on the deck: mid-span DAF engine {:.4}, reference (12 \
         modes) {:.4}, one mode (Biggs) {:.4}; peak vehicle acceleration engine {:.4}, reference \
         {:.4}, one mode {:.4} m/s^2",
        daf(column(&system, &traj, "z_mid")),
        daf(&w(&twelve)),
        daf(&w(&one)),
        peak(column(&system, &traj, "z_v_a")),
        a(&twelve),
        a(&one),
    );
}
