//! The ONNX export in ONNX Runtime: on each shipped system (the vehicle track on a short
//! track, the quarter car, the bridge with a rate output), a small model is trained and
//! calibrated by the real stage binaries on a synthetic dataset (`learn_fixtures`), exported
//! by the real `export` binary, and run in ONNX Runtime by `tests/interop/check_onnx.py`: for
//! the dataset's test split and one design outside the training box, under a profile file,
//! every channel, index, interval bound at every level the file carries, verdict and range
//! flag equals `predict`'s, and the excitation the recipe of `examples/onnx` builds from the
//! profile equals `predict`'s. `examples/onnx/run.py` runs on the vehicle-track file. Refusals
//! (an unwritable path, an unknown index, a level the calibration cannot support, a
//! normaliser the graph cannot compute) exit 2 and leave no file; a model without a
//! calibration exports without intervals and says so.
//!
//! Needs Python 3 with numpy, pyarrow and onnxruntime (tests/interop/requirements.txt, which
//! `scripts/test` installs): without them this test fails, it never skips.

use pino_data::{Column, Table};
use pino_mbd_tests::{output_text, run_bin, run_stage, stage_context, system_path, workspace_root};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A small dataset of `system` (a shipped description) with a calibration split.
fn dataset(dir: &Path, file: &str, duration: f64) -> PathBuf {
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let system = if file == "vtcd" {
        learn_fixtures::synthetic::SyntheticSpec::vehicle_track_for(duration)
    } else {
        mbd_system::SystemSource::read(&system_path(file), Default::default()).unwrap()
    };
    let spec = learn_fixtures::synthetic::SyntheticSpec {
        n_train: 4,
        n_validation: 3,
        n_test: 3,
        n_calibration: 12,
        duration,
        system,
        ..Default::default()
    };
    learn_fixtures::synthetic::write_dataset(&spec, &data).unwrap();
    data
}

fn stage(exe: &str, description: Option<&Path>, ctx: &Path) {
    let o = run_stage(exe, description, ctx, 2);
    assert!(o.status.success(), "{exe}: {}", output_text(&o));
}

/// Trains a width-8 model of algorithm 5 (with `rate_outputs`) and calibrates it with
/// `normaliser` and error heads on `heads`: (model directory, calibration directory).
fn model(
    dir: &Path,
    data: &Path,
    file: &str,
    rates: &[&str],
    (normaliser, heads): (&str, &str),
) -> (PathBuf, PathBuf) {
    let mut params = serde_json::json!({"algorithm": 5, "width": 8, "modes": 6,
        "projection_width": 16, "padding": 25, "epochs": 2, "batch_size": 2,
        "learning_rate": 1e-3, "lr_decay": 0.75, "lr_decay_every": 10, "lambda_ode": 0.25,
        "lambda_d": 0.25, "beam_weight": 0.0, "rho": 0.025, "seed": 1, "startup_fraction": 0.0,
        "time_stride": 1});
    if !rates.is_empty() {
        params["rate_outputs"] = serde_json::json!(rates);
    }
    let inputs = serde_json::json!({"params": [data], "dataset": [data], "weights": [data]});
    let (ctx, out) = stage_context(dir, "train", params, inputs, false);
    // The description is named only for the rate outputs (checked against it).
    let description = (!rates.is_empty()).then(|| system_path(file));
    stage("train", description.as_deref(), &ctx);
    let (ctx, cal) = stage_context(
        dir,
        "calibrate",
        serde_json::json!({"normaliser": normaliser, "head_inputs": [heads], "ridge": 1.0,
                           "batch_size": 4}),
        serde_json::json!({"params": [data], "dataset": [data], "models": [&out]}),
        false,
    );
    stage("calibrate", None, &ctx);
    (out, cal)
}

/// The test split's designs and one outside the training box (its first parameter 30 % above
/// its range), as JSON (which `predict --params` reads as YAML).
fn designs(dir: &Path, data: &Path) -> PathBuf {
    let t = pino_data::read_parquet(&data.join("params.parquet"), None).unwrap();
    let split = t.str("split").unwrap().to_vec();
    let (_, system) = pino_data::system::read_record(&[data.to_owned()]).unwrap();
    let names = system.sampled_names();
    let ranges = system.ranges();
    let columns: Vec<Vec<f64>> = names.iter().map(|n| t.f64(n).unwrap().to_vec()).collect();
    let mut sets: Vec<serde_json::Map<String, serde_json::Value>> = (0..split.len())
        .filter(|&r| split[r] == "test")
        .map(|r| {
            names
                .iter()
                .zip(&columns)
                .map(|(n, c)| ((*n).to_owned(), c[r].into()))
                .collect()
        })
        .collect();
    let mut outside = sets[0].clone();
    outside.insert(names[0].to_owned(), (ranges[0][1] * 1.3).into());
    sets.push(outside);
    let path = dir.join("designs.json");
    std::fs::write(&path, serde_json::to_string(&sets).unwrap()).unwrap();
    path
}

/// A profile from 0 to 600 m every 0.1 m (a few mm of waviness and a dip), as Parquet for
/// `predict --profile` and as CSV for the recipe.
fn profile(dir: &Path) -> (PathBuf, PathBuf) {
    let x: Vec<f64> = (0..6000).map(|k| k as f64 * 0.1).collect();
    let eta: Vec<f64> = x
        .iter()
        .map(|x| {
            1.5e-3 * (x / 7.3).sin() + 0.7e-3 * (x / 2.1 + 0.4).sin() + 0.3e-3 * (x / 0.9).cos()
                - 1e-3 * (-(x - 40.0).powi(2) / 4.0).exp()
        })
        .collect();
    let mut t = Table::default();
    t.push("x", Column::F64(x.clone())).unwrap();
    t.push("eta", Column::F64(eta.clone())).unwrap();
    let parquet = dir.join("profile.parquet");
    pino_data::write_parquet(&parquet, &t).unwrap();
    let mut csv = String::from("x,eta\n");
    for (a, b) in x.iter().zip(&eta) {
        csv.push_str(&format!("{a:?},{b:?}\n"));
    }
    let path = dir.join("profile.csv");
    std::fs::write(&path, csv).unwrap();
    (parquet, path)
}

/// `predict` of the designs under the profile, with the calibration at `level` (none: without)
/// into `histories[-level].parquet` and `indices[-level].parquet`.
fn predict(out: &Path, model: &Path, designs: &Path, profile: &Path, cal: Option<(&Path, f64)>) {
    let tag = cal.map_or(String::new(), |(_, l)| format!("-{l}"));
    let (h, ix) = (
        out.join(format!("histories{tag}.parquet")),
        out.join(format!("indices{tag}.parquet")),
    );
    let mut args = vec![
        "--model".to_owned(),
        model.display().to_string(),
        "--params".into(),
        designs.display().to_string(),
        "--profile".into(),
        profile.display().to_string(),
        "--out".into(),
        h.display().to_string(),
        "--indices".into(),
        ix.display().to_string(),
    ];
    if let Some((c, level)) = cal {
        args.extend(["--calibration".into(), c.display().to_string()]);
        args.extend(["--coverage".into(), level.to_string()]);
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run_bin("predict", &refs);
    assert!(o.status.success(), "predict: {}", output_text(&o));
}

fn export(args: &[&str]) -> std::process::Output {
    run_bin("export", args)
}

/// Runs the checker; returns its report.
fn check(
    python: &str,
    onnx: &Path,
    csv: &Path,
    designs: &Path,
    out: &Path,
    intervals: bool,
) -> String {
    let script = workspace_root().join("tests/interop/check_onnx.py");
    let mut cmd = Command::new(python);
    cmd.arg(&script).arg(onnx).arg(csv).arg(designs).arg(out);
    if !intervals {
        cmd.arg("--no-intervals");
    }
    let o = cmd.output().unwrap();
    let report = output_text(&o);
    assert!(o.status.success(), "{}", report);
    report
}

/// Trains, calibrates, exports and checks one system; returns the exported file and the
/// profile CSV.
fn system_round_trip(
    python: &str,
    dir: &Path,
    file: &str,
    duration: f64,
    rates: &[&str],
    normaliser: (&str, &str),
) -> (PathBuf, PathBuf, PathBuf, PathBuf) {
    let data = dataset(dir, file, duration);
    let (model_dir, cal) = model(dir, &data, file, rates, normaliser);
    let designs = designs(dir, &data);
    let (parquet, csv) = profile(dir);
    let onnx = dir.join("model.onnx");
    let o = export(&[
        "--model",
        model_dir.to_str().unwrap(),
        "--calibration",
        cal.to_str().unwrap(),
        "--out",
        onnx.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "export: {}", output_text(&o));
    let levels: Vec<f64> = vec![0.8, 0.9];
    let out = dir.join("predicted");
    std::fs::create_dir_all(&out).unwrap();
    for &l in &levels {
        predict(&out, &model_dir, &designs, &parquet, Some((&cal, l)));
    }
    let report = check(python, &onnx, &csv, &designs, &out, true);
    println!("{file}: {report}");
    (onnx, csv, model_dir, designs)
}

#[test]
fn the_exported_graph_answers_as_predict_does_in_onnx_runtime() {
    let python = super::python_with("numpy, pyarrow, onnxruntime");
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    // The intervals under `none` and under error heads on the parameters: the normalisers a
    // graph computes, so `predict` (which answers with the calibration's) must agree.
    for (file, duration, rates, normaliser) in [
        ("quarter-car", 0.5, &[][..], ("error_head", "parameters")),
        ("bridge", 0.4, &["z_mid_a"][..], ("none", "residual")),
    ] {
        let dir = root.join(file);
        std::fs::create_dir_all(&dir).unwrap();
        system_round_trip(&python, &dir, file, duration, rates, normaliser);
    }
    let dir = root.join("vtcd");
    std::fs::create_dir_all(&dir).unwrap();
    let (onnx, csv, model_dir, designs) =
        system_round_trip(&python, &dir, "vtcd", 0.3, &[], ("none", "residual"));

    // Without a calibration: no intervals, and the file says why.
    let bare = dir.join("bare.onnx");
    let o = export(&[
        "--model",
        model_dir.to_str().unwrap(),
        "--out",
        bare.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", output_text(&o));
    assert!(
        output_text(&o).contains("no intervals"),
        "{}",
        output_text(&o)
    );
    let out = dir.join("bare");
    std::fs::create_dir_all(&out).unwrap();
    predict(
        &out,
        &model_dir,
        &designs,
        &dir.join("profile.parquet"),
        None,
    );
    println!("{}", check(&python, &bare, &csv, &designs, &out, false));

    // The example: numpy and ONNX Runtime alone.
    let example = workspace_root().join("examples/onnx/run.py");
    let o = Command::new(&python)
        .arg(&example)
        .arg(&onnx)
        .arg(&csv)
        .output()
        .unwrap();
    let text = output_text(&o);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("peak_wheel_rail_force_kn") && text.contains("extrapolated"),
        "{text}"
    );
    assert_eq!(text.matches("90% [").count(), 3 * 14, "{text}");
    println!("{text}");

    // Refusals: exit 2, the culprit named, no file.
    let cal = dir.join("calibrate-out");
    let m = model_dir.to_str().unwrap();
    let c = cal.to_str().unwrap();
    let target = dir.join("refused.onnx");
    let t = target.to_str().unwrap();
    for (args, needle) in [
        (
            vec![
                "--model",
                m,
                "--calibration",
                c,
                "--out",
                "/nonexistent/dir/m.onnx",
            ],
            "/nonexistent/dir/m.onnx",
        ),
        (
            vec![
                "--model",
                m,
                "--calibration",
                c,
                "--out",
                t,
                "--indices",
                "peak_wheel_rail_force_kn,comfort",
            ],
            "`comfort`",
        ),
        (
            vec![
                "--model",
                m,
                "--calibration",
                c,
                "--out",
                t,
                "--levels",
                "0.95",
            ],
            "level 0.95",
        ),
        (
            vec![
                "--model",
                m,
                "--calibration",
                c,
                "--out",
                t,
                "--normaliser",
                "residual",
            ],
            "normaliser `residual`",
        ),
        (
            vec![
                "--model",
                m,
                "--calibration",
                c,
                "--out",
                t,
                "--normaliser",
                "error_head",
            ],
            "normaliser `error_head`",
        ),
        (
            vec![
                "--model",
                m,
                "--calibration",
                c,
                "--out",
                t,
                "--spectral",
                "fft",
            ],
            "spectral form `fft`",
        ),
        (
            vec!["--model", "/nonexistent/model", "--out", t],
            "/nonexistent/model",
        ),
    ] {
        let o = export(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", output_text(&o));
        assert!(
            output_text(&o).contains(needle),
            "{args:?}: {}",
            output_text(&o)
        );
        assert!(!target.exists() && !Path::new("/nonexistent/dir").exists());
    }
}
