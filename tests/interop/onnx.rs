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

/// Trains a width-8 model of `algorithm` (with `rate_outputs`) into `dir/train-out`.
fn train(dir: &Path, data: &Path, file: &str, rates: &[&str], algorithm: i64) -> PathBuf {
    let mut params = serde_json::json!({"algorithm": algorithm, "width": 8, "modes": 6,
        "projection_width": 16, "padding": 25, "epochs": 2, "batch_size": 2,
        "learning_rate": 1e-3, "lr_decay": 0.75, "lr_decay_every": 10, "lambda_ode": 0.25,
        "lambda_d": 0.25, "beam_weight": 0.0, "rho": 0.025, "seed": 1, "startup_fraction": 0.0,
        "time_stride": 1});
    if !rates.is_empty() {
        params["rate_outputs"] = serde_json::json!(rates);
    }
    let inputs = serde_json::json!({"params": [data], "dataset": [data], "weights": [data]});
    std::fs::create_dir_all(dir).unwrap();
    let (ctx, out) = stage_context(dir, "train", params, inputs, false);
    // The description is named only for the rate outputs (checked against it).
    let description = (!rates.is_empty()).then(|| system_path(file));
    stage("train", description.as_deref(), &ctx);
    out
}

/// Calibrates `models` in one run with `normaliser` and error heads on `heads`; the
/// calibration directory.
fn calibrate(
    dir: &Path,
    data: &Path,
    models: &[&Path],
    (normaliser, heads): (&str, &str),
) -> PathBuf {
    let (ctx, cal) = stage_context(
        dir,
        "calibrate",
        serde_json::json!({"normaliser": normaliser, "head_inputs": [heads], "ridge": 1.0,
                           "batch_size": 4}),
        serde_json::json!({"params": [data], "dataset": [data], "models": models}),
        false,
    );
    stage("calibrate", None, &ctx);
    cal
}

/// Trains a width-8 model of algorithm 5 (with `rate_outputs`) and calibrates it with
/// `normaliser` and error heads on `heads`: (model directory, calibration directory).
fn model(
    dir: &Path,
    data: &Path,
    file: &str,
    rates: &[&str],
    normaliser: (&str, &str),
) -> (PathBuf, PathBuf) {
    let out = train(dir, data, file, rates, 5);
    let cal = calibrate(dir, data, &[&out], normaliser);
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

/// `predict` of the designs under the profile by `source` (`--model DIR [--calibration
/// CAL]` or `--surrogate DIR`), at `level` (none: without intervals), into
/// `histories[-level].parquet` and `indices[-level].parquet`.
fn predict(out: &Path, source: &[&str], designs: &Path, profile: &Path, level: Option<f64>) {
    let tag = level.map_or(String::new(), |l| format!("-{l}"));
    let (h, ix) = (
        out.join(format!("histories{tag}.parquet")),
        out.join(format!("indices{tag}.parquet")),
    );
    let mut args: Vec<String> = source.iter().map(|s| (*s).to_owned()).collect();
    for (flag, path) in [
        ("--params", designs),
        ("--profile", profile),
        ("--out", &h),
        ("--indices", &ix),
    ] {
        args.extend([flag.to_owned(), path.display().to_string()]);
    }
    if let Some(level) = level {
        args.extend(["--coverage".into(), level.to_string()]);
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = run_bin("predict", &refs);
    assert!(o.status.success(), "predict: {}", output_text(&o));
}

fn export(args: &[&str]) -> std::process::Output {
    run_bin("export", args)
}

/// Runs the checker with `flags` (`--intervals`, `--routes FILE`); returns its report.
fn check(
    python: &str,
    onnx: &Path,
    csv: &Path,
    designs: &Path,
    out: &Path,
    flags: &[&str],
) -> String {
    let script = workspace_root().join("tests/interop/check_onnx.py");
    let mut cmd = Command::new(python);
    cmd.arg(&script).arg(onnx).arg(csv).arg(designs).arg(out);
    if !flags.contains(&"--intervals") {
        cmd.arg("--no-intervals");
    }
    cmd.args(flags.iter().filter(|f| **f != "--intervals"));
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
    let (m, c) = (model_dir.to_str().unwrap(), cal.to_str().unwrap());
    for &l in &levels {
        predict(
            &out,
            &["--model", m, "--calibration", c],
            &designs,
            &parquet,
            Some(l),
        );
    }
    let report = check(python, &onnx, &csv, &designs, &out, &["--intervals"]);
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
    let m = model_dir.to_str().unwrap();
    predict(
        &out,
        &["--model", m],
        &designs,
        &dir.join("profile.parquet"),
        None,
    );
    println!("{}", check(&python, &bare, &csv, &designs, &out, &[]));

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

/// Sets each validation error of `model`'s calibration in `cal` so that it wins the indices
/// and channels at even positions (`even`) or odd ones: a surrogate of two such candidates
/// has both as members.
fn make_win(cal: &Path, model: &Path, even: bool) {
    use pino_calibration::{Calibration, ModelIdentity};
    let identity = ModelIdentity::of(model).unwrap();
    let file = Calibration::find(cal, &identity).unwrap();
    let mut c = Calibration::load(&file, &identity).unwrap();
    let quantities = c
        .indices
        .iter_mut()
        .enumerate()
        .chain(c.channels.iter_mut().map(|b| &mut b.quantity).enumerate());
    for (k, q) in quantities {
        let v = q
            .validation
            .as_mut()
            .expect("calibrate records validation errors");
        v.mean_relative_pct = Some(if (k % 2 == 0) == even { 1.0 } else { 2.0 });
    }
    c.write(file.parent().unwrap()).unwrap();
}

/// A column of a Parquet file.
fn column(file: &Path, name: &str) -> Vec<f64> {
    let t = pino_data::read_parquet(file, None).unwrap();
    t.f64(name)
        .unwrap_or_else(|e| panic!("{}: {name}: {e}", file.display()))
        .to_vec()
}

/// The bits of each value (NaN equal to itself).
fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Whether `a` and `b` differ by more than 1e-3 of their scale somewhere.
fn differ(a: &[f64], b: &[f64]) -> bool {
    let scale = a.iter().chain(b).fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-3 * scale)
}

/// A surrogate of two members (two small models of one dataset, calibrated in one run, each
/// made to win half of the indices and channels by its recorded validation errors, built by
/// `pino_surrogate::build`) exported by `export --surrogate`: in ONNX Runtime every
/// channel, band, index, interval, verdict and range flag equals the surrogate's own answers
/// (`predict --surrogate`, which answers through `Surrogate::answers` and
/// `Surrogate::histories`), and the file's metadata routes every quantity to the member the
/// manifest does. Each route is checked for power: the surrogate's answer is its member's own
/// (`predict --model`), and on some quantity of each member the other member answers
/// otherwise, by far more than the comparison's tolerance.
#[test]
fn a_surrogate_of_two_members_answers_as_it_does_in_onnx_runtime() {
    let python = super::python_with("numpy, pyarrow, onnxruntime");
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let data = dataset(dir, "vtcd", 0.3);
    let models = [
        train(&dir.join("a"), &data, "vtcd", &[], 5),
        train(&dir.join("b"), &data, "vtcd", &[], 1),
    ];
    let cal = calibrate(dir, &data, &[&models[0], &models[1]], ("none", "residual"));
    make_win(&cal, &models[0], true);
    make_win(&cal, &models[1], false);
    let sur = dir.join("surrogate");
    let manifest = pino_surrogate::build::build(&models, &cal, &sur).unwrap();
    assert_eq!(manifest.members.len(), 2, "{:?}", manifest.members);
    let onnx = dir.join("surrogate.onnx");
    let o = export(&[
        "--surrogate",
        sur.to_str().unwrap(),
        "--out",
        onnx.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "export: {}", output_text(&o));

    let designs = designs(dir, &data);
    let (parquet, csv) = profile(dir);
    let out = dir.join("predicted");
    std::fs::create_dir_all(&out).unwrap();
    let s = sur.to_str().unwrap();
    for level in [0.8, 0.9] {
        predict(&out, &["--surrogate", s], &designs, &parquet, Some(level));
    }
    let routes = serde_json::json!({
        "indices": manifest.indices.iter().map(|r| (r.name.clone(), r.member.clone().into()))
            .collect::<serde_json::Map<_, _>>(),
        "channels": manifest.channels.iter().map(|r| (r.name.clone(), r.member.clone().into()))
            .collect::<serde_json::Map<_, _>>(),
    });
    let routes_file = dir.join("routes.json");
    std::fs::write(&routes_file, routes.to_string()).unwrap();
    let r = routes_file.to_str().unwrap();
    let report = check(
        &python,
        &onnx,
        &csv,
        &designs,
        &out,
        &["--intervals", "--routes", r],
    );
    println!("surrogate: {report}");

    // Each member alone, at one level.
    let c = cal.to_str().unwrap();
    let own: Vec<PathBuf> = models
        .iter()
        .zip(["a", "b"])
        .map(|(m, tag)| {
            let at = dir.join(format!("member-{tag}"));
            std::fs::create_dir_all(&at).unwrap();
            let m = m.to_str().unwrap();
            predict(
                &at,
                &["--model", m, "--calibration", c],
                &designs,
                &parquet,
                Some(0.9),
            );
            at
        })
        .collect();
    let member_of = |route: &str| -> usize {
        let m = manifest.members.iter().find(|m| m.name == route).unwrap();
        let hash = |d: &Path| pino_calibration::ModelIdentity::of(d).unwrap().blake3;
        models
            .iter()
            .position(|d| hash(d) == m.model.blake3)
            .unwrap()
    };
    let mut powered = [0usize; 2];
    for (kind, file, routes, suffixes) in [
        (
            "index",
            "indices-0.9.parquet",
            &manifest.indices,
            &["", "_lo", "_hi"][..],
        ),
        (
            "channel",
            "histories-0.9.parquet",
            &manifest.channels,
            &["", "_lo", "_hi"][..],
        ),
    ] {
        for route in routes {
            let m = member_of(&route.member);
            for suffix in suffixes {
                let col = format!("{}{suffix}", route.name);
                let mine = column(&out.join(file), &col);
                let theirs = column(&own[m].join(file), &col);
                assert_eq!(bits(&mine), bits(&theirs), "{kind} {col}");
            }
            let other = column(&own[1 - m].join(file), &route.name);
            if differ(&column(&out.join(file), &route.name), &other) {
                powered[m] += 1;
            }
        }
    }
    assert!(
        powered.iter().all(|&n| n > 0),
        "routes that tell the members apart: {powered:?}"
    );
}
