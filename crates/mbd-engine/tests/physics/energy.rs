//! Conservation of mechanical energy without damping: the vehicle-track model (short track)
//! with every damping set to 0, at standstill, on a level track, starting from rest (the
//! wheels drop onto the rail and the whole system oscillates, contacts included). The energy
//! is written here from the description's elements and `docs/model.md`, independently of the
//! engine's force code:
//! ```text
//! E = 1/2 sum m_i z_i'^2 + 1/2 sum J_i beta_i'^2            bodies (half-vehicle masses)
//!   + 1/2 sum q_k'^2 + 1/2 sum m_l z_lj'^2                  rail modes (unit modal mass), supports
//!   + 1/2 k_s (d_s1^2 + d_s2^2) + 1/2 k_p sum d_pi^2        suspensions
//!   + sum 2/5 G^(-3/2) max(delta_i, 0)^(5/2)                Hertz contacts, delta_i = z_wi - w(x_wi)
//!   + 1/2 sum w_k^2 q_k^2                                    rail bending
//!   + sum_j 1/2 k_f (w(x_j) - z_sj)^2 + 1/2 k_b (z_sj - z_bj)^2 + 1/2 k_g z_bj^2
//!   + 1/2 k_w sum over the N + 1 shear links (z_b,j+1 - z_bj)^2  (blocks past the ends fixed)
//!   - W sum z_wi                                             work of the wheel loads
//! ```
//! with `w(x) = sum_k sqrt(2 / (m_r L)) sin(k pi x / L) q_k`. Zhai's method has no numerical
//! damping; its energy oscillates with an amplitude of order `(w dt)^2` and does not drift.
//! Measured over 0.1 s: 8.5e-4 of the largest kinetic energy (107 J) at dt 1e-4, 2.1e-4 at 5e-5
//! (order 2); asserted: below 5e-3 and cut by more than 3 when dt is halved. A missing or
//! misassembled term would leave a deviation of order 1 that does not converge.

use crate::common::*;
use mbd_engine::{Route, StartMode};
use std::f64::consts::PI;

/// The undamped vehicle-track model at standstill on the short track.
fn undamped() -> std::sync::Arc<mbd_system::System> {
    let mut text = standstill(&system_text("vtcd.yaml"));
    for name in ["c_p", "c_s", "c_f"] {
        text = fix_parameter(&text, name, 0.0);
    }
    short_track(&text, &[("c_b", 0.0), ("c_w", 0.0), ("c_g", 0.0)])
}

/// Largest `|E - E_0|` over the largest kinetic energy, and the latter (J).
fn energy_deviation(dt: f64) -> (f64, f64) {
    let system = undamped();
    let sampled = system.nominal();
    let model = system.instantiate(&sampled).unwrap();
    let p = |n: &str| value(&system, &model, n);
    let cfg = config(0.1, dt, 10, StartMode::Rest, SHORT_X0);
    let e = engine(&system, &sampled, &cfg, vec![None], Route::Fast);
    // The description's constants.
    let (k_s, k_p, l_c, l_t) = (p("k_s"), p("k_p"), p("l_c"), p("l_t"));
    let (w_load, g) = (p("W"), p("hertz_g"));
    let (n_f, n_m, s) = (p("n_f") as usize, p("n_m") as usize, p("s"));
    let (m_r, ei) = (p("m_r"), p("rail_e") * p("rail_i"));
    let (m_s, m_b, k_f, k_b, k_w, k_g) =
        (p("m_s"), p("m_b"), p("k_f"), p("k_b"), p("k_w"), p("k_g"));
    let length = n_f as f64 * s;
    let mass_of = |dof: &str| -> f64 {
        let body = &dof[dof.find('_').unwrap() + 1..];
        let whole = |n: &str| p(n) / 2.0;
        match (dof.starts_with("beta"), body.chars().next().unwrap()) {
            (false, 'c') => whole("m_c"),
            (true, 'c') => whole("j_c"),
            (false, 't') => whole("m_t"),
            (true, 't') => whole("j_t"),
            (false, 'w') => whole("m_w"),
            _ => panic!("unexpected DOF {dof}"),
        }
    };
    let dofs: Vec<&str> = system.dofs.iter().map(|d| d.name.as_str()).collect();
    let masses: Vec<f64> = dofs.iter().map(|d| mass_of(d)).collect();
    let at = |name: &str| dofs.iter().position(|d| *d == name).unwrap();
    let rigid = dofs.len();
    let shape =
        |x: f64, k: usize| (2.0 / (m_r * length)).sqrt() * ((k + 1) as f64 * PI * x / length).sin();
    let wheel_x = [2.0 * (l_c + l_t), 2.0 * l_c, 2.0 * l_t, 0.0].map(|o| SHORT_X0 + o);
    let omega2: Vec<f64> = (1..=n_m)
        .map(|k| ei / m_r * (k as f64 * PI / length).powi(4))
        .collect();
    let energy = |x: &[f64], v: &[f64]| -> (f64, f64) {
        let q = &x[rigid..rigid + n_m];
        let qd = &v[rigid..rigid + n_m];
        let (zs, zb) = (&x[rigid + n_m..rigid + n_m + n_f], &x[rigid + n_m + n_f..]);
        let (vs, vb) = (&v[rigid + n_m..rigid + n_m + n_f], &v[rigid + n_m + n_f..]);
        let deflection = |xp: f64| (0..n_m).map(|k| shape(xp, k) * q[k]).sum::<f64>();
        let kinetic = 0.5 * (0..rigid).map(|i| masses[i] * v[i] * v[i]).sum::<f64>()
            + 0.5 * qd.iter().map(|v| v * v).sum::<f64>()
            + 0.5 * m_s * vs.iter().map(|v| v * v).sum::<f64>()
            + 0.5 * m_b * vb.iter().map(|v| v * v).sum::<f64>();
        let z = |n: &str| x[at(n)];
        let d_s = [
            z("z_c") - l_c * z("beta_c") - z("z_t1"),
            z("z_c") + l_c * z("beta_c") - z("z_t2"),
        ];
        let d_p = [
            z("z_t1") - l_t * z("beta_t1") - z("z_w1"),
            z("z_t1") + l_t * z("beta_t1") - z("z_w2"),
            z("z_t2") - l_t * z("beta_t2") - z("z_w3"),
            z("z_t2") + l_t * z("beta_t2") - z("z_w4"),
        ];
        let mut potential = 0.5 * k_s * d_s.iter().map(|d| d * d).sum::<f64>()
            + 0.5 * k_p * d_p.iter().map(|d| d * d).sum::<f64>();
        for (i, xw) in wheel_x.iter().enumerate() {
            let zw = z(&format!("z_w{}", i + 1));
            let delta = zw - deflection(*xw);
            if delta > 0.0 {
                potential += 0.4 * delta.powf(2.5) / g.powf(1.5);
            }
            potential -= w_load * zw;
        }
        potential += 0.5 * omega2.iter().zip(q).map(|(w2, q)| w2 * q * q).sum::<f64>();
        for j in 0..n_f {
            let w = deflection(j as f64 * s);
            potential += 0.5 * k_f * (w - zs[j]).powi(2)
                + 0.5 * k_b * (zs[j] - zb[j]).powi(2)
                + 0.5 * k_g * zb[j].powi(2);
        }
        let shear: f64 = zb.windows(2).map(|p| (p[1] - p[0]).powi(2)).sum::<f64>()
            + zb[0].powi(2)
            + zb[n_f - 1].powi(2);
        potential += 0.5 * k_w * shear;
        (kinetic + potential, kinetic)
    };
    assert_eq!(
        e.layout().len,
        rigid + n_m + 2 * n_f,
        "state layout of the engine's doc"
    );
    let mut e0 = None;
    let (mut deviation, mut kinetic_max) = (0.0f64, 0.0f64);
    e.run_observed(cfg.steps(), None, |st| {
        let (total, kinetic) = energy(st.x, st.v);
        let start = *e0.get_or_insert(total);
        deviation = deviation.max((total - start).abs());
        kinetic_max = kinetic_max.max(kinetic);
    })
    .unwrap();
    (deviation / kinetic_max, kinetic_max)
}

#[test]
fn undamped_energy_is_conserved_to_the_integrators_order() {
    let (coarse, kinetic) = energy_deviation(1e-4);
    let (fine, _) = energy_deviation(5e-5);
    println!(
        "largest kinetic energy {kinetic:.3} J; energy deviation {coarse:.2e} (dt 1e-4), {fine:.2e} \
         (dt 5e-5) of it"
    );
    // Meaningful: the drop converts real energy (the wheels fall ~1 mm under 70 kN).
    assert!(kinetic > 1.0, "{kinetic}");
    assert!(coarse < 5e-3, "{coarse:e}");
    assert!(
        coarse / fine > 3.0,
        "not second order: {coarse:e} -> {fine:e}"
    );
}
