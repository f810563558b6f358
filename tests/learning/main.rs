//! End-to-end: the real `train`, `evaluate` and `predict` binaries on a small synthetic dataset
//! (rigid-rail vehicle records that satisfy the ODEs exactly, `learn_fixtures::synthetic`), driven
//! through the stage protocol's `--context FILE`.
//!
//! Build the binaries first: `cargo build -p train -p evaluate -p predict`.

use pino_mbd_tests::{output_text as text, run_bin as run, stage_context};
use std::path::{Path, PathBuf};

/// A hand-written stage context (not in check mode): [`stage_context`].
fn context(
    dir: &Path,
    name: &str,
    params: serde_json::Value,
    inputs: serde_json::Value,
) -> (PathBuf, PathBuf) {
    stage_context(dir, name, params, inputs, false)
}

/// A synthetic dataset of 4 + 2 + 2 samples of 0.3 s in `dir/data`: its spec and directory.
fn tiny_dataset(dir: &Path) -> (learn_fixtures::synthetic::SyntheticSpec, PathBuf) {
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let spec = learn_fixtures::synthetic::SyntheticSpec {
        n_train: 4,
        n_validation: 2,
        n_test: 2,
        // The vehicle-track indices read from 0.2 s (`indices_from`): 0.1 s of them.
        duration: 0.3,
        ..Default::default()
    };
    learn_fixtures::synthetic::write_dataset(&spec, &data).unwrap();
    (spec, data)
}

#[test]
fn train_evaluate_predict_end_to_end_and_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (spec, data) = tiny_dataset(dir);
    // The same samples without a test split (the validation fallback of `evaluate`).
    let no_test = dir.join("no-test");
    std::fs::create_dir_all(&no_test).unwrap();
    learn_fixtures::synthetic::write_dataset(
        &learn_fixtures::synthetic::SyntheticSpec { n_test: 0, ..spec },
        &no_test,
    )
    .unwrap();
    let inputs = serde_json::json!({"params": [data], "dataset": [data], "weights": [data]});
    // Every training parameter is required (their one home is the pipeline file).
    let small = |alg: i64| {
        serde_json::json!({"algorithm": alg, "width": 8, "modes": 6, "projection_width": 16,
                           "padding": 0, "epochs": 2, "batch_size": 2, "learning_rate": 1e-3,
                           "lr_decay": 0.75, "lr_decay_every": 10, "lambda_ode": 0.25,
                           "lambda_d": 1.0, "beam_weight": 0.0, "rho": 0.025, "seed": 1,
                           "startup_fraction": 0.1, "time_stride": 1})
    };

    // Two algorithms: 3 uses phi and the ODE residual, 5 the derivative loss and depth 5.
    let mut models = Vec::new();
    for alg in [3, 5] {
        let (ctx, out) = context(dir, &format!("train{alg}"), small(alg), inputs.clone());
        let o = run("train", &["--context", ctx.to_str().unwrap()]);
        assert!(o.status.success(), "{}", text(&o));
        let log = text(&o);
        assert!(
            log.contains("::progress 2 2") && log.contains("ETA"),
            "{log}"
        );
        assert!(log.contains("::summary algorithm"), "{log}");
        for f in ["model.safetensors", "model.json", "history.parquet"] {
            assert!(out.join(f).is_file(), "{f} missing");
        }
        assert!(
            !out.join("checkpoint.json").exists(),
            "checkpoints are removed at the end"
        );
        models.push(out);
    }
    // Same inputs, same bytes: a second run of algorithm 3 reproduces every file.
    // The same unit (`train3`, written into every file's metadata) in another directory.
    let (ctx, again) = context(&dir.join("again"), "train3", small(3), inputs.clone());
    let o = run("train", &["--context", ctx.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    for f in ["model.safetensors", "model.json", "history.parquet"] {
        let a = std::fs::read(models[0].join(f)).unwrap();
        assert!(
            a == std::fs::read(again.join(f)).unwrap(),
            "{f} differs between runs"
        );
    }

    let (ctx, out) = context(
        dir,
        "evaluate",
        serde_json::json!({"plot_samples": 1, "plot_channels": ["z_c", "z_w1"], "batch_size": 8,
                            "compare_with_paper": true}),
        serde_json::json!({"params": [data], "dataset": [data], "models": models}),
    );
    let o = run("evaluate", &["--context", ctx.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let t4 = pino_data::read_parquet(&out.join("table4.parquet"), None).unwrap();
    // The truth row (algorithm 0) first: 0 on solutions and forces, a positive floor on
    // derivatives; then the models, scored on the two test samples.
    assert_eq!(t4.i64("algorithm").unwrap(), &[0, 3, 5]);
    assert_eq!(t4.str("split").unwrap(), &["test", "test", "test"]);
    assert_eq!(t4.i64("samples").unwrap(), &[2, 2, 2]);
    let sol = t4.f64("solutions_pct").unwrap();
    assert_eq!(sol[0], 0.0);
    assert_eq!(t4.f64("contact_forces_pct").unwrap()[0], 0.0);
    // The truth row's derivatives are central differences against the exact ones: a small
    // positive floor (measured 0.38 % and 0.29 % on this data).
    let (d1, d2) = (
        t4.f64("first_derivatives_pct").unwrap(),
        t4.f64("second_derivatives_pct").unwrap(),
    );
    assert!(d1[0] > 0.0 && d1[0] < 1.0 && d2[0] > 0.0 && d2[0] < 1.0);
    // Two epochs on four samples teach a model the records' scale, not their shape: every
    // column near the 100 % of predicting zero (measured 100.0-106.6 %; a unit or sign error
    // would read far above), and the peak wheel-rail force, which the normalisation's mean
    // carries, within 10 % of the static wheel load (measured 3.0 % and 3.5 %).
    let cf = t4.f64("contact_forces_pct").unwrap();
    for column in [sol, d1, d2, cf] {
        assert!(
            column[1..].iter().all(|v| *v > 0.0 && *v < 115.0),
            "{column:?}"
        );
    }
    let peak = t4.f64("peak_contact_force_error_pct_w").unwrap();
    assert!(peak[1..].iter().all(|v| *v >= 0.0 && *v < 10.0), "{peak:?}");
    let paper = t4.f64("paper_second_derivatives_pct").unwrap();
    assert!(paper[0].is_nan() && paper[1..] == [20.79, 3.20]);
    let md = std::fs::read_to_string(out.join("table4.md")).unwrap();
    assert!(
        md.contains("| 5 | PINO-MBD (direct derivatives) | 5 |")
            && md.contains("on the test split (2 samples)")
            && md.contains("| - | truth (exact solutions, central differences) | - | 0.00 |")
            && !md.contains("WARNING"),
        "{md}"
    );
    let ch = pino_data::read_parquet(&out.join("channel_errors.parquet"), None).unwrap();
    assert_eq!(ch.num_rows(), 2 * (18 + 10 + 10 + 4));
    let names = ch.str("channel").unwrap();
    assert!(names.contains(&"p_4".to_owned()) && names.contains(&"p_4_hertz".to_owned()));
    for f in [
        "table4.csv",
        "channel_errors.csv",
        "training_curves.png",
        "pred_alg3_sample6.png",
        "plots.md",
        "speed.csv",
        "indices_errors.csv",
        "indices_errors.md",
        "indices_samples.parquet",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let out_eval = out.clone();

    // Without a test split: scored on validation, and the table says so loudly.
    let (ctx, out) = context(
        dir,
        "evaluate-no-test",
        serde_json::json!({"plot_samples": 0, "plot_channels": ["z_c", "z_w1"], "batch_size": 8,
                            "compare_with_paper": false}),
        serde_json::json!({"params": [no_test], "dataset": [no_test], "models": models}),
    );
    let o = run("evaluate", &["--context", ctx.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("NO TEST SPLIT"), "{}", text(&o));
    let t4 = pino_data::read_parquet(&out.join("table4.parquet"), None).unwrap();
    assert_eq!(t4.str("split").unwrap()[0], "validation");
    let md = std::fs::read_to_string(out.join("table4.md")).unwrap();
    assert!(
        md.contains("on the validation split (2 samples)") && md.contains("WARNING"),
        "{md}"
    );

    // predict: two sets from YAML, one override, a profile file.
    let yaml = dir.join("sets.yaml");
    std::fs::write(&yaml, "- {k_s: 4.2e5}\n- {v_kmh: 320}\n").unwrap();
    let profile = dir.join("profile.parquet");
    let xs: Vec<f64> = (0..2000).map(|k| k as f64 * 0.25).collect();
    let mut t = pino_data::Table::default();
    t.push("x", pino_data::Column::F64(xs.clone())).unwrap();
    t.push(
        "eta",
        pino_data::Column::F64(xs.iter().map(|x| 3e-4 * (x / 7.0).sin()).collect()),
    )
    .unwrap();
    pino_data::write_parquet(&profile, &t).unwrap();
    let pred = dir.join("pred.parquet");
    let o = run(
        "predict",
        &[
            "--model",
            models[1].to_str().unwrap(),
            "--params",
            yaml.to_str().unwrap(),
            "--set",
            "c_p=2.1e4",
            "--profile",
            profile.to_str().unwrap(),
            "--out",
            pred.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let p = pino_data::read_parquet(&pred, None).unwrap();
    // 270 window points -> 268 interior rows per set.
    assert_eq!(p.num_rows(), 2 * 268);
    for c in [
        "set", "t", "z_c", "z_r4", "p_1", "p_4", "beta_c_v", "z_w4_a", "eta_1",
    ] {
        assert!(p.column(c).is_ok(), "column {c}");
    }
    assert!(p.f64("z_w1_a").unwrap().iter().all(|v| v.is_finite()));

    // Engineering indices: evaluate scores them (truth row + 2 models); predict sweeps a grid
    // and writes them only; a design 25x above the trained k_f is flagged, and refused with
    // --strict (exit 2).
    let ie = pino_data::read_parquet(&out_eval.join("indices_errors.parquet"), None).unwrap();
    assert_eq!(ie.num_rows(), 3 * 14);
    assert!(out_eval
        .join("indices_scatter_sperling_wz_front.png")
        .is_file());
    let sweep = dir.join("sweep.yaml");
    std::fs::write(
        &sweep,
        "grid:\n  k_s: {from: 4.0e+5, to: 5.0e+5, steps: 2}\n  v_kmh: [310, 330]\n",
    )
    .unwrap();
    let ixp = dir.join("indices.parquet");
    let sweep_args = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = [
            "--model",
            models[1].to_str().unwrap(),
            "--sweep",
            sweep.to_str().unwrap(),
            "--profile",
            profile.to_str().unwrap(),
            "--indices",
            ixp.to_str().unwrap(),
            "--indices-only",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    fn strs(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    let o = run("predict", &strs(&sweep_args(&["--set", "k_f=4.0e7"])));
    assert!(o.status.success(), "{}", text(&o));
    let ix = pino_data::read_parquet(&ixp, None).unwrap();
    assert_eq!(ix.i64("set").unwrap(), &[0, 1, 2, 3]);
    assert_eq!(ix.f64("k_s").unwrap(), &[4.0e5, 4.0e5, 5.0e5, 5.0e5]);
    assert_eq!(ix.f64("v_kmh").unwrap(), &[310.0, 330.0, 310.0, 330.0]);
    assert!(ix
        .f64("peak_wheel_rail_force_kn")
        .unwrap()
        .iter()
        .all(|v| v.is_finite()));
    let o = run("predict", &strs(&sweep_args(&["--set", "k_f=1e9"])));
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("4 of 4 set(s) outside the model's training ranges")
            && text(&o).contains("k_f = 1000000000"),
        "{}",
        text(&o)
    );
    let ix = pino_data::read_parquet(&ixp, None).unwrap();
    assert!(ix
        .opt_str("outside_training_range")
        .unwrap()
        .iter()
        .all(|s| s.is_some_and(|s| s.contains("k_f=1000000000"))));
    let o = run(
        "predict",
        &strs(&sweep_args(&["--set", "k_f=1e9", "--strict"])),
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--strict: refused"), "{}", text(&o));

    // Bad input: unknown algorithm, missing column, model of another configuration.
    let (ctx, _) = context(
        dir,
        "bad-alg",
        {
            let mut p = small(3);
            p["algorithm"] = 6.into();
            p
        },
        inputs.clone(),
    );
    let o = run("train", &["--context", ctx.to_str().unwrap()]);
    assert!(
        !o.status.success() && text(&o).contains("unknown algorithm 6"),
        "{}",
        text(&o)
    );

    let broken = dir.join("broken");
    std::fs::create_dir_all(&broken).unwrap();
    let sim = pino_data::read_parquet(&data.join("simulation.parquet"), None).unwrap();
    let (_, described) = pino_data::system::read_record(std::slice::from_ref(&data)).unwrap();
    let units = pino_data::system::units_of(&described).unwrap();
    let mut cut = pino_data::Table::default().with_units(units);
    for (name, col) in sim.columns() {
        if name != "z_w3_a" {
            cut.push(name, col.clone()).unwrap();
        }
    }
    pino_data::write_parquet(&broken.join("simulation.parquet"), &cut).unwrap();
    // The dataset's records beside it (the description, the run controls).
    for record in [mbd_system::SYSTEM_FILE, pino_data::artifacts::RUN_FILE] {
        std::fs::copy(data.join(record), broken.join(record)).unwrap();
    }
    let (ctx, _) = context(
        dir,
        "bad-col",
        small(1),
        serde_json::json!({"params": [data], "dataset": [broken], "weights": [data]}),
    );
    let o = run("train", &["--context", ctx.to_str().unwrap()]);
    assert!(
        !o.status.success() && text(&o).contains("missing column `z_w3_a`"),
        "{}",
        text(&o)
    );

    std::fs::copy(models[0].join("model.json"), models[1].join("model.json")).unwrap();
    let o = run(
        "predict",
        &[
            "--model",
            models[1].to_str().unwrap(),
            "--seed",
            "1",
            "--out",
            pred.to_str().unwrap(),
        ],
    );
    assert!(!o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("model.safetensors") && text(&o).contains("depth 3"),
        "{}",
        text(&o)
    );
}

#[test]
fn the_budget_study_trains_algorithm_5_on_subsets_of_one_training_split() {
    // configs/budget-study.yaml: every training is algorithm 5 on at most the training split
    // the file samples, judged on the same validation split (one dataset for all).
    let file = "configs/budget-study.yaml";
    let root = pino_mbd_tests::workspace_root();
    let pipeline = orchestrator::spec::Pipeline::load(
        &root,
        &root.join(file),
        &orchestrator::spec::LoadOptions::default(),
    )
    .unwrap();
    let n_train = pino_mbd_tests::stage_params(file, "sample-params")["n_train"]
        .as_u64()
        .unwrap() as usize;
    let (_, described) = pino_mbd_tests::system("vtcd", &[]);
    let layout = pino_learn::layout::Layout::of(&described);
    let trainings: Vec<_> = pipeline
        .stages
        .iter()
        .filter(|s| s.cmd[0] == "train")
        .collect();
    assert_eq!(trainings.len(), 9);
    for stage in trainings {
        assert_eq!(
            stage.inputs.len(),
            2,
            "{}: params and dataset only",
            stage.name
        );
        let p: pino_learn::config::TrainParams =
            serde_json::from_value(stage.expansions[0].params.clone()).unwrap();
        p.configs(&layout).unwrap();
        assert_eq!(p.algorithm, 5, "{}", stage.name);
        let n = p.train_samples.expect("a subset");
        assert!(n <= n_train, "{}: {n} > {n_train}", stage.name);
    }
}

#[test]
fn pipeline_files_parameter_blocks_parse_into_the_learning_types() {
    for (file, system) in [
        ("pipeline.yaml", "vtcd"),
        ("configs/paper.yaml", "vtcd"),
        ("configs/long.yaml", "vtcd"),
        ("configs/quarter-car.yaml", "quarter-car"),
        ("configs/bridge.yaml", "bridge"),
    ] {
        let (_, described) = pino_mbd_tests::system(system, &[]);
        let layout = pino_learn::layout::Layout::of(&described);
        for alg in 1..=5 {
            let mut params = pino_mbd_tests::stage_params(file, "train");
            params["algorithm"] = serde_json::Value::from(alg);
            let p: pino_learn::config::TrainParams = serde_json::from_value(params).unwrap();
            let (m, _, _) = p.configs(&layout).unwrap_or_else(|e| panic!("{file}: {e}"));
            assert_eq!(m.depth, if alg == 5 { 5 } else { 3 }, "{file}");
            assert_eq!(
                (m.in_channels, m.out_channels),
                (layout.n_inputs(), layout.n_outputs()),
                "{file}"
            );
        }
        let _: pino_eval::EvalParams =
            serde_json::from_value(pino_mbd_tests::stage_params(file, "evaluate"))
                .unwrap_or_else(|e| panic!("{file}: {e}"));
    }
}

/// `rate_outputs`: the network outputs the stored accelerations the indices read, supervised
/// by their exact columns; `evaluate` and `predict` read them instead of differences, and a
/// column the description does not store is refused.
#[test]
fn rate_outputs_are_predicted_and_read_instead_of_differences() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (_, data) = tiny_dataset(dir);
    let inputs = serde_json::json!({"params": [data], "dataset": [data]});
    let params = |rates: &[&str]| {
        serde_json::json!({"algorithm": 4, "width": 8, "modes": 6, "projection_width": 16,
                           "padding": 0, "epochs": 2, "batch_size": 2, "learning_rate": 1e-3,
                           "lr_decay": 0.75, "lr_decay_every": 10, "lambda_ode": 0.25,
                           "lambda_d": 1.0, "beam_weight": 0.0, "rho": 0.025, "seed": 1,
                           "startup_fraction": 0.1, "time_stride": 1, "rate_outputs": rates})
    };
    // A column the description does not store is refused, naming it and the stored rates.
    let (ctx, _) = context(dir, "bad", params(&["z_c_jerk"]), inputs.clone());
    let o = run("train", &["--context", ctx.to_str().unwrap()]);
    let log = text(&o);
    assert!(
        !o.status.success()
            && log.contains(
                "params.rate_outputs: `z_c_jerk` is not a velocity or acceleration column"
            )
            && log.contains("z_c_v")
            && log.contains("z_t2_a"),
        "{log}"
    );

    let rates = ["z_c_a", "beta_c_a"];
    let (ctx, model) = context(dir, "train-rates", params(&rates), inputs.clone());
    let o = run("train", &["--context", ctx.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("model.json")).unwrap()).unwrap();
    let outputs = meta["layout"]["outputs"].as_array().unwrap();
    assert_eq!(meta["layout"]["rates"], 2);
    assert_eq!(outputs[outputs.len() - 2..], ["z_c_a", "beta_c_a"]);
    assert_eq!(
        meta["model"]["out_channels"].as_u64().unwrap() as usize,
        outputs.len()
    );

    let (ctx, out) = context(
        dir,
        "evaluate",
        serde_json::json!({"plot_samples": 0, "plot_channels": ["z_c"], "batch_size": 8,
                            "compare_with_paper": false}),
        serde_json::json!({"params": [data], "dataset": [data], "models": [model]}),
    );
    let o = run("evaluate", &["--context", ctx.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    // The direct outputs are scored beside the differences of the displacements.
    let ch = pino_data::read_parquet(&out.join("channel_errors.parquet"), None).unwrap();
    let names = ch.str("channel").unwrap();
    let at = |n: &str| names.iter().position(|x| x == n).unwrap();
    assert_eq!(ch.str("unit").unwrap()[at("z_c_a (output)")], "m/s^2");
    assert_eq!(ch.str("unit").unwrap()[at("beta_c_a (output)")], "rad/s^2");
    assert!(names.contains(&"z_c_a".to_owned()));
    let md = std::fs::read_to_string(out.join("indices_errors.md")).unwrap();
    assert!(
        md.contains("Algorithm 4 reads `z_c_a`, `beta_c_a` from its own outputs"),
        "{md}"
    );

    // predict: one `z_c_a` column, the network's own (not the second difference of `z_c`,
    // which the bogies' `z_t1_a` still is).
    let pred = dir.join("pred.parquet");
    let o = run(
        "predict",
        &[
            "--model",
            model.to_str().unwrap(),
            "--set",
            "k_s=4.2e5",
            "--seed",
            "3",
            "--out",
            pred.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let p = pino_data::read_parquet(&pred, None).unwrap();
    assert_eq!(p.names().filter(|n| *n == "z_c_a").count(), 1);
    let dt = {
        let t = p.f64("t").unwrap();
        t[1] - t[0]
    };
    let second_difference_gap = |x: &str, a: &str| {
        let (x, a) = (p.f64(x).unwrap(), p.f64(a).unwrap());
        (1..x.len() - 1)
            .map(|n| ((x[n + 1] - 2.0 * x[n] + x[n - 1]) / (dt * dt) - a[n]).abs())
            .fold(0.0, f64::max)
            / a.iter().fold(0.0f64, |m, v| m.max(v.abs()))
    };
    assert!(second_difference_gap("z_t1", "z_t1_a") < 1e-6);
    assert!(second_difference_gap("z_c", "z_c_a") > 1e-3);
}

/// The shipped pipelines train a rate-output candidate: `train-rates` is `train`'s algorithm 5
/// with `rate_outputs` (stored rates of its description) and nothing else changed (`extends`);
/// every model trained is a candidate of the one surrogate, calibrated together, and the
/// studies, the export and `evaluate`'s report read that surrogate, not a model.
#[test]
fn every_trained_model_is_a_candidate_of_the_one_surrogate_the_studies_read() {
    for (file, system, rates) in [
        ("pipeline.yaml", "vtcd", 4),
        ("configs/bridge.yaml", "bridge", 1),
        ("configs/quarter-car.yaml", "quarter-car", 1),
    ] {
        let (_, described) = pino_mbd_tests::system(system, &[]);
        let plain = pino_mbd_tests::stage_spec(file, "train")
            .expansions
            .into_iter()
            .map(|e| e.params)
            .find(|p| p["algorithm"] == 5)
            .unwrap_or_else(|| panic!("{file}: `train` has no algorithm 5"));
        let rated = pino_mbd_tests::stage_spec(file, "train-rates");
        assert_eq!(rated.expansions.len(), 1, "{file}");
        let description = format!("systems/{system}.yaml");
        assert_eq!(rated.cmd, ["train", description.as_str()], "{file}");
        let mut with = rated.expansions[0].params.clone();
        let p: pino_learn::config::TrainParams = serde_json::from_value(with.clone()).unwrap();
        let layout = pino_learn::layout::Layout::of(&described)
            .with_rate_outputs(&described, &p.rate_outputs)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(layout.rates, rates, "{file}");
        p.configs(&layout).unwrap();
        let map = with.as_object_mut().unwrap();
        map.remove("rate_outputs");
        map.remove("rate_weight");
        assert_eq!(with, plain, "{file}");
        // Every stage running `train` is a candidate, calibrated in one `calibrate` run.
        let pipeline = pino_mbd_tests::shipped_pipeline(file);
        let trained: Vec<&str> = pipeline
            .stages
            .iter()
            .filter(|s| s.cmd[0] == "train")
            .map(|s| s.name.as_str())
            .collect();
        let surrogate = pino_mbd_tests::stage_spec(file, "surrogate");
        let mut candidates = surrogate.inputs["candidates"].clone();
        candidates.sort();
        let mut want: Vec<String> = trained.iter().map(|s| s.to_string()).collect();
        want.sort();
        assert_eq!(candidates, want, "{file}");
        assert_eq!(surrogate.inputs["calibration"], ["calibrate"], "{file}");
        assert_eq!(
            pino_mbd_tests::stage_spec(file, "calibrate").inputs["models"],
            surrogate.inputs["candidates"],
            "{file}"
        );
        // Whatever reads answers reads the surrogate; no stage routes by hand.
        for s in &pipeline.stages {
            if ["study", "export"].contains(&s.cmd[0].as_str()) {
                assert_eq!(s.inputs.len(), 1, "{file}: {}", s.name);
                assert_eq!(s.inputs["surrogate"], ["surrogate"], "{file}: {}", s.name);
            }
        }
        assert_eq!(
            pino_mbd_tests::stage_spec(file, "evaluate").inputs["surrogate"],
            ["surrogate"],
            "{file}"
        );
    }
}

/// A rate output the description does not store is refused at planning (the `train` check,
/// `pipeline run` exit 2, nothing run), at the line of `rate_outputs` in the pipeline file.
#[test]
fn an_unstored_rate_output_is_refused_at_planning_at_its_line() {
    let root = pino_mbd_tests::workspace_root();
    let file = "configs/quarter-car.yaml";
    let yaml = std::fs::read_to_string(root.join(file)).unwrap();
    let line = 1 + yaml
        .lines()
        .position(|l| l.trim_start().starts_with("rate_outputs:"))
        .unwrap();
    let ws = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(ws.path().join("configs")).unwrap();
    std::fs::create_dir_all(ws.path().join("systems")).unwrap();
    std::fs::write(ws.path().join(file), &yaml).unwrap();
    std::fs::copy(
        root.join("systems/quarter-car.yaml"),
        ws.path().join("systems/quarter-car.yaml"),
    )
    .unwrap();
    let o = std::process::Command::new(pino_mbd_tests::bin("pipeline"))
        .current_dir(ws.path())
        .args(["--bin-dir"])
        .arg(pino_mbd_tests::pipeline_bin_dir(file))
        .args([
            "-f",
            file,
            "run",
            "--set",
            "train-rates.rate_outputs=[z_s_jerk]",
        ])
        .env_remove("PINO_BIN_DIR")
        .output()
        .unwrap();
    let err = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("quarter-car.yaml:{line}: train: params.rate_outputs: `z_s_jerk` is not a velocity or acceleration column"))
            && err.contains("z_s_a"),
        "{err}"
    );
    assert!(!ws.path().join("artifacts/objects").exists(), "nothing ran");
}
