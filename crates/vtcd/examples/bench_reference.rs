//! Benchmark: compute seconds per simulated second of one sample at paper fidelity
//! (N_f = 900, N_M = 450, dt = 1e-4), single-threaded, nominal vehicle, irregularity on.
//!
//! ```text
//! RAYON_NUM_THREADS=1 cargo run --release -p vtcd --example bench_reference -- [duration_s] [runs] [start]
//! ```
//! `start` is `equilibrium` (default) or `rest`; the equilibrium start's static solve is timed
//! on its own too.
//! Prints each run and the median. The solver itself is single-threaded; rayon only spreads
//! samples in the stage. Besides wall time it reads this thread's on-CPU time from
//! `/proc/thread-self/schedstat` (Linux), which stays meaningful when other processes share
//! the cores; the median of that CPU time is the headline figure.

use std::time::Instant;
use vtcd::params::SampleParams;
use vtcd::simulation::{Profile, Simulation, SimulationConfig, StartMode};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let duration: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let start = match args.get(3).map(String::as_str) {
        None | Some("equilibrium") => StartMode::Equilibrium,
        Some("rest") => StartMode::Rest,
        Some(other) => panic!("start `{other}`: allowed `equilibrium` or `rest`"),
    };
    let config = SimulationConfig {
        duration,
        start,
        ..Default::default()
    };
    // A smooth stand-in profile (0.6 mm, 20 m and 3.7 m wavelengths) over the whole rail:
    // the cost does not depend on the profile's content.
    let n = 5401;
    let x: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
    let eta: Vec<f64> = x
        .iter()
        .map(|x| {
            6e-4 * (x * std::f64::consts::TAU / 20.0).sin()
                + 1e-4 * (x * std::f64::consts::TAU / 3.7).sin()
        })
        .collect();
    let profile = Profile::new(x, eta).expect("valid profile");
    let sim = Simulation::new(&SampleParams::NOMINAL, &config, Some(profile)).expect("valid model");
    let bound = vtcd::stability::spectrum_bound(
        sim.vehicle(),
        sim.track(),
        sim.params().k_f,
        sim.params().c_f,
        sim.hertz_g(),
        [
            config.x0,
            config.x0 + sim.speed() * duration + sim.offsets()[0],
        ],
    );
    println!(
        "stability: omega_max <= {:.0} rad/s, damping rate <= {:.0} 1/s, dt limit {:.3e} s (dt = {:e})",
        bound.omega_max,
        bound.damping_max,
        bound.dt_limit(),
        config.dt
    );
    transforms_only(&config, 3);
    // The initial state alone (the static solve of the equilibrium start), wall-clock median
    // of 21 (too short for the scheduler's CPU-time accounting).
    let mut init: Vec<f64> = (0..21)
        .map(|_| {
            let start = Instant::now();
            let x = sim.initial_state().expect("static solve");
            assert_eq!(x.len(), sim.state_len());
            start.elapsed().as_secs_f64()
        })
        .collect();
    init.sort_by(f64::total_cmp);
    println!(
        "initial state ({:?} start): {:.3} ms wall",
        config.start,
        init[10] * 1e3
    );
    let mut per_sim_second = Vec::new();
    for run in 0..runs {
        let start = Instant::now();
        let cpu0 = thread_cpu_seconds();
        let traj = sim.run().expect("finite run");
        let cpu = thread_cpu_seconds().zip(cpu0).map(|(b, a)| b - a);
        let wall = start.elapsed().as_secs_f64();
        let secs = cpu.unwrap_or(wall);
        let ratio = secs / duration;
        let steps = config.steps();
        println!(
            "run {run}: cpu {secs:.3} s (wall {wall:.3} s) for {duration} s simulated ({steps} steps, {:.2} us/step, {} rows): {ratio:.4} s per simulated s",
            secs / steps as f64 * 1e6,
            traj.t.len()
        );
        per_sim_second.push(ratio);
    }
    // Plausibility of the physics on this run: wheel-load range after the fade-in, rail
    // deflection under wheel 1, car-body motion.
    let traj = sim.run().expect("finite run");
    let from = traj.t.len() / 5;
    let range = |c: usize| {
        let v = &traj.columns[c][from..];
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let col = vtcd::simulation::col::P;
    let (p_lo, p_hi) = range(col);
    let (zr_lo, zr_hi) = range(vtcd::simulation::col::Z_R);
    let (zc_lo, zc_hi) = range(vtcd::simulation::col::Z);
    println!(
        "physics: P_1 in [{:.1}, {:.1}] kN (W = {:.1} kN), z_r1 in [{:.3}, {:.3}] mm, z_c in [{:.3}, {:.3}] mm",
        p_lo / 1e3,
        p_hi / 1e3,
        sim.vehicle().w / 1e3,
        zr_lo * 1e3,
        zr_hi * 1e3,
        zc_lo * 1e3,
        zc_hi * 1e3
    );
    per_sim_second.sort_by(f64::total_cmp);
    let median = per_sim_second[per_sim_second.len() / 2];
    println!("median: {median:.4} s compute per simulated s (paper MATLAB: 25; target 0.2)");
    let sample_secs = median * 5.0;
    println!(
        "paper scale (5 s): {sample_secs:.2} s per sample per core, {:.0} samples/hour on 2 cores, 20000 samples in {:.1} h on 2 cores",
        2.0 * 3600.0 / sample_secs,
        20000.0 * sample_secs / 2.0 / 3600.0
    );
}

/// On-CPU time of this thread (s), from `/proc/thread-self/schedstat` (first field, ns).
fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// Times the two sine transforms of a step alone (modal -> fasteners with N_M inputs,
/// fasteners -> modes with N_M outputs), the floor of this solver's step.
fn transforms_only(config: &SimulationConfig, runs: usize) {
    let (nf, nm) = (config.track.n_f, config.track.n_m);
    let mut dst = vtcd::rail::SineTransform::new(nf);
    let modal: Vec<f64> = (0..nm).map(|k| 1.0 / (1.0 + k as f64)).collect();
    let (mut seat, mut back) = (vec![0.0; nf - 1], vec![0.0; nm]);
    let steps = config.steps();
    let mut per_step = Vec::new();
    for _ in 0..runs {
        let cpu0 = thread_cpu_seconds().unwrap_or(0.0);
        let start = Instant::now();
        for _ in 0..steps {
            dst.apply(&modal, &mut seat);
            dst.apply(&seat, &mut back);
        }
        let secs = thread_cpu_seconds().map_or(start.elapsed().as_secs_f64(), |t| t - cpu0);
        per_step.push(secs / steps as f64);
        std::hint::black_box(&back);
    }
    per_step.sort_by(f64::total_cmp);
    println!(
        "two sine transforms alone: {:.2} us per step (median of {runs})",
        per_step[runs / 2] * 1e6
    );
}
