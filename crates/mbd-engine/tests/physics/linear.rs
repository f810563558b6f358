//! The assembled linear structure of the vehicle-track model and the time-step bound built on
//! it, probed through the engine's own force evaluation.
//!
//! With the Hertz contacts replaced by linear springs (a variant description; their stiffness
//! the Hertz tangent at [`CONTACT_LOAD_FACTOR`] times the wheel load, where the stability bound
//! linearises a contact), the engine's accelerations are affine in the state, so
//! `K e_j = -M (A(e_j, 0) - A(0, 0))` and `C e_j = -M (A(0, e_j) - A(0, 0))` exactly up to
//! round-off: the columns of the stiffness and damping matrices, probed on unit vectors.
//!
//! - Both are symmetric (Maxwell-Betti; a sign error in a pitch lever or a one-way coupling
//!   breaks it): `|K_ij - K_ji| <= 1e-11 sqrt(|K_ii K_jj|)` (round-off of the 1 m probes,
//!   measured ~1e-15), with couplings present in every block (body-body, body-beam, mode-mode,
//!   beam-support, support-support), so the check is not of a diagonal.
//! - The highest circular frequency `sqrt(lambda_max(M^-1/2 K M^-1/2))` is below the engine's
//!   bound [`Bound::omega_max`] (for the spring variant and for the Hertz model itself, whose
//!   bound linearises there), and the damping rate `lambda_max(M^-1/2 C M^-1/2)` below
//!   [`Bound::damping_max`], at the nominal values, at the light-and-stiff corner of the
//!   sampling box (lightest bodies, stiffest and most damped suspensions and pads, longest
//!   levers, top speed) and at the corner of the smallest stable step. The bound is 1.26-1.31
//!   times the true frequency (asserted below 3: a bound of the right problem).
//! - On the full 540 m track at the corner of the box with the smallest stable step (found
//!   range by range) `dt = 1e-4` is accepted and a step above [`Bound::dt_limit`] refused with
//!   both values named.

use crate::common::*;
use mbd_engine::stability::{Bound, CONTACT_LOAD_FACTOR};
use mbd_engine::{Engine, Route, StartMode};
use mbd_system::Sampled;
use nalgebra::{DMatrix, SymmetricEigen};
use std::sync::Arc;

/// The extreme corner of the sampling box: masses and inertias at their minimum, stiffness,
/// damping, lever arms and speed at their maximum.
fn extreme(system: &mbd_system::System) -> Sampled {
    let ends = system.sampled_names().into_iter().zip(system.ranges());
    system
        .sampled_by_name(
            ends.map(|(name, [lo, hi])| (name, if name.starts_with(['m', 'j']) { lo } else { hi })),
        )
        .unwrap()
}

/// The corner of the sampling box with the smallest stable step on `system` (x0 = `x0`): each
/// sampled parameter in turn set to the end of its range that lowers `Bound::dt_limit`.
fn worst_corner(system: &Arc<mbd_system::System>, x0: f64) -> Sampled {
    let limit = |sampled: &Sampled| {
        let model = system.instantiate(sampled).unwrap();
        let cfg = config(0.01, 1e-5, 10, StartMode::Equilibrium, x0);
        Bound::of(&Engine::new(system.clone(), model, &cfg, vec![None]).unwrap()).dt_limit()
    };
    let mut corner = system.nominal();
    for (i, [lo, hi]) in system.ranges().into_iter().enumerate() {
        let mut low = corner.clone();
        low.as_mut_slice()[i] = lo;
        let mut high = corner.clone();
        high.as_mut_slice()[i] = hi;
        corner = if limit(&low) < limit(&high) {
            low
        } else {
            high
        };
    }
    corner
}

/// `systems/vtcd.yaml` with each Hertz contact replaced by a linear spring of the Hertz
/// tangent stiffness at `CONTACT_LOAD_FACTOR W`: `1.5 (f W)^(1/3) / G`.
fn spring_contacts(text: &str) -> String {
    let hertz_g = "  hertz_g: {unit: m/N^(2/3), expr: \"4.57 * wheel_radius^-0.149 * 1e-8\", doc: Hertz constant G of a conical tread}\n";
    let mut text = replace_once(
        text,
        hertz_g,
        &format!(
            "{hertz_g}  k_c: {{unit: N/m, expr: \"1.5 * ({CONTACT_LOAD_FACTOR} * W)^(1/3) / hertz_g\"}}\n"
        ),
    );
    // The springs' forces are `f_<element>`: the stored columns and the railway binding follow.
    text = replace_once(
        &text,
        "eta_4, p_1, p_2, p_3, p_4]",
        "eta_4, f_1, f_2, f_3, f_4]",
    );
    text = replace_once(
        &text,
        "contact_forces: [p_1, p_2, p_3, p_4]",
        "contact_forces: [f_1, f_2, f_3, f_4]",
    );
    for j in 1..=4 {
        text = replace_once(
            &text,
            &format!("\"{j}\": {{kind: hertz, from: w{j}, to: r{j}, g: hertz_g, profile: track}}"),
            &format!(
                "\"{j}\": {{kind: spring_damper, from: w{j}, to: r{j}, k: k_c, profile: track}}"
            ),
        );
    }
    text
}

/// `K` and `C` (state order, N/m and N s/m for the rigid DOFs) probed on unit vectors.
fn probe(e: &Engine) -> (DMatrix<f64>, DMatrix<f64>, Vec<f64>) {
    let n = e.layout().len;
    let masses = mbd_engine::statics::state_masses(e);
    let zero = vec![0.0; n];
    let (a0, _) = e.evaluate(0.0, &zero, &zero);
    let mut k = DMatrix::zeros(n, n);
    let mut c = DMatrix::zeros(n, n);
    let mut unit = zero.clone();
    for j in 0..n {
        unit[j] = 1.0;
        let (ak, _) = e.evaluate(0.0, &unit, &zero);
        let (ac, _) = e.evaluate(0.0, &zero, &unit);
        unit[j] = 0.0;
        for i in 0..n {
            k[(i, j)] = -masses[i] * (ak[i] - a0[i]);
            c[(i, j)] = -masses[i] * (ac[i] - a0[i]);
        }
    }
    (k, c, masses)
}

/// Largest `|A_ij - A_ji| / sqrt(|A_ii A_jj|)`.
fn asymmetry(a: &DMatrix<f64>) -> f64 {
    let n = a.nrows();
    let mut worst = 0.0f64;
    for i in 0..n {
        for j in 0..i {
            let scale = (a[(i, i)] * a[(j, j)]).abs().sqrt();
            worst = worst.max((a[(i, j)] - a[(j, i)]).abs() / scale);
        }
    }
    worst
}

/// `lambda_max(M^-1/2 A M^-1/2)`.
fn largest_eigenvalue(a: &DMatrix<f64>, masses: &[f64]) -> f64 {
    let n = a.nrows();
    let scaled = DMatrix::from_fn(n, n, |i, j| {
        0.5 * (a[(i, j)] + a[(j, i)]) / (masses[i] * masses[j]).sqrt()
    });
    SymmetricEigen::new(scaled)
        .eigenvalues
        .iter()
        .fold(f64::NEG_INFINITY, |m, &l| m.max(l))
}

fn short_engines(
    sampled: &Sampled,
    hertz: &Arc<mbd_system::System>,
    spring: &Arc<mbd_system::System>,
) -> (Engine, Engine) {
    // 0.01 s: the longest vehicle at the top speed stays on the 36 m track.
    let cfg = config(0.01, 1e-4, 10, StartMode::Equilibrium, SHORT_X0);
    (
        engine(hertz, sampled, &cfg, vec![None], Route::Fast),
        engine(spring, sampled, &cfg, vec![None], Route::Fast),
    )
}

#[test]
fn stiffness_and_damping_are_symmetric_and_the_stability_bound_holds() {
    let text = system_text("vtcd.yaml");
    let hertz = short_track(&text, &[]);
    let spring = short_track(&spring_contacts(&text), &[]);
    let cases = [
        ("nominal", hertz.nominal()),
        ("light and stiff", extreme(&hertz)),
        ("smallest dt limit", worst_corner(&hertz, SHORT_X0)),
    ];
    for (label, sampled) in cases {
        let (he, se) = short_engines(&sampled, &hertz, &spring);
        let (k, c, masses) = probe(&se);
        let (ak, ac) = (asymmetry(&k), asymmetry(&c));
        println!("{label}: asymmetry of K {ak:.1e}, of C {ac:.1e}");
        assert!(ak < 1e-11 && ac < 1e-11, "{label}: K {ak:e}, C {ac:e}");
        // Couplings in every block.
        let layout = se.layout();
        let modes = layout.beams[0].modes.clone();
        let sup = layout.beams[0].supports.clone();
        let coupled = |rows: std::ops::Range<usize>, cols: std::ops::Range<usize>| {
            rows.clone().any(|i| {
                cols.clone().any(|j| {
                    i != j && k[(i, j)].abs() > 1e-3 * (k[(i, i)] * k[(j, j)]).abs().sqrt()
                })
            })
        };
        let rigid = 0..layout.rigid;
        assert!(coupled(rigid.clone(), rigid.clone()), "body-body");
        assert!(coupled(rigid.clone(), modes.clone()), "body-beam");
        assert!(coupled(modes.clone(), modes.clone()), "mode-mode");
        assert!(coupled(modes.clone(), sup.clone()), "beam-support");
        assert!(coupled(sup.clone(), sup.clone()), "support-support");
        // Frequencies and damping rates against the bounds.
        let omega = largest_eigenvalue(&k, &masses).sqrt();
        let rate = largest_eigenvalue(&c, &masses);
        let (bh, bs) = (Bound::of(&he), Bound::of(&se));
        println!(
            "{label}: highest frequency {omega:.0} rad/s, bound {:.0} (Hertz model) / {:.0} \
             (springs); damping rate {rate:.0} 1/s, bound {:.0} / {:.0}",
            bh.omega_max, bs.omega_max, bh.damping_max, bs.damping_max
        );
        assert!(omega <= bh.omega_max && omega <= bs.omega_max);
        assert!(rate <= bh.damping_max && rate <= bs.damping_max);
        // Meaningful: the bound is an upper bound of this problem, not of another scale.
        assert!(
            bh.omega_max < 3.0 * omega,
            "bound {} far above {omega}",
            bh.omega_max
        );
    }
}

#[test]
fn time_step_above_the_limit_is_refused_and_1e_4_passes_at_the_extreme_corner() {
    let system = load(&system_text("vtcd.yaml"), &[]);
    let sampled = worst_corner(&system, 20.0);
    let ranges = system.ranges();
    let ends: Vec<String> = sampled
        .iter()
        .zip(&ranges)
        .map(|((n, v), r)| format!("{n} {}", if v == r[0] { "min" } else { "max" }))
        .collect();
    println!("the corner of the smallest dt limit: {}", ends.join(", "));
    let model = system.instantiate(&sampled).unwrap();
    let make = |dt: f64| {
        Engine::new(
            system.clone(),
            model.clone(),
            &config(0.01, dt, 10, StartMode::Equilibrium, 20.0),
            vec![None],
        )
    };
    let ok = make(1e-4).unwrap_or_else(|e| panic!("dt = 1e-4 at the extreme corner: {e}"));
    let limit = Bound::of(&ok).dt_limit();
    println!("extreme corner: dt limit {limit:.4e} s");
    assert!(limit > 1e-4);
    assert!(make(limit).is_ok());
    let dt = 1.01 * limit;
    match make(dt) {
        Err(e @ mbd_engine::Error::StepTooLarge { .. }) => {
            let message = e.to_string();
            let mbd_engine::Error::StepTooLarge {
                dt: asked,
                limit: named,
                ..
            } = e
            else {
                unreachable!()
            };
            assert_eq!(asked, dt);
            assert!((named / limit - 1.0).abs() < 1e-12, "{named} vs {limit}");
            assert!(message.contains(&format!("{dt}")), "{message}");
            assert!(message.contains(&format!("{limit:.3e}")), "{message}");
        }
        Err(e) => panic!("dt = {dt}: wrong error {e}"),
        Ok(_) => panic!("dt = {dt} above the limit {limit} was accepted"),
    }
}
