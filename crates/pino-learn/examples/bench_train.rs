//! Benchmark: training step time and samples per second, inference time.
//!
//! ```text
//! cargo run --release -p pino-learn --example bench_train -- \
//!     [width] [modes] [depth] [batch] [points] [fused|matmul] [steps] [algorithm] [padding%] \
//!     [inference samples] [inference batch]
//! ```
//! Builds a synthetic dataset of `points` time points per record (after the 10% start-up
//! window), runs `steps` optimizer steps of `algorithm` (default 4) and reports
//! the median step time, samples per second, and the forward time for 40 samples.
//!
//! `PINO_BENCH_DEVICE=cuda` runs on the first CUDA GPU (a build with `--features
//! pino-learn/cuda`); the transform is then always the matrix DFT (the fused kernels are CPU
//! code), and every phase ends with a device synchronisation so that its time is the GPU's
//! work, not the launch.
use learn_fixtures::synthetic::{write_dataset, SyntheticSpec};
use pino_learn::config::{DeviceKind, ModelConfig, TrainParams};
use pino_learn::data::{make_batch, prepare};
use pino_learn::loss::LossContext;
use pino_learn::model::Fno;
use pino_learn::optim::Adam;
use pino_learn::spectral::Transform;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    pino_learn::tune_allocator();
    let a: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: &str| a.get(i).cloned().unwrap_or_else(|| d.to_owned());
    let width: usize = arg(0, "32").parse()?;
    let modes: usize = arg(1, "32").parse()?;
    let depth: usize = arg(2, "3").parse()?;
    let batch: usize = arg(3, "8").parse()?;
    let points: usize = arg(4, "1800").parse()?;
    let device_kind = match std::env::var("PINO_BENCH_DEVICE").as_deref() {
        Err(_) | Ok("cpu") => DeviceKind::Cpu,
        Ok("cuda") => DeviceKind::Cuda,
        Ok(other) => return Err(format!("PINO_BENCH_DEVICE `{other}`: allowed cpu, cuda").into()),
    };
    let dev = device_kind.device()?;
    let transform = match arg(5, "fused").as_str() {
        _ if !dev.is_cpu() => Transform::Matmul,
        "matmul" => Transform::Matmul,
        "fused" => Transform::Fused,
        other => return Err(format!("transform `{other}`: allowed fused, matmul").into()),
    };
    let steps: usize = arg(6, "10").parse()?;
    let dir = std::env::temp_dir().join(format!("pino-bench-{points}"));
    std::fs::create_dir_all(&dir)?;
    let duration = points as f64 / 0.9 * 1e-3;
    let spec = SyntheticSpec {
        n_train: batch.max(8) as u64,
        n_validation: 40,
        duration,
        system: SyntheticSpec::vehicle_track_for(duration),
        ..Default::default()
    };
    let files = write_dataset(&spec, &dir)?;
    let algorithm: i64 = arg(7, "4").parse()?;
    // The learning settings of `pipeline.yaml`'s laptop default, resized by the arguments.
    let mut p = TrainParams::small(algorithm);
    (p.width, p.modes, p.depth, p.projection_width) = (width, modes, Some(depth), 64);
    let ds = files.load(
        &pino_learn::config::WindowConfig {
            startup_fraction: 0.1,
            time_stride: 1,
        },
        true,
    )?;
    let (model_cfg, train, _) = p.configs(&ds.layout)?;
    let cfg = ModelConfig {
        width,
        modes,
        depth,
        padding_percent: arg(8, "0").parse()?,
        ..model_cfg
    };
    let model = Fno::new(cfg, ds.t_points(), 1, transform, &dev)?;
    let norm = ds.normalisation()?;
    let loss = LossContext::new(
        train,
        norm.clone(),
        ds.dt,
        ds.force_scale(),
        ds.layout.clone(),
        ds.system().clone(),
    );
    let items = prepare(&ds, &norm)?;
    let idx: Vec<usize> = (0..batch).collect();
    let b = make_batch(&items, &idx, ds.t_points(), &dev)?;
    let mut adam = Adam::new(model.vars())?;
    let mut times = Vec::new();
    let mut phases = [Vec::new(), Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..steps {
        dev.synchronize()?;
        let t0 = Instant::now();
        let u = model.forward(&b.x)?;
        dev.synchronize()?;
        let t1 = Instant::now();
        let (total, _) = loss.loss(&u, &b)?;
        dev.synchronize()?;
        let t2 = Instant::now();
        let g = total.backward()?;
        dev.synchronize()?;
        let t3 = Instant::now();
        adam.step(model.vars(), &g, 1e-4)?;
        dev.synchronize()?;
        let t4 = Instant::now();
        times.push((t4 - t0).as_secs_f64());
        for (k, d) in [t1 - t0, t2 - t1, t3 - t2, t4 - t3].into_iter().enumerate() {
            phases[k].push(d.as_secs_f64());
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let med = median(&mut times);
    let [f, l, bw, a] = phases.each_mut().map(median);
    println!(
        "phases (median ms): forward {:.2}, loss {:.2}, backward {:.2}, adam {:.2}",
        f * 1e3,
        l * 1e3,
        bw * 1e3,
        a * 1e3
    );
    // Inference as `evaluate` runs it (`infer::predict_samples`: batches side by side).
    // The 40 validation records are cycled up to the requested count (same cost per sample).
    let n_infer: usize = arg(9, "40").parse()?;
    let infer_batch: usize = arg(10, "8").parse()?;
    let val: Vec<usize> = (0..n_infer)
        .map(|k| spec.n_train as usize + k % 40)
        .collect();
    let mut inf = Vec::new();
    for _ in 0..3 {
        let (_, wall) = pino_learn::infer::predict_samples(
            &model,
            &items,
            &val,
            ds.t_points(),
            infer_batch,
            &dev,
        )?;
        inf.push(wall);
    }
    inf.sort_by(f64::total_cmp);
    println!(
        "{device_kind:?} width {width} modes {modes} depth {depth} batch {batch} T {} {transform:?}: params {}, step median {:.4} s, {:.1} samples/s, inference {n_infer} samples {:.3} s",
        ds.t_points(),
        model.num_parameters(),
        med,
        batch as f64 / med,
        inf[1]
    );
    Ok(())
}
