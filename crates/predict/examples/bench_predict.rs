//! Benchmark: the engineering indices of many designs through the surrogate (`predict
//! --indices`), at the default model size.
//!
//! ```text
//! cargo run --release -p pino-predict --example bench_predict -- [designs] [batch] [model_dir] [calibration]
//! ```
//! Without `model_dir`, builds an untrained model of the laptop default size (width 32, 128
//! modes, projection 64, depth 3, 25 % padding) on a synthetic 2-s record at 1 kHz (2000
//! points, as `pipeline.yaml`); the cost of a forward pass does not depend on the weights.
//! Draws `designs` (default 10 000) random parameter sets inside the training ranges, and
//! reports the wall time of `Predictor::indices` (forward passes, central differences and
//! the indices), designs per second, and the solver's time for the same designs from its
//! measured cost (BENCHMARKS.md: 0.09 s of one core per simulated second). With a
//! `calibration` (the `calibrate` stage's output for `model_dir`), also the time of the same
//! designs with their intervals and verdicts at 0.9 (`Predictor::answers`), the two alternated
//! three times, medians reported.
use candle_core::Device;
use learn_fixtures::synthetic::{write_dataset, SyntheticSpec};
use pino_learn::checkpoint::save_model;
use pino_learn::config::{TrainParams, WindowConfig};
use pino_learn::model::Fno;
use pino_learn::spectral::Transform;
use pino_learn::train::model_meta;
use pino_predict::{parse_sweep, Predictor, ProfileChoice, ProfileSource};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    pino_learn::candle_single_threaded_by_default();
    pino_learn::tune_allocator();
    let a: Vec<String> = std::env::args().skip(1).collect();
    let designs: usize = a.first().map_or(Ok(10_000), |s| s.parse())?;
    let batch: usize = a.get(1).map_or(Ok(16), |s| s.parse())?;
    let dev = Device::Cpu;
    let model_dir = match a.get(2) {
        Some(d) => PathBuf::from(d),
        None => {
            let dir = std::env::temp_dir().join("pino-bench-predict");
            std::fs::create_dir_all(&dir)?;
            let spec = SyntheticSpec {
                n_train: 4,
                n_validation: 1,
                duration: 2.0,
                system: SyntheticSpec::vehicle_track_for(2.0),
                ..Default::default()
            };
            let files = write_dataset(&spec, &dir)?;
            let mut p = TrainParams::small(4);
            (p.width, p.modes, p.projection_width, p.padding) = (32, 128, 64, 25);
            let w = WindowConfig {
                startup_fraction: 0.0,
                time_stride: 1,
            };
            let ds = files.load(&w, false)?;
            let (cfg, t, _) = p.configs(&ds.layout)?;
            let model = Fno::new(cfg, ds.t_points(), 1, Transform::Fused, &dev)?;
            let meta = model_meta(&ds, cfg, t, w)?;
            save_model(&dir, &model, &meta)?;
            dir
        }
    };
    let mut predictor = Predictor::load(&model_dir, &dev)?;
    let calibrated = match a.get(3) {
        Some(path) => {
            predictor.load_calibration(std::path::Path::new(path))?;
            true
        }
        None => false,
    };
    let meta = &predictor.meta;
    let ranges = meta.training_ranges.clone();
    let mut yaml = format!("random:\n  seed: 7\n  count: {designs}\n  ranges:\n");
    for (k, name) in ranges.names.iter().enumerate() {
        yaml.push_str(&format!(
            "    {name}: [{}, {}]\n",
            ranges.min[k], ranges.max[k]
        ));
    }
    let sets = parse_sweep(&predictor.space, &yaml, std::path::Path::new("bench"))?;
    let profiles = predictor.profiles(Some(&ProfileChoice::Generated { seed: 1, id: 0 }))?;
    let run = predictor.run_config(None)?;
    let cfg = predictor.index_config()?;
    let t0 = Instant::now();
    let ix = predictor.indices(&sets, &profiles, &run, &cfg, batch)?;
    let wall = t0.elapsed().as_secs_f64();
    let simulated = meta.grid.t_points as f64 * meta.grid.dt;
    let peak = predictor
        .index_inputs()
        .columns()
        .iter()
        .position(|c| c.name == "peak_wheel_rail_force_kn")
        .ok_or("the vehicle-track indices name the peak force")?;
    let worst = ix
        .iter()
        .map(|i| i.values[peak])
        .fold(f64::NEG_INFINITY, f64::max);
    println!(
        "{designs} designs x {simulated:.3} s ({} points, width {}, modes {}, depth {}, batch {batch}, {} rayon threads): {wall:.2} s = {:.0} designs/s (max peak force {worst:.1} kN)",
        meta.grid.t_points,
        meta.model.width,
        meta.model.modes,
        meta.model.depth,
        rayon::current_num_threads(),
        designs as f64 / wall
    );
    if calibrated {
        let (mut plain, mut with) = (Vec::new(), Vec::new());
        for _ in 0..3 {
            let t0 = Instant::now();
            predictor.indices(&sets, &profiles, &run, &cfg, batch)?;
            plain.push(t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            predictor.answers(
                &sets,
                &ProfileSource::Shared(&profiles),
                &run,
                &cfg,
                batch,
                0.9,
            )?;
            with.push(t0.elapsed().as_secs_f64());
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (p, w) = (median(&mut plain), median(&mut with));
        println!(
            "with intervals (alternated x3, medians): {p:.3} s -> {w:.3} s, +{:.1} % ({:.2} ms per design)",
            100.0 * (w / p - 1.0),
            1e3 * (w - p) / designs as f64
        );
    }
    let solver_core_s = 0.09 * simulated * designs as f64;
    println!(
        "solver for the same designs (0.09 core-s per simulated s, BENCHMARKS.md): {solver_core_s:.0} core-s = {:.0} s on 2 cores",
        solver_core_s / 2.0
    );
    Ok(())
}
