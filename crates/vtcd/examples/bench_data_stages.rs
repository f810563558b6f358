//! Benchmark of the per-sample work of the `irregularity` and `weights` stages, one core.
//!
//! ```text
//! cargo run --release -p vtcd --example bench_data_stages
//! ```
//!
//! - irregularity: one 540-m profile at dx = 0.1 m (5400 points, 266 bins), the pipeline's
//!   default, and a 5-s record's worth at paper scale (same profile: the length is the rail's);
//! - weights: `magnitude_weights` on a 5000-point record (5 s at 1 kHz, window from 10%: the
//!   paper's 4500 points) with all 38 signals.
//!
//! Prints the median over 7 repeats of the mean time per sample.

use std::time::Instant;
use vtcd::irregularity::IrregularityParams;
use vtcd::params::SampleParams;
use vtcd::vehicle::NUM_DOFS;
use vtcd::weights::{magnitude_weights, SampleSignals, WeightConfig};

fn median_per_item(repeats: usize, items: u64, mut f: impl FnMut(u64)) -> f64 {
    let mut times: Vec<f64> = (0..repeats)
        .map(|_| {
            let t = Instant::now();
            for i in 0..items {
                f(i);
            }
            t.elapsed().as_secs_f64() / items as f64
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[repeats / 2]
}

fn main() {
    let g = IrregularityParams::with_seed(1)
        .validate()
        .expect("defaults are valid");
    let per_profile = median_per_item(7, 500, |id| {
        std::hint::black_box(g.profile(id));
    });
    println!(
        "irregularity: {:.1} us per profile ({} points, {} bins)",
        per_profile * 1e6,
        g.len(),
        g.bins().len()
    );

    // A 5000-point record with smooth signals (values do not change the work).
    let n = 5000;
    let sig = |k: usize| -> Vec<f64> {
        (0..n)
            .map(|t| 1e-3 * ((t * (k + 1)) as f64 * 1e-3).sin())
            .collect()
    };
    let z: Vec<Vec<f64>> = (0..NUM_DOFS).map(sig).collect();
    let v: Vec<Vec<f64>> = (0..NUM_DOFS).map(|k| sig(k + 10)).collect();
    let a: Vec<Vec<f64>> = (0..NUM_DOFS).map(|k| sig(k + 20)).collect();
    let zr: Vec<Vec<f64>> = (0..4).map(|k| sig(k + 30)).collect();
    let eta: Vec<Vec<f64>> = (0..4).map(|k| sig(k + 34)).collect();
    let s = SampleSignals {
        z: std::array::from_fn(|i| z[i].as_slice()),
        v: std::array::from_fn(|i| v[i].as_slice()),
        a: std::array::from_fn(|i| a[i].as_slice()),
        z_r: std::array::from_fn(|j| zr[j].as_slice()),
        eta: std::array::from_fn(|j| eta[j].as_slice()),
    };
    let cfg = WeightConfig::with_seed(1);
    let p = SampleParams::NOMINAL;
    let per_sample = median_per_item(7, 200, |id| {
        std::hint::black_box(magnitude_weights(&cfg, &p, id, &s).expect("equal lengths"));
    });
    println!(
        "weights: {:.1} us per sample ({n} points, 38 noised signals)",
        per_sample * 1e6
    );
}
