//! Benchmark: compute seconds per simulated second of one sample at paper fidelity
//! (N_f = 900, N_M = 450, dt = 1e-4), single-threaded, nominal vehicle, irregularity on.
//!
//! ```text
//! RAYON_NUM_THREADS=1 cargo run --release -p vtcd --example bench_simulate -- [duration_s] [runs]
//! ```
//! Prints each run and the median. The solver itself is single-threaded; rayon only spreads
//! samples in the stage.

use std::time::Instant;
use vtcd::params::SampleParams;
use vtcd::simulation::{Profile, Simulation, SimulationConfig};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let duration: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let config = SimulationConfig {
        duration,
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
    let mut per_sim_second = Vec::new();
    for run in 0..runs {
        let start = Instant::now();
        let traj = sim.run().expect("finite run");
        let secs = start.elapsed().as_secs_f64();
        let ratio = secs / duration;
        let steps = config.steps();
        println!(
            "run {run}: {secs:.3} s for {duration} s simulated ({steps} steps, {:.2} us/step, {} rows): {ratio:.4} s per simulated s",
            secs / steps as f64 * 1e6,
            traj.t.len()
        );
        per_sim_second.push(ratio);
    }
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
