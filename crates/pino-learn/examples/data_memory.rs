//! Benchmark: peak memory of the data path of `train` and `evaluate` against dataset size.
//!
//! ```text
//! cargo run --release -p pino-learn --example data_memory -- gen DIR N_TRAIN N_VAL N_TEST DURATION_S
//! /usr/bin/time -v target/release/examples/data_memory train DIR
//! /usr/bin/time -v target/release/examples/data_memory evaluate DIR
//! /usr/bin/time -v target/release/examples/data_memory model DIR [EPOCHS]
//! ```
//! `gen` writes a synthetic dataset (1 kHz, one row group per sample) into `DIR`. `train` does
//! what the `train` stage does with the data: the indexing and statistics pass, the prepared
//! f32 store of the training and validation splits, and one epoch of batches of 4 (without a
//! model, whose memory does not depend on the dataset size). `evaluate` reads the test split
//! alone and builds its batches of 8. `model` is the `train` stage's library path whole
//! (`train::train`: dataset, store, model, optimizer, losses, validation) at the paper's
//! sizes (`configs/paper.yaml`: width 72, 320 modes, 25 % padding, batches of 20, algorithm 5,
//! the deepest) for `EPOCHS` epochs (default 1). Each prints the samples held, the bytes of the store and
//! the process's peak resident set (VmHWM).
use candle_core::Device;
use learn_fixtures::synthetic::{write_dataset, SyntheticSpec};
use pino_learn::config::{TrainParams, WindowConfig};
use pino_learn::data::{load_dataset, load_split, make_batch, prepare, DatasetInfo, Split};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // As the `train` and `evaluate` stages do.
    pino_learn::tune_allocator();
    let a: Vec<String> = std::env::args().skip(1).collect();
    let mode = a.first().map(String::as_str).unwrap_or("");
    let dir = PathBuf::from(
        a.get(1)
            .ok_or("usage: data_memory gen|train|evaluate DIR ...")?,
    );
    let params = dir.join(pino_data::artifacts::PARAMS_FILE);
    let sims = vec![dir.join(pino_data::artifacts::SIMULATION_FILE)];
    // The laptop and paper configurations start from equilibrium: no start-up dropped.
    let window = WindowConfig {
        startup_fraction: 0.0,
        time_stride: 1,
    };
    let info = || -> Result<DatasetInfo, Box<dyn std::error::Error>> {
        Ok(DatasetInfo::from_dirs(std::slice::from_ref(&dir))?)
    };
    let dev = Device::Cpu;
    let t0 = Instant::now();
    match mode {
        "gen" => {
            let n = |i: usize| -> Result<usize, Box<dyn std::error::Error>> {
                Ok(a.get(i).ok_or("missing count")?.parse()?)
            };
            std::fs::create_dir_all(&dir)?;
            let duration = a.get(5).map_or(Ok(2.0), |d| d.parse())?;
            let spec = SyntheticSpec {
                n_train: n(2)? as u64,
                n_validation: n(3)? as u64,
                n_test: n(4)? as u64,
                duration,
                system: SyntheticSpec::vehicle_track_for(duration),
                ..Default::default()
            };
            write_dataset(&spec, Path::new(&dir))?;
        }
        "train" => {
            let ds = load_dataset(&info()?, &params, &sims, None, &window)?;
            let norm = ds.normalisation()?;
            let items = prepare(&ds, &norm)?;
            let idx = ds.split_indices(Split::Train);
            let mut checksum = 0.0f64;
            for chunk in idx.chunks(4) {
                let b = make_batch(&items, chunk, ds.t_points(), &dev)?;
                checksum += b.u.sum_all()?.to_scalar::<f32>()? as f64;
            }
            println!(
                "train: {} samples held ({} train) x {} points, store {:.1} MB, {:.1} s, peak RSS {:.1} MB (checksum {checksum:.3})",
                items.len(),
                idx.len(),
                ds.t_points(),
                items.heap_bytes() as f64 / 1e6,
                t0.elapsed().as_secs_f64(),
                peak_rss_mb()
            );
        }
        "evaluate" => {
            // A model's statistics come from its file; the statistics pass stands in here
            // (it holds no time series).
            let norm = load_dataset(&info()?, &params, &sims, None, &window)?.normalisation()?;
            let before = peak_rss_mb();
            let t1 = Instant::now();
            let (ds, items) = load_split(&info()?, &params, &sims, &window, Split::Test, &norm)?;
            let idx: Vec<usize> = (0..items.len()).collect();
            let mut checksum = 0.0f64;
            for chunk in idx.chunks(8) {
                let b = make_batch(&items, chunk, ds.t_points(), &dev)?;
                checksum += b.x.sum_all()?.to_scalar::<f32>()? as f64;
            }
            println!(
                "evaluate: {} test samples x {} points, store {:.1} MB, {:.1} s, peak RSS {:.1} MB (after the statistics pass {:.1} MB) (checksum {checksum:.3})",
                items.len(),
                ds.t_points(),
                items.heap_bytes() as f64 / 1e6,
                t1.elapsed().as_secs_f64(),
                peak_rss_mb(),
                before
            );
        }
        "model" => {
            let ds = load_dataset(&info()?, &params, &sims, None, &window)?;
            let mut p = TrainParams::small(5);
            (p.width, p.modes, p.projection_width, p.padding) = (72, 320, 72, 25);
            (p.batch_size, p.startup_fraction) = (20, 0.0);
            p.epochs = a.get(2).map_or(Ok(1), |e| e.parse())?;
            let (model_cfg, cfg, window) = p.configs(&ds.layout)?;
            let n_train = ds.split_indices(Split::Train).len();
            // A fresh start every time (a checkpoint left by an earlier run would resume).
            let _ = std::fs::remove_dir_all(dir.join("checkpoint"));
            std::fs::create_dir_all(dir.join("checkpoint"))?;
            let opts = pino_learn::train::TrainOptions {
                transform: pino_learn::spectral::Transform::Fused,
                checkpoint_dir: dir.join("checkpoint"),
                stop_after_epochs: None,
            };
            let outcome =
                pino_learn::train::train(&ds, model_cfg, cfg, window, &opts, &dev, &mut |_| {})?;
            println!(
                "model: {} samples ({n_train} train) x {} points, {} parameters, {:.1} s, loss {:.4}, peak RSS {:.1} MB",
                ds.samples.len(),
                ds.t_points(),
                outcome.model.num_parameters(),
                t0.elapsed().as_secs_f64(),
                outcome.history.last().map_or(f64::NAN, |h| h.loss_total),
                peak_rss_mb()
            );
        }
        other => {
            return Err(format!("unknown mode `{other}`: gen, train, evaluate or model").into())
        }
    }
    Ok(())
}
