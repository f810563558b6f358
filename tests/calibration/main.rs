//! Calibrated answers end to end: the real `train`, `calibrate`, `evaluate` and `predict`
//! binaries on a small synthetic vehicle-track dataset with a calibration split
//! (`learn_fixtures::synthetic`), driven through the stage protocol's `--context FILE`.
//!
//! Checked: the calibration file (one per model, scores sorted, the levels its samples
//! support), its determinism, the coverage tables of `evaluate`, the intervals and
//! three-valued verdicts of `predict` (inside their interval, an extrapolated design never
//! `pass`), and every refusal (another model's calibration, a corrupt file, a level outside
//! (0, 1) or above n / (n + 1)): exit 2, the file or value named, nothing written. A dataset
//! without calibration samples gives answers without intervals and says why.

use pino_calibration::{Calibration, Normaliser};
use pino_mbd_tests::{output_text as text, run_bin as run, stage_context};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A hand-written stage context (not in check mode): [`stage_context`].
fn context(
    dir: &Path,
    name: &str,
    params: serde_json::Value,
    inputs: serde_json::Value,
) -> (PathBuf, PathBuf) {
    stage_context(dir, name, params, inputs, false)
}

/// Calibration samples of the synthetic dataset: 12 support levels up to 12/13 = 0.923.
const N_CALIBRATION: u64 = 12;

fn stage(binary: &str, ctx: &Path) {
    let o = run(binary, &["--context", ctx.to_str().unwrap()]);
    assert!(o.status.success(), "{binary}: {}", text(&o));
}

fn dataset(dir: &Path, n_calibration: u64) -> PathBuf {
    let data = dir.join(format!("data-{n_calibration}"));
    std::fs::create_dir_all(&data).unwrap();
    let spec = learn_fixtures::synthetic::SyntheticSpec {
        n_train: 4,
        n_validation: 3,
        n_test: 4,
        n_calibration,
        // The vehicle-track indices read from 0.2 s (`indices_from`): 0.1 s of them.
        duration: 0.3,
        ..Default::default()
    };
    learn_fixtures::synthetic::write_dataset(&spec, &data).unwrap();
    data
}

fn train(dir: &Path, name: &str, data: &Path, alg: i64, seed: u64) -> PathBuf {
    let params = serde_json::json!({"algorithm": alg, "width": 8, "modes": 6, "projection_width": 16,
        "padding": 0, "epochs": 2, "batch_size": 2, "learning_rate": 1e-3, "lr_decay": 0.75,
        "lr_decay_every": 10, "lambda_ode": 0.25, "lambda_d": 1.0, "beam_weight": 0.0,
        "rho": 0.025, "seed": seed, "startup_fraction": 0.1, "time_stride": 1});
    let inputs = serde_json::json!({"params": [data], "dataset": [data], "weights": [data]});
    let (ctx, out) = context(dir, name, params, inputs);
    stage("train", &ctx);
    out
}

fn calibrate(dir: &Path, name: &str, data: &Path, models: &[PathBuf]) -> PathBuf {
    let (ctx, out) = context(
        dir,
        name,
        serde_json::json!({"normaliser": "error_head", "head_inputs": ["residual"], "ridge": 1.0,
                           "batch_size": 4}),
        serde_json::json!({"params": [data], "dataset": [data], "models": models}),
    );
    stage("calibrate", &ctx);
    out
}

/// `predict` on `model` with `args`; the output files are named after `tag`.
fn predict(dir: &Path, model: &Path, tag: &str, args: &[&str]) -> (Output, PathBuf, PathBuf) {
    let (ix, out) = (
        dir.join(format!("{tag}-indices.parquet")),
        dir.join(format!("{tag}-out.parquet")),
    );
    let mut all = vec![
        "--model",
        model.to_str().unwrap(),
        "--seed",
        "3",
        "--indices",
        ix.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    (run("predict", &all), ix, out)
}

#[test]
fn calibrated_answers_end_to_end_and_every_refusal() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let data = dataset(dir, N_CALIBRATION);
    let model = train(dir, "train5", &data, 5, 1);
    let other = train(dir, "train5b", &data, 5, 2);
    let cal_dir = calibrate(dir, "calibrate", &data, std::slice::from_ref(&model));

    // One calibration per model, keyed by algorithm; the scores of every quantity sorted.
    let file = cal_dir.join("algorithm-5").join("calibration.json");
    let cal: Calibration = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(
        (cal.n, cal.n_fit, cal.normaliser),
        (N_CALIBRATION as usize, 3, Normaliser::ErrorHead)
    );
    assert!(cal.has_intervals());
    let system = learn_fixtures::synthetic::vehicle_track_system();
    let layout = pino_learn::layout::Layout::of(&system);
    let indices = pino_outputs::indices_eval::IndexInputs::of(&system, &layout).unwrap();
    let names: Vec<&str> = cal.indices.iter().map(|q| q.name.as_str()).collect();
    let expected: Vec<&str> = indices.columns().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, expected);
    assert_eq!(cal.channels.len(), layout.n_outputs() + 2 * layout.n_dofs());
    for q in cal
        .indices
        .iter()
        .chain(cal.channels.iter().map(|c| &c.quantity))
    {
        for set in q.scores.values() {
            assert_eq!(set.len(), N_CALIBRATION as usize, "{}", q.name);
            assert!(set.sorted().windows(2).all(|w| w[0] <= w[1]), "{}", q.name);
        }
        // 12 samples support 0.8 and 0.9, not 0.95 (above 12/13).
        assert!(
            q.quantiles.contains_key("0.8") && q.quantiles.contains_key("0.9"),
            "{}",
            q.name
        );
        assert!(!q.quantiles.contains_key("0.95"), "{}", q.name);
    }
    // Same inputs, same bytes.
    let again = calibrate(
        &dir.join("again"),
        "calibrate",
        &data,
        std::slice::from_ref(&model),
    );
    assert_eq!(
        std::fs::read(&file).unwrap(),
        std::fs::read(again.join("algorithm-5").join("calibration.json")).unwrap()
    );

    // evaluate reports the coverage on the test split.
    let (ctx, eval) = context(
        dir,
        "evaluate",
        serde_json::json!({"plot_samples": 1, "plot_channels": ["z_c"], "batch_size": 4,
                           "compare_with_paper": false}),
        serde_json::json!({"params": [data], "dataset": [data], "models": [&model],
                           "calibration": [&cal_dir]}),
    );
    stage("evaluate", &ctx);
    let cov = pino_data::read_parquet(&eval.join("coverage.parquet"), None).unwrap();
    assert!(cov.num_rows() > 0);
    assert!(cov
        .f64("coverage")
        .unwrap()
        .iter()
        .all(|c| (0.0..=1.0).contains(c)));
    assert!(cov.i64("n_test").unwrap().iter().all(|&n| n == 4));
    assert!(
        cov.f64("level")
            .unwrap()
            .iter()
            .all(|&l| l == 0.8 || l == 0.9),
        "0.95 unsupported"
    );
    let md = std::fs::read_to_string(eval.join("coverage.md")).unwrap();
    assert!(
        md.contains("12 calibration samples") && md.contains("`peak_wheel_rail_force_kn`"),
        "{md}"
    );

    // predict: every index inside its interval, bands around every channel.
    let cal_arg = cal_dir.to_str().unwrap();
    let (o, ix, out) = predict(dir, &model, "calibrated", &["--calibration", cal_arg]);
    assert!(o.status.success(), "{}", text(&o));
    let t = pino_data::read_parquet(&ix, None).unwrap();
    for c in indices.columns() {
        let (v, lo, hi) = (
            t.f64(&c.name).unwrap()[0],
            t.f64(&format!("{}_lo", c.name)).unwrap()[0],
            t.f64(&format!("{}_hi", c.name)).unwrap()[0],
        );
        assert!(lo <= v && v <= hi && lo < hi, "{}: {lo} {v} {hi}", c.name);
    }
    assert_eq!(t.f64("coverage").unwrap(), &[0.9]);
    assert_eq!(t.bool("extrapolated").unwrap(), &[false]);
    let verdict = t.opt_str("verdict").unwrap()[0];
    assert!(
        matches!(verdict, Some("pass" | "uncertain" | "fail")),
        "{verdict:?}"
    );
    let h = pino_data::read_parquet(&out, None).unwrap();
    let (z, lo, hi) = (
        h.f64("z_c").unwrap(),
        h.f64("z_c_lo").unwrap(),
        h.f64("z_c_hi").unwrap(),
    );
    assert!(z.iter().zip(lo).zip(hi).all(|((z, l), h)| l < z && z < h));
    assert!(
        h.f64("eta_1_lo").is_err(),
        "excitations are exact inputs: no band"
    );

    // An extrapolated design: flagged, never `pass`.
    let (o, ix, _) = predict(
        dir,
        &model,
        "outside",
        &["--calibration", cal_arg, "--set", "k_s=1.0e5"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let t = pino_data::read_parquet(&ix, None).unwrap();
    assert_eq!(t.bool("extrapolated").unwrap(), &[true]);
    for name in t
        .names()
        .filter(|n| n.ends_with("verdict"))
        .map(str::to_owned)
        .collect::<Vec<_>>()
    {
        assert_ne!(t.opt_str(&name).unwrap()[0], Some("pass"), "{name}");
    }

    // Refusals: exit 2, the cause named, nothing written.
    let corrupt = dir.join("corrupt.json");
    std::fs::write(
        &corrupt,
        "{\"format\": \"pino-mbd calibration 1\", \"model\": ",
    )
    .unwrap();
    let bad_cases: Vec<(&str, Vec<&str>, &str)> = vec![
        (
            "another",
            vec!["--calibration", cal_arg],
            "none of this model",
        ),
        (
            "another-file",
            vec!["--calibration", file.to_str().unwrap()],
            "another model",
        ),
        (
            "level",
            vec!["--calibration", cal_arg, "--coverage", "0.95"],
            "12 calibration samples",
        ),
        (
            "range",
            vec!["--calibration", cal_arg, "--coverage", "1.5"],
            "outside (0, 1)",
        ),
        (
            "corrupt",
            vec!["--calibration", corrupt.to_str().unwrap()],
            "corrupt.json",
        ),
        (
            "missing",
            vec!["--calibration", "/nonexistent/cal"],
            "/nonexistent/cal",
        ),
    ];
    for (tag, args, needle) in bad_cases {
        let m = if tag.starts_with("another") {
            &other
        } else {
            &model
        };
        let (o, ix, out) = predict(dir, m, tag, &args);
        assert_eq!(o.status.code(), Some(2), "{tag}: {}", text(&o));
        assert!(text(&o).contains(needle), "{tag}: {}", text(&o));
        assert!(
            !ix.exists() && !out.exists(),
            "{tag}: something was written"
        );
    }
}

#[test]
fn without_calibration_samples_answers_carry_no_interval_and_say_why() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let data = dataset(dir, 0);
    let model = train(dir, "train5", &data, 5, 1);
    let cal_dir = calibrate(dir, "calibrate", &data, std::slice::from_ref(&model));
    let text_of =
        std::fs::read_to_string(cal_dir.join("algorithm-5").join("calibration.json")).unwrap();
    let cal: Calibration = serde_json::from_str(&text_of).unwrap();
    assert_eq!(cal.n, 0);
    assert!(cal
        .no_intervals
        .as_deref()
        .unwrap()
        .contains("n_calibration = 0"));
    let (o, ix, out) = predict(
        dir,
        &model,
        "plain",
        &["--calibration", cal_dir.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("no intervals") && text(&o).contains("n_calibration = 0"),
        "{}",
        text(&o)
    );
    let t = pino_data::read_parquet(&ix, None).unwrap();
    assert!(t
        .names()
        .all(|n| !n.ends_with("_lo") && !n.ends_with("_hi") && n != "verdict"));
    let h = pino_data::read_parquet(&out, None).unwrap();
    assert!(h
        .names()
        .all(|n| !n.ends_with("_lo") && !n.ends_with("_hi")));
}
