//! Benchmark: the `indices` stage's engine (`compute_all`) on synthetic paper-scale shards.
//!
//! ```text
//! cargo run --release -p indices-scan --example bench_indices -- DIR generate SAMPLES_PER_SHARD SHARDS ROWS
//! cargo run --release -p indices-scan --example bench_indices -- DIR run SHARDS
//! ```
//! `generate` writes `params.parquet` and `SHARDS` files `sim_K.parquet` of
//! `SAMPLES_PER_SHARD` samples x `ROWS` rows (5000: the paper's 5 s at 1 kHz), one row group per
//! sample as `simulate` writes them, with the 16 columns the indices read (`sample_id`, `t`,
//! `p_1..4`, `z_c_a`, `beta_c_a`, `z_t1_a`, `z_t2_a`, `z_r1..4`; the stage projects onto
//! those, so the other 42 columns of a real shard are never decoded). `run` computes the
//! indices of the first `SHARDS` shards and prints the wall time of each pass, the cost per
//! sample and the peak resident memory (VmHWM). The system is the vehicle-track description
//! (`systems/vtcd.yaml`) at its nominal values.
use indices_scan::{aggregate, check_columns, read_params, record_pass};
use mbd_system::system::ParamSource;
use mbd_system::{System, SystemSource};
use pino_data::{schema, Column, StreamWriter, Table};
use pino_indices::IndexSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn system() -> System {
    SystemSource {
        file: "systems/vtcd.yaml".into(),
        text: include_str!("../../../systems/vtcd.yaml").into(),
        values: Default::default(),
    }
    .compile()
    .expect("the repository's vtcd.yaml compiles")
}

fn columns() -> &'static [String] {
    static COLUMNS: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
    COLUMNS.get_or_init(|| indices_scan::needed_columns(&IndexSet::of(&system())))
}

fn sample_table(id: i64, rows: usize) -> Table {
    let dt = 1e-3;
    let s = id as f64;
    let w = |k: usize, f: f64, a: f64| {
        a * (2.0 * std::f64::consts::PI * f * k as f64 * dt + 0.1 * s).sin()
    };
    let mut t = Table::default();
    t.push(schema::SAMPLE_ID, Column::I64(vec![id; rows]))
        .unwrap();
    t.push(
        schema::TIME,
        Column::F64((0..rows).map(|k| k as f64 * dt).collect()),
    )
    .unwrap();
    for (i, c) in columns()[2..].iter().enumerate() {
        let base = if c.starts_with("p_") { 70e3 } else { 0.0 };
        let amp = if c.starts_with("p_") {
            8e3
        } else if c.starts_with("z_r") {
            2e-4
        } else {
            0.3
        };
        t.push(
            c,
            Column::F64(
                (0..rows)
                    .map(|k| base + w(k, 1.0 + 3.0 * i as f64, amp) + 0.01 * amp * w(k, 37.0, 1.0))
                    .collect(),
            ),
        )
        .unwrap();
    }
    t
}

fn peak_rss_mb() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn generate(
    dir: &Path,
    per: usize,
    shards: usize,
    rows: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    let n = per * shards;
    let system = system();
    let units = pino_data::system::units_of(&system)?;
    let mut p = Table::default().with_units(units.clone());
    p.push(schema::SAMPLE_ID, Column::I64((0..n as i64).collect()))?;
    p.push(schema::SPLIT, Column::Str(vec!["train".into(); n]))?;
    for i in system.sampled() {
        let par = &system.parameters[i];
        let ParamSource::Sampled { nominal, .. } = par.source else {
            unreachable!("sampled")
        };
        p.push(&par.name, Column::F64(vec![nominal; n]))?;
    }
    pino_data::write_parquet(&dir.join(pino_data::artifacts::PARAMS_FILE), &p)?;
    for k in 0..shards {
        let path = dir.join(format!("sim_{k}.parquet"));
        let mut w = StreamWriter::create(&path, &sample_table(0, 0).with_units(units.clone()))?;
        for id in (k * per)..((k + 1) * per) {
            w.write(&sample_table(id as i64, rows))?;
        }
        w.finish()?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(a.first().ok_or("DIR")?);
    match a.get(1).map(String::as_str) {
        Some("generate") => generate(&dir, a[2].parse()?, a[3].parse()?, a[4].parse()?),
        Some("run") => {
            let shards: usize = a[2].parse()?;
            let files: Vec<PathBuf> = (0..shards)
                .map(|k| dir.join(format!("sim_{k}.parquet")))
                .collect();
            let cfg = pino_indices::IndexParams::default().validate()?;
            let system = system();
            let set = IndexSet::of(&system);
            let railway = set
                .railway
                .as_ref()
                .ok_or("vtcd.yaml binds the railway indices")?;
            let params = read_params(&system, &[dir.join(pino_data::artifacts::PARAMS_FILE)])?;
            let t0 = Instant::now();
            check_columns(&files, &indices_scan::needed_columns(&set))?;
            let spectral = record_pass(&files, &system, &set, &params, &cfg, &|_| {})?;
            let t1 = Instant::now();
            let windows: Vec<(i64, f64)> =
                spectral.iter().map(|(id, s)| (*id, s.t_start)).collect();
            let aggs = aggregate(&files, railway, &windows, &|_| PathBuf::new())?;
            let t2 = Instant::now();
            let n = aggs.len();
            let (a1, a2) = ((t1 - t0).as_secs_f64(), (t2 - t1).as_secs_f64());
            println!(
                "{n} samples x {} rows: record pass {a1:.1} s, polars aggregation {a2:.1} s, total {:.1} s = {:.2} ms/sample; peak RSS {:.0} MB",
                spectral.values().next().map_or(0, |s| s.n),
                a1 + a2,
                1e3 * (a1 + a2) / n as f64,
                peak_rss_mb()
            );
            Ok(())
        }
        _ => Err("usage: DIR generate PER SHARDS ROWS | DIR run SHARDS".into()),
    }
}
