//! End-to-end tests of the data stages `sample-params`, `irregularity` and `weights`, run by
//! hand as the orchestrator would (`--context FILE`), checking their Parquet artifacts.
//!
//! Needs the binaries: `cargo build -p sample-params -p irregularity -p weights`.

use pino_data::{read_parquet, schema, write_parquet, Column, Table};
use pino_mbd_tests::bin;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Writes a context file for `stage` and returns (context path, output dir).
fn context(dir: &Path, stage: &str, params: &str, inputs: &str) -> (PathBuf, PathBuf) {
    let out = dir.join(format!("{stage}-out"));
    std::fs::create_dir_all(&out).unwrap();
    let ctx = dir.join(format!("{stage}.json"));
    let text = format!(
        r#"{{"protocol":1,"stage":"{stage}","params":{params},"inputs":{{{inputs}}},"output":"{}"}}"#,
        out.display()
    );
    std::fs::write(&ctx, text).unwrap();
    (ctx, out)
}

fn run(name: &str, ctx: &Path, threads: usize) -> Output {
    Command::new(bin(name))
        .arg("--context")
        .arg(ctx)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .unwrap()
}

fn ok(name: &str, ctx: &Path, threads: usize) -> String {
    let out = run(name, ctx, threads);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{name} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

fn fails(name: &str, ctx: &Path) -> String {
    let out = run(name, ctx, 1);
    assert!(!out.status.success(), "{name} should have failed");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

const SAMPLING: &str = r#"{"seed": 5, "n_train": 6, "n_validation": 2, "n_test": 2,
    "ranges": {"m_c": {"nominal": 38880, "factor": [0.8, 1.2]}, "v_kmh": [300, 350]}}"#;

#[test]
fn sample_params_and_irregularity_write_their_tables() {
    let dir = tempfile::tempdir().unwrap();
    let (ctx, sp) = context(dir.path(), "sample-params", SAMPLING, "");
    let stdout = ok("sample-params", &ctx, 1);
    assert!(
        stdout.contains("::summary 6 train + 2 validation + 2 test samples"),
        "{stdout}"
    );

    let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
    let mut expected = vec![schema::SAMPLE_ID, schema::SPLIT];
    expected.extend(schema::PARAMETERS);
    assert_eq!(params.names().collect::<Vec<_>>(), expected);
    assert_eq!(
        params.i64(schema::SAMPLE_ID).unwrap(),
        &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]
    );
    let splits = params.str(schema::SPLIT).unwrap();
    assert!(
        splits[..6].iter().all(|s| s == "train")
            && splits[6..8].iter().all(|s| s == "validation")
            && splits[8..].iter().all(|s| s == "test"),
        "{splits:?}"
    );
    assert!(params
        .f64("v_kmh")
        .unwrap()
        .iter()
        .all(|v| (300.0..350.0).contains(v)));
    assert!(params
        .f64("m_c")
        .unwrap()
        .iter()
        .all(|v| (31104.0..46656.0).contains(v)));

    // Same seed, same bytes.
    let first = std::fs::read(sp.join("params.parquet")).unwrap();
    ok("sample-params", &ctx, 1);
    assert_eq!(first, std::fs::read(sp.join("params.parquet")).unwrap());

    let inputs = format!(r#""params": ["{}"]"#, sp.display());
    let ir_params =
        r#"{"seed": 5, "dx": 0.1, "length": 540, "wavelength_min": 2, "wavelength_max": 100}"#;
    let (ctx, ir) = context(dir.path(), "irregularity", ir_params, &inputs);
    let stdout = ok("irregularity", &ctx, 2);
    assert!(
        stdout.contains("10 profiles x 5400 points") && stdout.contains("RMS 0.606 mm"),
        "{stdout}"
    );
    let table = read_parquet(&ir.join("irregularity.parquet"), None).unwrap();
    assert_eq!(
        table.names().collect::<Vec<_>>(),
        [schema::SAMPLE_ID, schema::TRACK_X, schema::TRACK_ETA]
    );
    assert_eq!(table.num_rows(), 10 * 5400);
    let (ids, x, eta) = (
        table.i64("sample_id").unwrap(),
        table.f64("x").unwrap(),
        table.f64("eta").unwrap(),
    );
    for s in 0..10 {
        let rows = s * 5400..(s + 1) * 5400;
        assert!(ids[rows.clone()].iter().all(|&i| i == s as i64));
        assert_eq!(x[rows.start], 0.0);
        assert!((x[rows.end - 1] - 539.9).abs() < 1e-9);
        // Every profile's mean square is the band integral, 0.36670 mm^2 (in m^2); 2e-4
        // relative is the 4-digit precision of the spec's 0.3667.
        let ms = eta[rows].iter().map(|e| e * e).sum::<f64>() / 5400.0;
        assert!((ms / 0.3667e-6 - 1.0).abs() < 2e-4, "sample {s}: {ms}");
    }
    // Thread count does not change the bytes.
    let bytes = std::fs::read(ir.join("irregularity.parquet")).unwrap();
    ok("irregularity", &ctx, 1);
    assert_eq!(
        bytes,
        std::fs::read(ir.join("irregularity.parquet")).unwrap()
    );
}

#[test]
fn bad_input_exits_nonzero_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            r#"{"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1, "ranges": {"m_c": [-100, 5000]}}"#,
            ["`m_c`", "> 0"],
        ),
        (
            r#"{"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1, "ranges": {"k_f": [4.5e7, 3.5e7]}}"#,
            ["`k_f`", "empty or inverted"],
        ),
        (
            r#"{"seed": 1, "n_train": 0, "n_validation": 1, "n_test": 1}"#,
            ["`n_train`", ">= 1"],
        ),
        (
            r#"{"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 0}"#,
            ["`n_test`", ">= 1"],
        ),
        (
            r#"{"seed": 1, "n_train": 4, "n_validation": 1}"#,
            ["missing field `n_test`", "sample-params.json"],
        ),
        (
            r#"{"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1, "ranges": {"mass": [1, 2]}}"#,
            ["unknown parameter `mass`", "m_c"],
        ),
        (
            r#"{"seed": 1, "n_train": 4, "n_validaton": 1}"#,
            ["unknown field `n_validaton`", "sample-params.json"],
        ),
    ];
    for (params, needles) in cases {
        let (ctx, _) = context(dir.path(), "sample-params", params, "");
        let err = fails("sample-params", &ctx);
        for n in needles {
            assert!(err.contains(n), "{params}: `{n}` not in: {err}");
        }
    }
    let (ctx, sp) = context(dir.path(), "sample-params", SAMPLING, "");
    ok("sample-params", &ctx, 1);
    let inputs = format!(r#""params": ["{}"]"#, sp.display());
    let (ctx, _) = context(
        dir.path(),
        "irregularity",
        r#"{"seed": 1, "wavelength_min": 120}"#,
        &inputs,
    );
    let err = fails("irregularity", &ctx);
    assert!(
        err.contains("wavelength_min") && err.contains("< wavelength_max"),
        "{err}"
    );
    let (ctx, _) = context(dir.path(), "irregularity", r#"{"seed": 1}"#, "");
    let err = fails("irregularity", &ctx);
    assert!(err.contains("needs input `params`"), "{err}");
}

/// A synthetic `simulation.parquet` for the given ids: every signal zero except a car-body
/// displacement ramp, with 20 time points per sample.
fn synthetic_dataset(path: &Path, ids: &[i64], drop: Option<&str>) {
    let n = 20;
    let mut t = Table::default();
    for col in schema::simulation_columns() {
        if Some(col.as_str()) == drop {
            continue;
        }
        let c = match col.as_str() {
            "sample_id" => Column::I64(
                ids.iter()
                    .flat_map(|&i| std::iter::repeat_n(i, n))
                    .collect(),
            ),
            "t" => Column::F64(
                ids.iter()
                    .flat_map(|_| (0..n).map(|k| k as f64 * 1e-3))
                    .collect(),
            ),
            "z_c" => Column::F64(
                ids.iter()
                    .flat_map(|&i| (0..n).map(move |k| 1e-4 * (k as f64 + i as f64)))
                    .collect(),
            ),
            _ => Column::F64(vec![0.0; ids.len() * n]),
        };
        t.push(&col, c).unwrap();
    }
    write_parquet(path, &t).unwrap();
    pino_data::provenance::write_provenance(
        &path.with_file_name(pino_data::provenance::PROVENANCE_FILE),
        &[("gravity", 9.81), ("wheel_radius", 0.43)],
    )
    .unwrap();
}

#[test]
fn weights_reads_shards_and_names_missing_columns() {
    let dir = tempfile::tempdir().unwrap();
    let (ctx, sp) = context(dir.path(), "sample-params", SAMPLING, "");
    ok("sample-params", &ctx, 1);
    // Two shards, round robin; sample 4 (train) failed and is absent; 6, 7 are validation and
    // 8 a test sample (present, and skipped like validation: weights cover training only).
    let (a, b) = (dir.path().join("shard0"), dir.path().join("shard1"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    synthetic_dataset(&a.join("simulation.parquet"), &[0, 2, 6], None);
    synthetic_dataset(&b.join("simulation.parquet"), &[1, 3, 5, 7, 8], None);
    let inputs = format!(
        r#""params": ["{}"], "dataset": ["{}", "{}"]"#,
        sp.display(),
        a.display(),
        b.display()
    );
    let (ctx, out) = context(
        dir.path(),
        "weights",
        r#"{"seed": 3, "noise_ratio": 0.02}"#,
        &inputs,
    );
    let stdout = ok("weights", &ctx, 2);
    assert!(
        stdout.contains("phi for 5 training samples")
            && stdout.contains("1 training samples absent"),
        "{stdout}"
    );
    let w = read_parquet(&out.join("weights.parquet"), None).unwrap();
    let mut names = vec![schema::SAMPLE_ID.to_owned()];
    names.extend(schema::phi_columns());
    assert_eq!(w.names().collect::<Vec<_>>(), names);
    assert_eq!(w.i64("sample_id").unwrap(), &[0, 1, 2, 3, 5]);
    // Wheels carry no load (z_w = z_r = eta = 0): R_wheel = -W exactly, so phi_7 = W.
    let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
    let row = |c: &str, i: usize| params.f64(c).unwrap()[i];
    for (k, &id) in w.i64("sample_id").unwrap().iter().enumerate() {
        let i = id as usize;
        let weight = (row("m_c", i) / 2.0 + row("m_t", i) + 2.0 * row("m_w", i)) * 9.81 / 4.0;
        assert!((w.f64("phi_7").unwrap()[k] / weight - 1.0).abs() < 1e-12);
        assert!(w.f64("phi_1").unwrap()[k] > 0.0 && w.f64("phi_2").unwrap()[k] == 0.0);
    }
    // Shard layout does not matter: one file with all samples gives the same bytes.
    let bytes = std::fs::read(out.join("weights.parquet")).unwrap();
    let c = dir.path().join("single");
    std::fs::create_dir_all(&c).unwrap();
    synthetic_dataset(
        &c.join("simulation.parquet"),
        &[0, 1, 2, 3, 5, 6, 7, 8],
        None,
    );
    let inputs1 = format!(
        r#""params": ["{}"], "dataset": ["{}"]"#,
        sp.display(),
        c.display()
    );
    // The same unit (`weights`, written into every file's metadata) in another directory.
    let (ctx1, out1) = context(
        &dir.path().join("single-run"),
        "weights",
        r#"{"seed": 3, "noise_ratio": 0.02}"#,
        &inputs1,
    );
    ok("weights", &ctx1, 1);
    assert_eq!(bytes, std::fs::read(out1.join("weights.parquet")).unwrap());

    // A missing column is named with its file.
    synthetic_dataset(
        &b.join("simulation.parquet"),
        &[1, 3, 5, 7, 8],
        Some("beta_t1_a"),
    );
    let err = fails("weights", &ctx);
    assert!(
        err.contains("missing column `beta_t1_a`") && err.contains("shard1"),
        "{err}"
    );
    // A dataset simulated with other constants is refused, naming both values and the file.
    let (ctx2, _) = context(
        dir.path(),
        "weights2",
        r#"{"seed": 3, "gravity": 9.8}"#,
        &inputs1,
    );
    let err = fails("weights", &ctx2);
    assert!(
        err.contains("gravity = 9.81")
            && err.contains("gravity = 9.8;")
            && err.contains("provenance.parquet"),
        "{err}"
    );
    // Noise ratio out of range.
    let (ctx, _) = context(
        dir.path(),
        "weights",
        r#"{"seed": 3, "noise_ratio": 1.5}"#,
        &inputs,
    );
    let err = fails("weights", &ctx);
    assert!(
        err.contains("`noise_ratio` = 1.5") && err.contains("(0, 1]"),
        "{err}"
    );
}

#[test]
fn pipeline_files_hold_valid_data_stage_parameters() {
    // The `params:` blocks of both pipeline files go through YAML -> JSON (as the orchestrator
    // passes them) into the stages' checked types, and hold the spec's values.
    for (file, n_train, n_validation, n_test) in [
        ("pipeline.yaml", 800, 100, 100),
        ("configs/paper.yaml", 20000, 2000, 2000),
        ("configs/long.yaml", 4800, 200, 200),
    ] {
        let params = |stage: &str| pino_mbd_tests::stage_params(file, stage);
        let sampling: vtcd::sampling::SamplingParams =
            serde_json::from_value(params("sample-params")).unwrap();
        let plan = sampling.validate().unwrap();
        assert_eq!(
            (plan.n_train(), plan.n_validation(), plan.n_test()),
            (n_train, n_validation, n_test),
            "{file}"
        );
        let defaults = vtcd::sampling::SamplingParams {
            ranges: Default::default(),
            ..sampling.clone()
        };
        assert_eq!(
            plan.ranges(),
            defaults.validate().unwrap().ranges(),
            "{file}: ranges differ from the spec"
        );
        assert_eq!(sampling.ranges.len(), 14, "{file}: every range written out");

        let irr: vtcd::irregularity::IrregularityParams =
            serde_json::from_value(params("irregularity")).unwrap();
        assert_eq!(irr.psd, vtcd::irregularity::TBT3352_VERTICAL, "{file}");
        let generator = irr.validate().unwrap();
        assert!((generator.variance() * 1e6 - 0.3667).abs() < 5e-5, "{file}");

        let w: vtcd::weights::WeightParams = serde_json::from_value(params("weights")).unwrap();
        w.validate().unwrap();
        let ix: pino_indices::IndexParams = serde_json::from_value(params("indices")).unwrap();
        let ix = ix.validate().unwrap();
        assert_eq!(ix.gravity, 9.81, "{file}");
        assert_eq!(
            ix.sperling,
            pino_indices::SperlingParams::default(),
            "{file}"
        );
        assert_eq!(ix.limits, pino_indices::Limits::default(), "{file}");
        assert_eq!(
            (w.noise_ratio, w.gravity, w.wheel_radius),
            (0.02, 9.81, 0.43),
            "{file}"
        );
    }
}

#[test]
fn weights_of_a_simulated_dataset_vanish_without_noise() {
    // The chain sample-params -> irregularity -> simulate -> weights on a short run. With
    // r = 1e-12 phi is the clean residual max_t |R_i| of the stored solution, which the
    // simulator makes consistent to round-off: below 1e-6 of the wheel load W (about 70 kN;
    // observed ~1e-10 W). With r = 2% every phi is far above that.
    let dir = tempfile::tempdir().unwrap();
    let sampling = r#"{"seed": 2, "n_train": 2, "n_validation": 1, "n_test": 1}"#;
    let (ctx, sp) = context(dir.path(), "sample-params", sampling, "");
    ok("sample-params", &ctx, 1);
    let inputs = format!(r#""params": ["{}"]"#, sp.display());
    let (ctx, ir) = context(dir.path(), "irregularity", r#"{"seed": 2}"#, &inputs);
    ok("irregularity", &ctx, 2);
    let inputs = format!(
        r#""params": ["{}"], "irregularity": ["{}"]"#,
        sp.display(),
        ir.display()
    );
    let (ctx, sim) = context(dir.path(), "simulate", r#"{"duration": 0.05}"#, &inputs);
    ok("simulate", &ctx, 2);
    let inputs = format!(
        r#""params": ["{}"], "dataset": ["{}"]"#,
        sp.display(),
        sim.display()
    );
    let mut phi = Vec::new();
    for (stage, r) in [("weights-clean", 1e-12), ("weights-noised", 0.02)] {
        let (ctx, out) = context(
            dir.path(),
            stage,
            &format!(r#"{{"seed": 2, "noise_ratio": {r}}}"#),
            &inputs,
        );
        ok("weights", &ctx, 2);
        let w = read_parquet(&out.join("weights.parquet"), None).unwrap();
        assert_eq!(w.i64("sample_id").unwrap(), &[0, 1]);
        let cols: Vec<Vec<f64>> = schema::phi_columns()
            .iter()
            .map(|c| w.f64(c).unwrap().to_vec())
            .collect();
        phi.push(cols);
    }
    let load = 7e4;
    for (i, (clean, noised)) in phi[0].iter().zip(&phi[1]).enumerate() {
        for (c, n) in clean.iter().zip(noised) {
            assert!(*c < 1e-6 * load, "phi_{} clean {c}", i + 1);
            assert!(
                *n > 1e3 * c.max(1e-9),
                "phi_{} noised {n} vs clean {c}",
                i + 1
            );
        }
    }
}
