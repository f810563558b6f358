//! Order of the fixed-step solver where a damper reads a generated profile. The damper's force
//! holds `c v d eta / dx`: with linear interpolation that slope is piecewise constant and jumps
//! at every profile point, a force discontinuity in time each `dx / v` that Zhai's two-step
//! formulas carry with an O(dt) error, so the global error falls only ~2x per halving of dt;
//! the not-a-knot cubic (`interpolation: cubic`) has a continuous slope and the solver keeps its
//! second order (~4x per halving). Measured by self-convergence, with no reference solution:
//! `e(dt) = max |y_dt - y_{dt/2}|` over the stored rows (same output times) of each compared
//! column, and the ratio `e(dt) / e(dt/2)` (4 for second order, 2 for first).
//!
//! Without a damper the jumps still act: a stiff contact rings at each one, which the last test
//! measures on the vehicle track's wheels.

use crate::common::{column, config, engine, generated_profile, load, system_text};
use mbd_engine::{Route, StartMode};
use mbd_system::System;
use std::sync::Arc;

/// A two-axle vehicle on a road: a body in bounce and pitch on two suspension spring-dampers,
/// two wheels on tyres with damping that read the road (every damper of the wheels reads the
/// profile's rate). SI units, z positive downward.
const TWO_AXLE: &str = r#"
format: 1
name: two-axle
parameters:
  m_b: {unit: kg, value: 1200}
  j_b: {unit: kg m^2, value: 1500}
  a: {unit: m, value: 1.3}
  b: {unit: m, value: 1.5}
  m_w: {unit: kg, value: 40}
  k_s: {unit: N/m, value: 30000}
  c_s: {unit: N s/m, value: 2000}
  k_t: {unit: N/m, value: 200000}
  c_t: {unit: N s/m, value: 300}
  v: {unit: m/s, value: 20}
  g: {unit: m/s^2, value: 9.81}
bodies:
  c: {mass: m_b, inertia: j_b, dofs: [z, pitch], points: {front: a, rear: -b}}
  wf: {mass: m_w, dofs: [z]}
  wr: {mass: m_w, dofs: [z]}
moving:
  speed: v
  points:
    rf: {on: ground, offset: a + b}
    rr: {on: ground, offset: 0}
profiles:
  road:
    kind: generated
    psd: {iso8608: C}
    wavelengths: [0.5, 90.0]
    interpolation: linear
elements:
  sf: {kind: spring_damper, from: c.front, to: wf, k: k_s, c: c_s, preload: m_b * g * b / (a + b)}
  sr: {kind: spring_damper, from: c.rear, to: wr, k: k_s, c: c_s, preload: m_b * g * a / (a + b)}
  tf: {kind: spring_damper, from: wf, to: rf, k: k_t, c: c_t, profile: road, preload: (m_b * b / (a + b) + m_w) * g}
  tr: {kind: spring_damper, from: wr, to: rr, k: k_t, c: c_t, profile: road, preload: (m_b * a / (a + b) + m_w) * g}
loads:
  body: {at: c, force: m_b * g}
  front: {at: wf, force: m_w * g}
  rear: {at: wr, force: m_w * g}
outputs: [f_tf, f_tr]
"#;

/// `text` with its one generated profile read by `interpolation`: its `interpolation:` line
/// replaced, or one added after its `wavelengths:`.
fn with_interpolation(text: &str, interpolation: &str) -> String {
    let line = format!("    interpolation: {interpolation}");
    let mut out: Vec<String> = Vec::new();
    let mut set = 0;
    for l in text.lines() {
        let key = l.trim_start();
        if key.starts_with("interpolation:") {
            out.push(line.clone());
            set += 1;
        } else {
            out.push(l.to_owned());
            if key.starts_with("wavelengths:") && !text.contains("interpolation:") {
                out.push(line.clone());
                set += 1;
            }
        }
    }
    assert_eq!(set, 1, "one generated profile");
    out.join("\n") + "\n"
}

/// The ratios `e(dt) / e(dt/2)` per column of `columns`, from runs at `dt`, `dt/2` and `dt/4`
/// stored every 1 ms from x0 = 5 m, on the generated profile (seed 3, spacing `dx`, 200 m,
/// sample 0).
fn halving_ratios(
    system: &Arc<System>,
    columns: &[&str],
    dt: f64,
    duration: f64,
    dx: f64,
) -> Vec<f64> {
    let profile = generated_profile(system, 3, dx, 200.0, 0);
    let output = 1e-3;
    let runs: Vec<_> = [dt, dt / 2.0, dt / 4.0]
        .iter()
        .map(|&h| {
            let every = (output / h).round() as usize;
            let cfg = config(duration, h, every, StartMode::Equilibrium, 5.0);
            let e = engine(
                system,
                &system.nominal(),
                &cfg,
                vec![Some(profile.clone())],
                Route::Fast,
            );
            e.run().unwrap()
        })
        .collect();
    columns
        .iter()
        .map(|name| {
            let y: Vec<&[f64]> = runs.iter().map(|r| column(system, r, name)).collect();
            let diff = |a: &[f64], b: &[f64]| {
                assert_eq!(a.len(), b.len());
                a.iter()
                    .zip(b)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            };
            let (coarse, fine) = (diff(y[0], y[1]), diff(y[1], y[2]));
            // Far above round-off: the ratio measures the scheme, not the arithmetic.
            let scale = y[2].iter().map(|v| v.abs()).fold(0.0, f64::max);
            assert!(fine > 1e-12 * scale, "{name}: {fine:e} of {scale:e}");
            println!("{name}: e(dt) {coarse:.3e}, e(dt/2) {fine:.3e}");
            coarse / fine
        })
        .collect()
}

/// One convergence case: name, description text, compared columns, dt (s), duration (s),
/// whether the linear profile stalls.
type Case<'a> = (&'a str, &'a str, &'a [&'a str], f64, f64, bool);

/// Second order with a cubic profile (every ratio >= 3.5), and the stall that motivates it with
/// the linear one (some ratio < 3) on the same profile points, for the bridge (the suspension
/// damper reads the deck roughness) and a two-axle vehicle with damped tyres on a road. The
/// quarter car's road is read by an undamped tyre only (a spring: the profile itself is
/// continuous either way), so it keeps second order with both.
#[test]
fn a_damper_on_a_cubic_profile_keeps_second_order() {
    let bridge = system_text("bridge.yaml");
    let quarter = system_text("quarter-car.yaml");
    let cases: [Case; 3] = [
        ("bridge", &bridge, &["z_v", "f_suspension"], 1e-4, 0.6, true),
        (
            "two-axle",
            TWO_AXLE,
            &["z_c", "beta_c", "f_tf", "f_tr"],
            2e-4,
            1.0,
            true,
        ),
        (
            "quarter-car",
            &quarter,
            &["z_s", "z_u", "f_tyre"],
            2e-4,
            1.0,
            false,
        ),
    ];
    for (case, text, columns, dt, duration, linear_stalls) in cases {
        for interpolation in ["cubic", "linear"] {
            let system = load(&with_interpolation(text, interpolation), &[]);
            let ratios = halving_ratios(&system, columns, dt, duration, 0.1);
            println!("{case}, {interpolation}: ratios {ratios:.2?}");
            if interpolation == "linear" && linear_stalls {
                assert!(
                    ratios.iter().any(|&r| r < 3.0),
                    "{case}, {interpolation}: expected the stall, found {ratios:.2?}"
                );
            } else {
                assert!(
                    ratios.iter().all(|&r| r >= 3.5),
                    "{case}, {interpolation}: halving dt cut the errors by {ratios:.2?}"
                );
            }
        }
    }
}

/// The standard deviation of `x` (sampled every `dt` s) and the share of it at or above `f_min`
/// (Hz): `sqrt(sum_{f >= f_min} |X_f|^2 / sum_{f > 0} |X_f|^2)` of the mean-removed record, by
/// Parseval.
fn spread_and_high_band_share(x: &[f64], dt: f64, f_min: f64) -> (f64, f64) {
    use rustfft::{num_complex::Complex, FftPlanner};
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut spectrum: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v - mean, 0.0)).collect();
    let spread = (spectrum.iter().map(|c| c.re * c.re).sum::<f64>() / n as f64).sqrt();
    FftPlanner::new().plan_fft_forward(n).process(&mut spectrum);
    let (mut high, mut all) = (0.0, 0.0);
    for (k, c) in spectrum.iter().enumerate().skip(1).take(n / 2) {
        let power = c.norm_sqr();
        all += power;
        if k as f64 / (n as f64 * dt) >= f_min {
            high += power;
        }
    }
    (spread, (high / all).sqrt())
}

/// A Hertz contact, with no damper, still feels the slope jumps of a linear profile: met every
/// `dx / v` (at 325 km/h over 0.1 m, 903 Hz), each is a kick near the wheel's ringing on its
/// contact spring, and the contact forces ring. The vehicle track's nominal design on the
/// pipeline's first profile (seed 1, 0.1 m, the full track), stored at every step (10 kHz) for
/// 1 s and read from 0.2 s: with `linear` the forces above 300 Hz are 7.6-9.5 % of their standard
/// deviation (the track's band ends at 49 Hz); the cubic spline through the same points leaves
/// 0.3-1.8 % (BENCHMARKS.md, "The wheel-load reduction rate, third look": 9-10 % against
/// 0.2-2.4 % on four profiles over 1.8 s), while the forces' spread is the same.
#[test]
fn a_linear_profile_rings_the_wheels_at_its_point_rate() {
    let text = system_text("vtcd.yaml");
    let (dt, duration, from) = (1e-4, 1.0, 0.2);
    let mut shares = Vec::new();
    let mut spreads = Vec::new();
    for interpolation in ["linear", "cubic"] {
        let system = load(&with_interpolation(&text, interpolation), &[]);
        let profile = generated_profile(&system, 1, 0.1, 540.0, 0);
        let cfg = config(duration, dt, 1, StartMode::Equilibrium, 20.0);
        let run = engine(
            &system,
            &system.nominal(),
            &cfg,
            vec![Some(profile)],
            Route::Fast,
        )
        .run()
        .unwrap();
        let first = (from / dt).round() as usize;
        let contacts = &system
            .railway
            .as_ref()
            .expect("railway binding")
            .contact_forces;
        let (spread, share): (Vec<f64>, Vec<f64>) = contacts
            .iter()
            .map(|&c| spread_and_high_band_share(&run.columns[c][first..], dt, 300.0))
            .unzip();
        println!("{interpolation}: above 300 Hz {share:.4?} of the spread {spread:.0?} N");
        shares.push(share);
        spreads.push(spread);
    }
    for wheel in 0..shares[0].len() {
        let (linear, cubic) = (shares[0][wheel], shares[1][wheel]);
        assert!(
            linear > 0.04,
            "wheel {}: linear rings {linear:.4}",
            wheel + 1
        );
        assert!(
            cubic < linear / 3.0,
            "wheel {}: cubic {cubic:.4} against linear {linear:.4}",
            wheel + 1
        );
        let (a, b) = (spreads[0][wheel], spreads[1][wheel]);
        assert!(
            (a - b).abs() < 0.05 * a,
            "wheel {}: spread {a} against {b} N",
            wheel + 1
        );
    }
}
