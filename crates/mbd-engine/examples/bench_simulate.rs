//! Benchmark: compute seconds per simulated second of one sample of a described system,
//! single-threaded, nominal parameters, a smooth stand-in profile under every generated profile.
//!
//! ```text
//! cargo run --release -p mbd-engine --example bench_simulate -- [system.yaml] [duration_s] [runs] [x0]
//! ```
//! Defaults: `systems/vtcd.yaml`, 1 s, 5 runs, x0 = 20 m; equilibrium start, dt = 1e-4, 1 kHz
//! output. Besides wall time it reads this thread's on-CPU time from
//! `/proc/thread-self/schedstat` (Linux), meaningful when other processes share the cores; the
//! median of that CPU time is the headline figure.

use mbd_engine::{Engine, Profile, RunConfig, StartMode};
use std::sync::Arc;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let file = args.get(1).map_or("systems/vtcd.yaml", String::as_str);
    let duration: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let runs: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5);
    let x0: f64 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(20.0);
    let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{file}: {e}"));
    let system = Arc::new(
        mbd_system::load_str(&text, file, &Default::default()).unwrap_or_else(|d| panic!("{d}")),
    );
    let config = RunConfig {
        duration,
        dt: 1e-4,
        output_every: 10,
        start: StartMode::Equilibrium,
        startup_zero_fraction: 0.0,
        startup_ramp_fraction: 0.0,
        x0,
    };
    // A smooth stand-in profile (0.6 mm, 20 m and 3.7 m wavelengths) over 2 km: the cost does
    // not depend on the profile's content.
    let x: Vec<f64> = (0..20001).map(|i| i as f64 * 0.1 - 100.0).collect();
    let eta: Vec<f64> = x
        .iter()
        .map(|x| {
            6e-4 * (x * std::f64::consts::TAU / 20.0).sin()
                + 1e-4 * (x * std::f64::consts::TAU / 3.7).sin()
        })
        .collect();
    let profiles = vec![Some(Profile::new(x, eta).expect("valid profile")); system.profiles.len()];
    let model = system
        .instantiate(&system.nominal())
        .expect("nominal model");
    let engine = Engine::new(system.clone(), model, &config, profiles).expect("valid model");
    let bound = mbd_engine::stability::Bound::of(&engine);
    println!(
        "{}: {} state entries; stability: omega_max <= {:.0} rad/s, dt limit {:.3e} s",
        system.name,
        engine.layout().len,
        bound.omega_max,
        bound.dt_limit()
    );
    let mut per_sim_second = Vec::new();
    for run in 0..runs {
        let start = Instant::now();
        let cpu0 = thread_cpu_seconds();
        let traj = engine.run().expect("finite run");
        let cpu = thread_cpu_seconds().zip(cpu0).map(|(b, a)| b - a);
        let wall = start.elapsed().as_secs_f64();
        let secs = cpu.unwrap_or(wall);
        let steps = config.steps();
        println!(
            "run {run}: cpu {secs:.3} s (wall {wall:.3} s), {:.2} us/step, {} rows: {:.4} s per simulated s",
            secs / steps as f64 * 1e6,
            traj.t.len(),
            secs / duration
        );
        per_sim_second.push(secs / duration);
    }
    per_sim_second.sort_by(f64::total_cmp);
    let median = per_sim_second[per_sim_second.len() / 2];
    println!("median: {median:.4} s compute per simulated s");
    println!(
        "samples of {duration} s per hour on 2 cores: {:.0}",
        2.0 * 3600.0 / (median * duration)
    );
}

/// On-CPU time of this thread (s), from `/proc/thread-self/schedstat` (first field, ns).
fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}
