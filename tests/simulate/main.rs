//! End-to-end tests of the `simulate` stage binary: schema and row order, dataset
//! consistency through the public column names, determinism across thread counts and shard
//! layouts, and refusal of bad input. A reduced track (150 fasteners, 90 m) and 0.2 s runs
//! keep them fast in the dev profile; the stage's logic does not depend on these sizes.

use pino_data::{read_parquet, read_parquet_files, schema, write_parquet, Column, Table};
use pino_mbd_tests::bin;
use std::path::{Path, PathBuf};
use std::process::Command;
use vtcd::params::SampleParams;
use vtcd::vehicle::Vehicle;

const N_SAMPLES: i64 = 6;

/// Writes `params.parquet` (6 samples around the nominal vehicle) and `irregularity.parquet`
/// (smooth, distinct profiles over 0..90 m) under `dir`.
fn write_inputs(dir: &Path, bad_mass: bool) -> (PathBuf, PathBuf) {
    let (pdir, idir) = (dir.join("params"), dir.join("irr"));
    std::fs::create_dir_all(&pdir).unwrap();
    std::fs::create_dir_all(&idir).unwrap();
    let mut params = Table::default();
    // Ids out of order on purpose: the stage sorts.
    let ids: Vec<i64> = (0..N_SAMPLES).rev().collect();
    params
        .push(schema::SAMPLE_ID, Column::I64(ids.clone()))
        .unwrap();
    params
        .push(
            schema::SPLIT,
            Column::Str(ids.iter().map(|_| "train".to_owned()).collect()),
        )
        .unwrap();
    for (j, name) in schema::PARAMETERS.iter().enumerate() {
        let nominal = SampleParams::NOMINAL.to_array()[j];
        let values = ids
            .iter()
            .map(|&id| {
                let v = nominal * (0.9 + 0.04 * id as f64);
                if bad_mass && j == 0 && id == 2 {
                    -v
                } else {
                    v
                }
            })
            .collect();
        params.push(name, Column::F64(values)).unwrap();
    }
    write_parquet(&pdir.join("params.parquet"), &params).unwrap();
    let (mut sid, mut xs, mut etas) = (Vec::new(), Vec::new(), Vec::new());
    for id in 0..N_SAMPLES {
        for i in 0..=900 {
            let x = i as f64 * 0.1;
            sid.push(id);
            xs.push(x);
            etas.push(4e-4 * (x / (3.0 + id as f64)).sin());
        }
    }
    let mut irr = Table::default();
    irr.push(schema::SAMPLE_ID, Column::I64(sid)).unwrap();
    irr.push(schema::TRACK_X, Column::F64(xs)).unwrap();
    irr.push(schema::TRACK_ETA, Column::F64(etas)).unwrap();
    write_parquet(&idir.join("irregularity.parquet"), &irr).unwrap();
    (pdir, idir)
}

const PARAMS: &str = r#"{"duration": 0.2, "n_f": 150, "n_m": 75, "x0": 5.0}"#;

/// Runs the stage; returns (success, stdout + stderr, output dir).
fn run_stage(
    dir: &Path,
    inputs: &(PathBuf, PathBuf),
    params: &str,
    shard: (usize, usize),
    threads: usize,
    tag: &str,
) -> (bool, String, PathBuf) {
    let out = dir.join(format!("out-{tag}"));
    std::fs::create_dir_all(&out).unwrap();
    let ctx = dir.join(format!("ctx-{tag}.json"));
    let text = format!(
        r#"{{"protocol":1,"stage":"simulate","params":{params},"inputs":{{"params":["{}"],"irregularity":["{}"]}},"output":"{}","shard":{{"index":{},"count":{}}}}}"#,
        inputs.0.display(),
        inputs.1.display(),
        out.display(),
        shard.0,
        shard.1
    );
    std::fs::write(&ctx, text).unwrap();
    let o = Command::new(bin("simulate"))
        .arg("--context")
        .arg(&ctx)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .unwrap();
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.success(), log, out)
}

#[test]
fn output_has_the_schema_sorted_rows_and_consistent_physics() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = write_inputs(dir.path(), false);
    let (ok, log, out) = run_stage(dir.path(), &inputs, PARAMS, (0, 1), 2, "a");
    assert!(ok, "{log}");
    assert!(log.contains("::summary 6 ok, 0 failed, 1200 rows"), "{log}");
    assert!(log.contains("::progress 6 6"), "{log}");
    let t = read_parquet(&out.join("simulation.parquet"), None).unwrap();
    let names: Vec<String> = t.names().map(str::to_owned).collect();
    assert_eq!(names, schema::simulation_columns());
    // 0.2 s at 1 kHz: 200 rows per sample, sorted by sample_id then t.
    let ids = t.i64(schema::SAMPLE_ID).unwrap();
    let times = t.f64(schema::TIME).unwrap();
    assert_eq!(ids.len(), 6 * 200);
    for w in 0..ids.len() - 1 {
        assert!(
            (ids[w], times[w]) < (ids[w + 1], times[w + 1]),
            "row {w} out of order"
        );
    }
    // The ten vehicle residuals on the stored columns (read by their public names) are
    // round-off: < 1e-6 of each equation's force scale.
    let params = read_parquet(&inputs.0.join("params.parquet"), None).unwrap();
    let f = |name: &str| t.f64(name).unwrap();
    let vz: Vec<&[f64]> = schema::VEHICLE_DOFS.iter().map(|n| f(n)).collect();
    let vv: Vec<&[f64]> = schema::VEHICLE_DOFS
        .iter()
        .map(|n| f(&schema::velocity(n)))
        .collect();
    let va: Vec<&[f64]> = schema::VEHICLE_DOFS
        .iter()
        .map(|n| f(&schema::acceleration(n)))
        .collect();
    let vp: Vec<&[f64]> = schema::CONTACT_FORCES.iter().map(|n| f(n)).collect();
    for sample in 0..N_SAMPLES {
        let prow = params
            .i64(schema::SAMPLE_ID)
            .unwrap()
            .iter()
            .position(|&i| i == sample)
            .unwrap();
        let p = SampleParams::from_array(std::array::from_fn(|j| {
            params.f64(schema::PARAMETERS[j]).unwrap()[prow]
        }));
        let veh = Vehicle::new(&p, 9.81);
        let rows: Vec<usize> = (0..ids.len()).filter(|&r| ids[r] == sample).collect();
        let (mut res, mut scale) = ([0.0f64; 10], [0.0f64; 10]);
        for &r in &rows {
            let z = std::array::from_fn(|i| vz[i][r]);
            let v = std::array::from_fn(|i| vv[i][r]);
            let a = std::array::from_fn(|i| va[i][r]);
            let pr = std::array::from_fn(|i| vp[i][r]);
            let rr = veh.residuals(&z, &v, &a, &pr);
            let ff = veh.forces(&z, &v, &pr);
            for i in 0..10 {
                res[i] = res[i].max(rr[i].abs());
                scale[i] = scale[i].max(ff[i].abs());
            }
        }
        for i in 0..10 {
            assert!(
                res[i] <= 1e-6 * scale[i],
                "sample {sample} eq {}: {} vs {}",
                i + 1,
                res[i],
                scale[i]
            );
        }
    }
    let failures = read_parquet(&out.join("failures.parquet"), None).unwrap();
    assert_eq!(failures.num_rows(), 0);
    assert_eq!(
        failures.names().collect::<Vec<_>>(),
        vec!["sample_id", "reason"]
    );
}

#[test]
fn byte_identical_across_threads_and_shards() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = write_inputs(dir.path(), false);
    let (ok1, log1, one) = run_stage(dir.path(), &inputs, PARAMS, (0, 1), 1, "t1");
    let (ok2, log2, two) = run_stage(dir.path(), &inputs, PARAMS, (0, 1), 2, "t2");
    assert!(ok1 && ok2, "{log1}{log2}");
    for file in ["simulation.parquet", "failures.parquet"] {
        let a = std::fs::read(one.join(file)).unwrap();
        let b = std::fs::read(two.join(file)).unwrap();
        assert!(a == b, "{file} differs between 1 and 2 threads");
    }
    let mut shard_files = Vec::new();
    for k in 0..4 {
        let (ok, log, out) = run_stage(dir.path(), &inputs, PARAMS, (k, 4), 2, &format!("s{k}"));
        assert!(ok, "{log}");
        shard_files.push(out.join("simulation.parquet"));
    }
    let whole = read_parquet(&one.join("simulation.parquet"), None).unwrap();
    let union = read_parquet_files(&shard_files, None).unwrap();
    assert_eq!(union.num_rows(), whole.num_rows());
    // Sort the union's rows by (sample_id, t) and compare every column row for row.
    let ids = union.i64(schema::SAMPLE_ID).unwrap();
    let t = union.f64(schema::TIME).unwrap();
    let mut order: Vec<usize> = (0..ids.len()).collect();
    order.sort_by(|&a, &b| (ids[a], t[a]).partial_cmp(&(ids[b], t[b])).unwrap());
    for (name, col) in whole.columns() {
        match (col, union.column(name).unwrap()) {
            (Column::F64(w), Column::F64(u)) => {
                assert!(
                    order
                        .iter()
                        .enumerate()
                        .all(|(r, &o)| w[r].to_bits() == u[o].to_bits()),
                    "{name}"
                );
            }
            (Column::I64(w), Column::I64(u)) => {
                assert!(order.iter().enumerate().all(|(r, &o)| w[r] == u[o]))
            }
            _ => panic!("column {name} changed type"),
        }
    }
}

#[test]
fn bad_input_is_refused_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = write_inputs(dir.path(), false);
    let cases = [
        (r#"{"n_ff": 150}"#, "unknown field `n_ff`"),
        (
            r#"{"output_every": 0, "n_f": 150, "n_m": 75}"#,
            "output_every",
        ),
        (
            r#"{"dt": 2e-3, "duration": 0.2, "n_f": 150, "n_m": 75, "x0": 5.0}"#,
            "stability limit",
        ),
        (r#"{"n_f": 150, "n_m": 150}"#, "n_m"),
        (
            r#"{"duration": 0.2, "n_f": 150, "n_m": 75, "x0": 5.0, "m_s": -237.0}"#,
            "m_s",
        ),
        (
            r#"{"duration": 0.2, "n_f": 150, "n_m": 75, "x0": 5.0, "start": "static"}"#,
            r#"`start` = "static" is not a start mode; allowed: "equilibrium""#,
        ),
    ];
    for (i, (params, needle)) in cases.iter().enumerate() {
        let (ok, log, _) = run_stage(dir.path(), &inputs, params, (0, 1), 1, &format!("bad{i}"));
        assert!(
            !ok && log.contains(needle),
            "params {params}: expected `{needle}` in: {log}"
        );
    }
    let bad = tempfile::tempdir().unwrap();
    let bad_inputs = write_inputs(bad.path(), true);
    let (ok, log, _) = run_stage(bad.path(), &bad_inputs, PARAMS, (0, 1), 1, "neg");
    assert!(
        !ok && log.contains("sample 2") && log.contains("m_c"),
        "{log}"
    );
}

/// The `simulate` blocks of `pipeline.yaml` and `configs/long.yaml` (laptop: 2 s) and
/// `configs/paper.yaml` (5 s) parse
/// into the stage's parameter type, pass validation, and keep the paper's physics (full
/// track, dt = 1e-4, 1 kHz); only the duration and the start-up fractions differ (both start
/// from equilibrium).
#[test]
fn pipeline_files_configure_the_paper_physics() {
    let mut durations = Vec::new();
    for file in ["pipeline.yaml", "configs/paper.yaml", "configs/long.yaml"] {
        let params = pino_mbd_tests::stage_params(file, "simulate");
        let c: vtcd::simulation::SimulationConfig =
            serde_json::from_value(params).unwrap_or_else(|e| panic!("{file}: {e}"));
        c.validate().unwrap();
        let paper = vtcd::simulation::SimulationConfig {
            duration: c.duration,
            startup_zero_fraction: c.startup_zero_fraction,
            startup_ramp_fraction: c.startup_ramp_fraction,
            ..Default::default()
        };
        assert_eq!(
            c, paper,
            "{file}: only the duration and the start-up fractions may differ from the spec"
        );
        assert_eq!(c.start, vtcd::simulation::StartMode::Equilibrium, "{file}");
        durations.push(c.duration);
    }
    assert_eq!(durations, [2.0, 5.0, 2.0]);
}

/// `start` reaches the solver: from `rest` every sample's first row is the zero state (the
/// vehicle not yet on the track, contact forces zero); from `equilibrium` (the default) the
/// first row is the static solution, every contact force equal to the wheel load W and the
/// car body lowered by the track deflection and the Hertz compression (about a millimetre).
#[test]
fn start_mode_selects_the_initial_state() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = write_inputs(dir.path(), false);
    let first_rows = |params: &str, tag: &str| {
        let (ok, log, out) = run_stage(dir.path(), &inputs, params, (0, 1), 2, tag);
        assert!(ok, "{log}");
        let t = read_parquet(&out.join("simulation.parquet"), None).unwrap();
        let times = t.f64(schema::TIME).unwrap();
        let rows: Vec<usize> = (0..times.len()).filter(|&r| times[r] == 0.0).collect();
        assert_eq!(rows.len(), N_SAMPLES as usize);
        let col = |n: &str| {
            rows.iter()
                .map(|&r| t.f64(n).unwrap()[r])
                .collect::<Vec<f64>>()
        };
        (col("z_c"), col("p_1"), col("p_4"))
    };
    let rest = first_rows(
        r#"{"duration": 0.05, "n_f": 150, "n_m": 75, "x0": 5.0, "start": "rest"}"#,
        "rest",
    );
    assert!(rest.0.iter().chain(&rest.1).all(|&v| v == 0.0), "{rest:?}");
    let eq = first_rows(
        r#"{"duration": 0.05, "n_f": 150, "n_m": 75, "x0": 5.0}"#,
        "eq",
    );
    // Samples are nominal x (0.9 + 0.04 id), sorted by id: W from their masses.
    for (k, ((&z_c, &p1), &p4)) in eq.0.iter().zip(&eq.1).zip(&eq.2).enumerate() {
        let f = 0.9 + 0.04 * k as f64;
        let p = SampleParams::from_array(SampleParams::NOMINAL.to_array().map(|v| v * f));
        let w = Vehicle::new(&p, 9.81).w;
        assert!(
            (p1 / w - 1.0).abs() < 1e-9 && (p4 / w - 1.0).abs() < 1e-9,
            "{p1} {p4} {w}"
        );
        assert!(z_c > 5e-4 && z_c < 2e-3, "z_c(0) = {z_c}");
    }
}
