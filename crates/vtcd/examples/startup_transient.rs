//! Measurement: how long the start-up of a run disturbs the data, for the rest and
//! equilibrium starts and several irregularity start-up schedules (issue 7).
//!
//! ```text
//! cargo run --release -p vtcd --example startup_transient -- [samples]
//! ```
//!
//! Samples are the pipeline's own draws (sampling seed 1, irregularity seed 1, ids 0..n), at
//! paper fidelity on the full 540 m track. Two measurements, each printed per time bin after
//! the start:
//!
//! 1. Irregularity off: the wheel-load deviation `max |P_i - W| / W` and the car-body travel
//!    `max |z_c(t) - z_c(0)|` (from rest `z_c(0) = 0`, so this is the drop).
//! 2. Irregularity on: the difference to a *stationary reference*, the same sample run from
//!    3.3 s earlier on the same track (the reference's start-up lies 3.3 s in the past: car-body
//!    memory decays as exp(-c t / m), about exp(-3.4) here). Compared at the same track
//!    positions (protocol time t = reference time t + 3.3 s), the difference is what the
//!    protocol's start adds to the data: `max |dP| / W`, `max |dz_c|`, `max |dz_w1|`. The
//!    floor of the measurement is shown by a second reference started 2.8 s earlier.
//! 3. What a learning window that starts at `t_w > 0` cannot see: the run started at 0
//!    (equilibrium, irregularity on from the start) against the same sample started at `t_w`
//!    (static at `t_w`), compared from `t_w` on (bins in s after `t_w`). The difference is the
//!    part of the windowed response set by the irregularity before the window.

use rayon::prelude::*;
use std::collections::BTreeMap;
use vtcd::irregularity::IrregularityParams;
use vtcd::params::SampleParams;
use vtcd::sampling::SamplingParams;
use vtcd::simulation::{col, Profile, Simulation, SimulationConfig, StartMode, Trajectory};

/// Protocol run length (s) and the stationary reference's lead (s).
const RUN: f64 = 1.5;
const LEAD: f64 = 3.3;
const LEAD_FLOOR: f64 = 2.8;
const WINDOW_STARTS: [f64; 2] = [0.1, 0.25];
const BINS: [f64; 9] = [0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5];

/// Per bin: the three maxima of [`compare`].
type Bins = Vec<[f64; 3]>;
/// One sample: irregularity-off tables (rest, equilibrium), irregularity-on tables (per
/// protocol, the floor, the window starts) and the stationary scales (P_1 std % of W, z_c std
/// um).
type SampleResult = (Vec<Bins>, Vec<Bins>, [f64; 2]);

struct Protocol {
    name: &'static str,
    start: StartMode,
    /// Irregularity off for this long (s), then faded in over `ramp` (s).
    zero: f64,
    ramp: f64,
}

fn run(
    p: &SampleParams,
    profile: &Profile,
    start: StartMode,
    x0: f64,
    duration: f64,
    zero: f64,
    ramp: f64,
) -> Trajectory {
    let cfg = SimulationConfig {
        duration,
        start,
        x0,
        startup_zero_fraction: zero / duration,
        startup_ramp_fraction: ramp / duration,
        ..Default::default()
    };
    Simulation::new(p, &cfg, Some(profile.clone()))
        .expect("valid model")
        .run()
        .expect("finite run")
}

/// Per bin: max over wheels of |dP| / W (%), |dz_c| (um), |dz_w1| (um).
fn compare(a: &Trajectory, b: &Trajectory, shift: usize, w: f64) -> Bins {
    let mut out = vec![[0.0f64; 3]; BINS.len() - 1];
    for (r, &t) in a.t.iter().enumerate() {
        let Some(bin) = BINS.windows(2).position(|s| t >= s[0] && t < s[1]) else {
            continue;
        };
        let rb = r + shift;
        let dp = (0..4)
            .map(|i| (a.columns[col::P + i][r] - b.columns[col::P + i][rb]).abs())
            .fold(0.0f64, f64::max);
        let dzc = (a.columns[col::Z][r] - b.columns[col::Z][rb]).abs();
        let dzw = (a.columns[col::Z + 6][r] - b.columns[col::Z + 6][rb]).abs();
        let o = &mut out[bin];
        o[0] = o[0].max(100.0 * dp / w);
        o[1] = o[1].max(1e6 * dzc);
        o[2] = o[2].max(1e6 * dzw);
    }
    out
}

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(8);
    let plan = SamplingParams {
        seed: 1,
        n_train: n,
        n_validation: 1,
        n_test: 1,
        ranges: BTreeMap::new(),
    }
    .validate()
    .expect("default ranges");
    let generator = IrregularityParams::with_seed(1)
        .validate()
        .expect("default irregularity");
    let x = generator.positions();
    let protocols = [
        Protocol {
            name: "rest, zero 0.2 s, ramp 0.2 s (today)",
            start: StartMode::Rest,
            zero: 0.2,
            ramp: 0.2,
        },
        Protocol {
            name: "equilibrium, zero 0.2 s, ramp 0.2 s",
            start: StartMode::Equilibrium,
            zero: 0.2,
            ramp: 0.2,
        },
        Protocol {
            name: "equilibrium, zero 0, ramp 0.2 s",
            start: StartMode::Equilibrium,
            zero: 0.0,
            ramp: 0.2,
        },
        Protocol {
            name: "equilibrium, zero 0, ramp 0.1 s",
            start: StartMode::Equilibrium,
            zero: 0.0,
            ramp: 0.1,
        },
        Protocol {
            name: "equilibrium, zero 0, ramp 0.05 s",
            start: StartMode::Equilibrium,
            zero: 0.0,
            ramp: 0.05,
        },
        Protocol {
            name: "equilibrium, zero 0, ramp 0 (on at t = 0)",
            start: StartMode::Equilibrium,
            zero: 0.0,
            ramp: 0.0,
        },
    ];
    let rows = ((RUN / 1e-3).round()) as usize;
    // Per sample: (off: [rest, eq]) and (on: per protocol, then the floor).
    let results: Vec<SampleResult> = (0..n)
        .into_par_iter()
        .map(|id| {
            let p = plan.draw(id);
            let profile = Profile::new(x.clone(), generator.profile(id)).expect("profile");
            let v = p.speed();
            let w = vtcd::vehicle::Vehicle::new(&p, 9.81).w;
            // 1. Irregularity off (the whole run): deviation from the static state.
            let off: Vec<Bins> = [StartMode::Rest, StartMode::Equilibrium]
                .iter()
                .map(|&start| {
                    let tr = run(&p, &profile, start, 20.0, RUN, RUN, 0.0);
                    let mut still = tr.clone();
                    for c in 0..still.columns.len() {
                        let first = if c >= col::P { w } else { tr.columns[c][0] };
                        still.columns[c].iter_mut().for_each(|v| *v = first);
                    }
                    compare(&tr, &still, 0, w)
                })
                .collect();
            // 2. Irregularity on, against the stationary reference.
            let x0 = 20.0 + v * LEAD;
            let reference = run(
                &p,
                &profile,
                StartMode::Equilibrium,
                20.0,
                LEAD + RUN,
                0.0,
                0.5,
            );
            let shift = (LEAD / 1e-3).round() as usize;
            let mut on: Vec<Bins> = protocols
                .iter()
                .map(|pr| {
                    let tr = run(&p, &profile, pr.start, x0, RUN, pr.zero, pr.ramp);
                    compare(&tr, &reference, shift, w)
                })
                .collect();
            let floor_ref = run(
                &p,
                &profile,
                StartMode::Equilibrium,
                20.0 + v * (LEAD - LEAD_FLOOR),
                LEAD_FLOOR + RUN,
                0.0,
                0.5,
            );
            let shift_floor = (LEAD_FLOOR / 1e-3).round() as usize;
            let mut floor = floor_ref.clone();
            for c in &mut floor.columns {
                c.drain(..shift_floor);
            }
            floor.t = floor.t[shift_floor..].to_vec();
            for t in &mut floor.t {
                *t -= LEAD_FLOOR;
            }
            on.push(compare(&floor, &reference, shift, w));
            // 3. Window starts t_w: the run from 0 vs the run started at t_w.
            let from_zero = run(&p, &profile, StartMode::Equilibrium, x0, RUN, 0.0, 0.0);
            for t_w in WINDOW_STARTS {
                let late = run(
                    &p,
                    &profile,
                    StartMode::Equilibrium,
                    x0 + v * t_w,
                    RUN - t_w,
                    0.0,
                    0.0,
                );
                on.push(compare(&late, &from_zero, (t_w / 1e-3).round() as usize, w));
            }
            // Signal scale of the stationary response over the run: std of P_1 / W (%) and
            // of z_c (um).
            let std = |c: usize, k: f64| {
                let s = &reference.columns[c][shift..shift + rows];
                let m = s.iter().sum::<f64>() / s.len() as f64;
                k * (s.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / s.len() as f64).sqrt()
            };
            (off, on, [std(col::P, 100.0 / w), std(col::Z, 1e6)])
        })
        .collect();
    let bins: Vec<String> = BINS
        .windows(2)
        .map(|b| format!("{}-{}", b[0], b[1]))
        .collect();
    let print = |title: &str, get: &dyn Fn(usize) -> Bins| {
        println!("\n{title}");
        println!(
            "| quantity | {} |\n|---|{}",
            bins.join(" | "),
            "---|".repeat(bins.len())
        );
        for (q, label) in ["max |dP|/W (%)", "max |dz_c| (um)", "max |dz_w1| (um)"]
            .iter()
            .enumerate()
        {
            let cells: Vec<String> = (0..BINS.len() - 1)
                .map(|b| {
                    let v = (0..n as usize).map(|s| get(s)[b][q]).fold(0.0f64, f64::max);
                    format!("{v:.3}")
                })
                .collect();
            println!("| {label} | {} |", cells.join(" | "));
        }
    };
    println!("{n} samples (sampling seed 1, irregularity seed 1), bins in s after the start; maxima over samples");
    for (k, name) in ["rest", "equilibrium"].iter().enumerate() {
        print(
            &format!(
                "Irregularity off, {name} start: deviation from W and car-body travel from z_c(0)"
            ),
            &|s| results[s].0[k].clone(),
        );
    }
    for (k, pr) in protocols.iter().enumerate() {
        print(
            &format!(
                "Irregularity on, {}: difference to the stationary reference",
                pr.name
            ),
            &|s| results[s].1[k].clone(),
        );
    }
    print(
        &format!("Measurement floor: reference started {LEAD_FLOOR} s earlier vs {LEAD} s earlier"),
        &|s| results[s].1[protocols.len()].clone(),
    );
    for (k, t_w) in WINDOW_STARTS.iter().enumerate() {
        print(
            &format!(
                "Window from {t_w} s: run from 0 vs run started at {t_w} s (bins after {t_w} s)"
            ),
            &|s| results[s].1[protocols.len() + 1 + k].clone(),
        );
    }
    let mean = |k: usize| results.iter().map(|r| r.2[k]).sum::<f64>() / n as f64;
    println!(
        "\nStationary response over {RUN} s (mean over samples): std of P_1 = {:.2} % of W, std of z_c = {:.1} um",
        mean(0),
        mean(1)
    );
}
