//! End-to-end tests of the `simulate` stage binary on the vehicle-track description: schema
//! and row order, the stored columns against the hand-written vehicle equations
//! (`mbd_test_models::vehicle_track`, an independent reference), determinism across thread counts and shard layouts, the start
//! modes, and refusal of bad input. The inputs come from the real `sample-params` and
//! `irregularity` stages; a reduced track (150 fasteners, 90 m, through `system_values`) and
//! 0.2 s runs keep them fast in the dev profile; the stage's logic does not depend on sizes.
//!
//! Needs the binaries: `cargo build -p sample-params -p irregularity -p simulate`.

use mbd_test_models::vehicle_track::{HalfVehicle, CONTACTS, DOFS, NUM_DOFS};
use pino_data::{read_parquet, read_parquet_files, schema, write_parquet, Column};
use pino_mbd_tests::{output_text, run_stage, stage_context, system, system_path};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

const N_SAMPLES: i64 = 6;

/// The reduced track of every run here (a description override, as `--set` gives it).
fn track() -> Value {
    json!({"n_f": 150, "n_m": 75})
}

/// `params` and `irregularity` artifacts of six training samples under `dir`.
fn inputs(dir: &Path) -> (PathBuf, PathBuf) {
    let vtcd = system_path("vtcd");
    let sizes = json!({"seed": 3, "n_train": N_SAMPLES - 2, "n_validation": 1, "n_test": 1,
                       "system_values": track()});
    let (ctx, sp) = stage_context(dir, "sp", sizes, json!({}), false);
    let o = run_stage("sample-params", Some(&vtcd), &ctx, 1);
    assert!(o.status.success(), "{}", output_text(&o));
    let controls = json!({"seed": 3, "dx": 0.1, "length": 120.0, "system_values": track()});
    let (ctx, ir) = stage_context(dir, "ir", controls, json!({"params": [&sp]}), false);
    let o = run_stage("irregularity", Some(&vtcd), &ctx, 2);
    assert!(o.status.success(), "{}", output_text(&o));
    (sp, ir)
}

/// The run controls of these tests with `changes` applied.
fn run_controls(changes: Value) -> Value {
    let mut p = json!({"duration": 0.2, "dt": 1e-4, "output_every": 10, "start": "equilibrium",
                       "startup_zero_fraction": 0.0, "startup_ramp_fraction": 0.0, "x0": 5.0,
                       "system_values": track()});
    for (k, v) in changes.as_object().expect("a map of changes") {
        p[k] = v.clone();
    }
    p
}

/// Runs shard `shard` of the stage with `params`; returns (success, stdout + stderr, output).
fn simulate(
    dir: &Path,
    inputs: &(PathBuf, PathBuf),
    params: Value,
    shard: (usize, usize),
    threads: usize,
    tag: &str,
) -> (bool, String, PathBuf) {
    let (ctx, out) = stage_context(
        dir,
        tag,
        params,
        json!({"params": [&inputs.0], "irregularity": [&inputs.1]}),
        false,
    );
    let mut context: Value = serde_json::from_slice(&std::fs::read(&ctx).unwrap()).unwrap();
    context["stage"] = json!("simulate");
    context["shard"] = json!({"index": shard.0, "count": shard.1});
    std::fs::write(&ctx, context.to_string()).unwrap();
    let o = run_stage("simulate", Some(&system_path("vtcd")), &ctx, threads);
    (o.status.success(), output_text(&o), out)
}

/// The hand-written half vehicle of sample `id`, its parameters read by their public names.
fn vehicle_of(params: &pino_data::Table, id: i64) -> HalfVehicle {
    let row = params
        .i64(schema::SAMPLE_ID)
        .unwrap()
        .iter()
        .position(|&i| i == id)
        .unwrap();
    HalfVehicle::new(|name| params.f64(name).unwrap()[row], 9.81)
}

#[test]
fn output_has_the_schema_sorted_rows_and_consistent_physics() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = inputs(dir.path());
    let (ok, log, out) = simulate(dir.path(), &inputs, run_controls(json!({})), (0, 1), 2, "a");
    assert!(ok, "{log}");
    assert!(log.contains("::summary 6 ok, 0 failed, 1200 rows"), "{log}");
    assert!(log.contains("::progress 6 6"), "{log}");
    let t = read_parquet(&out.join("simulation.parquet"), None).unwrap();
    let names: Vec<String> = t.names().map(str::to_owned).collect();
    let (_, described) = system("vtcd", &[]);
    let expected: Vec<String> = [schema::SAMPLE_ID, schema::TIME]
        .into_iter()
        .map(str::to_owned)
        .chain(described.channels.iter().map(|c| c.name.clone()))
        .collect();
    assert_eq!(names, expected);
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
    // The ten vehicle equations of the hand-written reference on the stored columns (read by
    // their public names) are round-off: < 1e-6 of each equation's force scale.
    let params = read_parquet(&inputs.0.join("params.parquet"), None).unwrap();
    let f = |name: &str| t.f64(name).unwrap();
    let vz: Vec<&[f64]> = DOFS.iter().map(|n| f(n)).collect();
    let vv: Vec<&[f64]> = DOFS.iter().map(|n| f(&format!("{n}_v"))).collect();
    let va: Vec<&[f64]> = DOFS.iter().map(|n| f(&format!("{n}_a"))).collect();
    let vp: Vec<&[f64]> = CONTACTS.iter().map(|n| f(n)).collect();
    for sample in 0..N_SAMPLES {
        let veh = vehicle_of(&params, sample);
        let rows: Vec<usize> = (0..ids.len()).filter(|&r| ids[r] == sample).collect();
        let (mut res, mut scale) = ([0.0f64; NUM_DOFS], [0.0f64; NUM_DOFS]);
        for &r in &rows {
            let z = std::array::from_fn(|i| vz[i][r]);
            let v = std::array::from_fn(|i| vv[i][r]);
            let a = std::array::from_fn(|i| va[i][r]);
            let pr = std::array::from_fn(|i| vp[i][r]);
            let rr = veh.residuals(&z, &v, &a, &pr);
            let ff = veh.forces(&z, &v, &pr);
            for i in 0..NUM_DOFS {
                res[i] = res[i].max(rr[i].abs());
                scale[i] = scale[i].max(ff[i].abs());
            }
        }
        for i in 0..NUM_DOFS {
            assert!(
                res[i] <= 1e-6 * scale[i],
                "sample {sample} {}: {} vs {}",
                DOFS[i],
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
    let inputs = inputs(dir.path());
    let p = || run_controls(json!({}));
    let (ok1, log1, one) = simulate(dir.path(), &inputs, p(), (0, 1), 1, "t1");
    let (ok2, log2, two) = simulate(dir.path(), &inputs, p(), (0, 1), 2, "t2");
    assert!(ok1 && ok2, "{log1}{log2}");
    for file in ["simulation.parquet", "failures.parquet"] {
        let a = std::fs::read(one.join(file)).unwrap();
        let b = std::fs::read(two.join(file)).unwrap();
        assert!(a == b, "{file} differs between 1 and 2 threads");
    }
    let mut shard_files = Vec::new();
    for k in 0..4 {
        let (ok, log, out) = simulate(dir.path(), &inputs, p(), (k, 4), 2, &format!("s{k}"));
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
    let inputs = inputs(dir.path());
    let cases = [
        (json!({"n_ff": 150}), "unknown field `n_ff`"),
        (json!({"output_every": 0}), "output_every"),
        (json!({"dt": 2e-3}), "stability limit"),
        (
            json!({"system_values": {"n_f": 150, "n_m": 150}}),
            "150 modes need fewer than supports.count = 150 supports",
        ),
        (
            // The sleeper mass is the first support level's (`mass: m_s`, at its line).
            json!({"system_values": {"n_f": 150, "n_m": 75, "m_s": -237.0}}),
            "vtcd.yaml:70:33: at the nominal values, `beams.r.supports.levels[0].mass` = -237",
        ),
        (
            json!({"start": "static"}),
            r#"`start` = "static" is not a start mode; allowed: "equilibrium""#,
        ),
    ];
    for (i, (changes, needle)) in cases.iter().enumerate() {
        let params = run_controls(changes.clone());
        let (ok, log, _) = simulate(dir.path(), &inputs, params, (0, 1), 1, &format!("bad{i}"));
        assert!(
            !ok && log.contains(needle),
            "changes {changes}: expected `{needle}` in: {log}"
        );
    }
    // A sample whose car-body mass was negated by hand: refused before anything runs, naming
    // the sample and the body's mass (`mass: m_c / 2`).
    let file = inputs.0.join("params.parquet");
    let mut params = read_parquet(&file, None).unwrap();
    let ids = params.i64(schema::SAMPLE_ID).unwrap().to_vec();
    let m_c: Vec<f64> = params
        .f64("m_c")
        .unwrap()
        .iter()
        .zip(&ids)
        .map(|(&m, &id)| if id == 2 { -m } else { m })
        .collect();
    let (_, described) = system("vtcd", &[]);
    let units = pino_data::system::units_of(&described).unwrap();
    let mut edited = pino_data::Table::default().with_units(units);
    for (name, col) in params.columns() {
        let col = if name == "m_c" {
            Column::F64(m_c.clone())
        } else {
            col.clone()
        };
        edited.push(name, col).unwrap();
    }
    params = edited;
    write_parquet(&file, &params).unwrap();
    let (ok, log, _) = simulate(
        dir.path(),
        &inputs,
        run_controls(json!({})),
        (0, 1),
        1,
        "neg",
    );
    assert!(
        !ok && log.contains("sample 2: `bodies.c.mass` = -"),
        "{log}"
    );
}

/// `start` reaches the solver: from `rest` every sample's first row is the zero state (the
/// vehicle not yet on the track, contact forces zero); from `equilibrium` (the default) the
/// first row is the static solution, every contact force equal to the wheel load W and the
/// car body lowered by the track deflection and the Hertz compression (about a millimetre).
#[test]
fn start_mode_selects_the_initial_state() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = inputs(dir.path());
    let first_rows = |changes: Value, tag: &str| {
        let (ok, log, out) = simulate(dir.path(), &inputs, run_controls(changes), (0, 1), 2, tag);
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
    // The paper's protocol: from rest, the profiles off for the first 10 % of the run.
    let rest = first_rows(
        json!({"duration": 0.05, "start": "rest", "startup_zero_fraction": 0.1,
               "startup_ramp_fraction": 0.1}),
        "rest",
    );
    assert!(rest.0.iter().chain(&rest.1).all(|&v| v == 0.0), "{rest:?}");
    let eq = first_rows(json!({"duration": 0.05}), "eq");
    let params = read_parquet(&inputs.0.join("params.parquet"), None).unwrap();
    for (id, ((&z_c, &p1), &p4)) in eq.0.iter().zip(&eq.1).zip(&eq.2).enumerate() {
        let w = vehicle_of(&params, id as i64).w;
        assert!(
            (p1 / w - 1.0).abs() < 1e-9 && (p4 / w - 1.0).abs() < 1e-9,
            "{p1} {p4} {w}"
        );
        assert!(z_c > 5e-4 && z_c < 2e-3, "z_c(0) = {z_c}");
    }
}
