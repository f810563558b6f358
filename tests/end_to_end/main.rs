//! The whole product, end to end: the real `pipeline.yaml` (every stage, as a user runs it)
//! driven by the real `pipeline` binary on the real stage binaries, shrunk through `--set`
//! to seconds of work: 17 samples (4 train, 2 validation, 1 test, 10 calibration) of 0.5 s on a 120 m track,
//! tiny networks, 2 epochs.
//!
//! What it proves: the stages agree on the artifact contract (file names, columns, input
//! wiring, shards and the train matrix), the outputs are the public schema, and a second run
//! is a no-op. Accuracy is not asserted here (2 epochs learn little); the learning tests do.

use mbd_system::system::Role;
use pino_data::system::channel_names;
use pino_data::{read_parquet, schema};
use pino_mbd_tests::output_text;
use pino_mbd_tests::TINY;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod kill_resume;

/// `pipeline` in `ws` on this profile's binaries, with the TINY overrides and then `extra`.
fn pipeline_cmd(ws: &Path, extra: &[&str]) -> Command {
    let mut cmd = Command::new(pino_mbd_tests::bin("pipeline"));
    cmd.current_dir(ws)
        .arg("--bin-dir")
        .arg(pino_mbd_tests::pipeline_bin_dir("pipeline.yaml"))
        .env_remove("PINO_BIN_DIR");
    for s in TINY.iter().chain(extra) {
        cmd.arg("--set").arg(s);
    }
    cmd
}

fn pipeline(ws: &Path, args: &[&str]) -> Output {
    pipeline_cmd(ws, &[])
        .args(args)
        .output()
        .expect("pipeline runs")
}

fn show(ws: &Path, stage: &str, extra: &[&str]) -> Vec<PathBuf> {
    let o = pipeline_cmd(ws, extra)
        .args(["show", stage])
        .output()
        .expect("pipeline runs");
    assert!(o.status.success(), "show {stage}: {}", output_text(&o));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(PathBuf::from)
        .collect()
}

fn named<'a>(files: &'a [PathBuf], name: &str) -> Vec<&'a PathBuf> {
    files
        .iter()
        .filter(|p| p.file_name().is_some_and(|n| n == name))
        .collect()
}

/// Samples of the TINY run: 4 train, 2 validation, 1 test, 10 calibration.
const SAMPLES: i64 = 17;

#[test]
fn the_default_pipeline_runs_end_to_end_and_then_is_fresh() {
    let ws = pino_mbd_tests::product_workspace("pipeline.yaml");
    let (_, system) = pino_mbd_tests::system("vtcd", &[]);
    let columns: Vec<String> = [schema::SAMPLE_ID, schema::TIME]
        .into_iter()
        .map(str::to_owned)
        .chain(system.channels.iter().map(|c| c.name.clone()))
        .collect();

    let first = pipeline(ws.path(), &["run"]);
    assert!(first.status.success(), "{}", output_text(&first));

    // The simulation is the public schema, both shards together hold every sample once.
    let sim = show(ws.path(), "simulate", &[]);
    let shards = named(&sim, "simulation.parquet");
    assert_eq!(shards.len(), 2, "two shards: {sim:?}");
    let mut ids = Vec::new();
    for file in &shards {
        let t = read_parquet(file, None).unwrap();
        let names: Vec<String> = t.names().map(str::to_owned).collect();
        assert_eq!(names, columns, "{}", file.display());
        let mut these: Vec<i64> = t.i64(schema::SAMPLE_ID).unwrap().to_vec();
        these.dedup();
        ids.extend(these);
        for p in channel_names(&system, Role::Force) {
            assert!(t
                .f64(&p)
                .unwrap()
                .iter()
                .all(|x| x.is_finite() && *x >= 0.0));
        }
    }
    ids.sort();
    assert_eq!(ids, (0..SAMPLES).collect::<Vec<i64>>());

    // phi for the four training samples, positive and finite.
    let weights = show(ws.path(), "weights", &[]);
    let w = read_parquet(named(&weights, "weights.parquet")[0], None).unwrap();
    assert_eq!(w.i64(schema::SAMPLE_ID).unwrap(), &[0, 1, 2, 3]);
    let phi = pino_learn::layout::Layout::of(&system).phi_columns();
    assert_eq!(phi.len(), 10, "one weight per vehicle DOF: {phi:?}");
    for c in phi {
        assert!(
            w.f64(&c).unwrap().iter().all(|x| x.is_finite() && *x > 0.0),
            "{c}"
        );
    }

    // One model per algorithm of the matrix, and a Table 4 row for each, after the truth row.
    let models = show(ws.path(), "train", &[]);
    assert_eq!(named(&models, "model.safetensors").len(), 5, "{models:?}");
    let eval = show(ws.path(), "evaluate", &[]);
    let table = read_parquet(named(&eval, "table4.parquet")[0], None).unwrap();
    assert_eq!(table.num_rows(), 6);
    assert_eq!(table.i64("algorithm").unwrap(), &[0, 1, 2, 3, 4, 5]);
    let md = std::fs::read_to_string(named(&eval, "table4.md")[0]).unwrap();
    assert!(md.contains('|'), "{md}");
    assert!(
        eval.iter()
            .any(|p| p.extension().is_some_and(|e| e == "png")),
        "plots: {eval:?}"
    );

    // Engineering indices: one row per simulated sample, every index finite; the evaluation
    // scores them for the truth row and each algorithm.
    let ix = show(ws.path(), "indices", &[]);
    let t = read_parquet(named(&ix, "indices.parquet")[0], None).unwrap();
    assert_eq!(
        t.i64(schema::SAMPLE_ID).unwrap(),
        (0..SAMPLES).collect::<Vec<i64>>().as_slice()
    );
    for c in pino_indices::INDEX_COLUMNS {
        assert!(
            t.f64(c.name).unwrap().iter().all(|x| x.is_finite()),
            "{}",
            c.name
        );
    }
    assert!(t
        .f64("peak_wheel_rail_force_kn")
        .unwrap()
        .iter()
        .all(|&p| p > 30.0 && p < 300.0));
    let errors = read_parquet(named(&eval, "indices_errors.parquet")[0], None).unwrap();
    assert_eq!(errors.num_rows(), 6 * pino_indices::INDEX_COLUMNS.len());
    assert_eq!(
        named(&eval, "indices_scatter_peak_wheel_rail_force_kn.png").len(),
        1
    );

    // One calibration per model (the paper's five, the rate and the force candidates) on the
    // ten calibration samples; evaluate reports the coverage on the test split of the five.
    let cals = show(ws.path(), "calibrate", &[]);
    assert_eq!(named(&cals, "calibration.json").len(), 7, "{cals:?}");
    let cov = read_parquet(named(&eval, "coverage.parquet")[0], None).unwrap();
    let mut algs: Vec<i64> = cov.i64("algorithm").unwrap().to_vec();
    algs.dedup();
    assert_eq!(algs, [1, 2, 3, 4, 5]);
    assert!(cov.i64("n_calibration").unwrap().iter().all(|&n| n == 10));

    // The surrogate: every index routed to a member among the seven candidates, every member a
    // model with its calibration; evaluate scores it per index beside Table 4.
    let sur = show(ws.path(), "surrogate", &[]);
    let dir = named(&sur, "surrogate.json")[0]
        .parent()
        .unwrap()
        .to_owned();
    let manifest = pino_surrogate::manifest::Manifest::load(&dir).unwrap();
    assert_eq!(manifest.candidates.len(), 7);
    assert_eq!(manifest.indices.len(), pino_indices::INDEX_COLUMNS.len());
    let members: Vec<&str> = manifest.members.iter().map(|m| m.name.as_str()).collect();
    assert!(manifest
        .indices
        .iter()
        .chain(&manifest.channels)
        .all(|r| members.contains(&r.member.as_str()) && r.validation.len() >= 5));
    let rows = read_parquet(named(&eval, "surrogate_errors.parquet")[0], None).unwrap();
    let kinds = rows.str("kind").unwrap();
    let quantities = rows.str("quantity").unwrap();
    let index_rows: Vec<&str> = (0..rows.num_rows())
        .filter(|&r| kinds[r] == "index")
        .map(|r| quantities[r].as_str())
        .collect();
    let index_names: Vec<&str> = pino_indices::INDEX_COLUMNS.iter().map(|c| c.name).collect();
    assert_eq!(index_rows, index_names);

    // The study: every design evaluated, the exceedance probability of its summary recomputed
    // from the evaluations, the solver beside 20 of them, and the same bytes from the unit's
    // context run again by hand on 1 and on 2 threads.
    let study = show(ws.path(), "study[study=wheel_unloading]", &[]);
    let evals = read_parquet(named(&study, "evaluations.parquet")[0], None).unwrap();
    assert_eq!(evals.num_rows(), 2000);
    let checked = |t: &pino_data::Table| {
        t.bool("solver_checked")
            .unwrap()
            .iter()
            .filter(|&&c| c)
            .count()
    };
    assert_eq!(checked(&evals), 20);
    let q = evals.f64("wheel_load_reduction_rate").unwrap();
    let over = q.iter().filter(|&&x| x > 0.6).count() as f64 / q.len() as f64;
    let summary = read_parquet(named(&study, "summary.parquet")[0], None).unwrap();
    let row = (0..summary.num_rows())
        .find(|&r| {
            summary.str("index").unwrap()[r] == "wheel_load_reduction_rate"
                && summary.str("source").unwrap()[r] == "surrogate"
        })
        .expect("a surrogate row of the wheel-load reduction rate");
    assert_eq!(summary.f64("p_exceed").unwrap()[row], over);
    assert_eq!(summary.f64("limit").unwrap()[row], 0.6);
    let lo = evals.f64("wheel_load_reduction_rate_lo").unwrap();
    let hi = evals.f64("wheel_load_reduction_rate_hi").unwrap();
    assert!(lo.iter().zip(q).zip(hi).all(|((l, v), h)| l <= v && v <= h));
    let solver = read_parquet(named(&study, "solver.parquet")[0], None).unwrap();
    assert_eq!(solver.num_rows(), 20);
    assert!(solver
        .opt_str("solver_failure")
        .unwrap()
        .iter()
        .all(Option::is_none));
    assert!(solver
        .f64("peak_wheel_rail_force_kn")
        .unwrap()
        .iter()
        .all(|&p| p > 30.0 && p < 300.0));
    // The sensitivity study: SALib's order, the solver's rows, one estimate per index, source
    // and factor (the interop test recomputes them with SALib).
    let sensitivity = show(ws.path(), "study[study=drivers]", &[]);
    let evals = read_parquet(named(&sensitivity, "evaluations.parquet")[0], None).unwrap();
    let factors = system.sampled_names().len() + 1;
    let per_row = factors + 2;
    assert_eq!(evals.num_rows(), 256 * per_row);
    let (row, position) = (evals.i64("row").unwrap(), evals.i64("position").unwrap());
    for (k, (r, p)) in row.iter().zip(position).enumerate() {
        assert_eq!((*r as usize, *p as usize), (k / per_row, k % per_row));
    }
    assert_eq!(checked(&evals), 16 * per_row);
    let sobol = read_parquet(named(&sensitivity, "sobol.parquet")[0], None).unwrap();
    let indices = pino_study::index_names(&system).unwrap();
    assert_eq!(sobol.num_rows(), indices.len() * 3 * factors);
    let total = sobol.f64("ST").unwrap();
    assert!(
        total.iter().all(|&t| t >= 0.0),
        "Jansen's total index is a mean of squares"
    );
    for chunk in sobol.f64("rank").unwrap().chunks(factors) {
        let mut ranks: Vec<usize> = chunk.iter().map(|&r| r as usize).collect();
        ranks.sort_unstable();
        assert_eq!(ranks, (1..=factors).collect::<Vec<_>>());
    }
    let solver = read_parquet(named(&sensitivity, "solver.parquet")[0], None).unwrap();
    assert_eq!(solver.num_rows(), 16 * per_row);
    assert!(solver
        .opt_str("solver_failure")
        .unwrap()
        .iter()
        .all(Option::is_none));

    // The optimisation: every candidate under the same excitations, the optimum the best
    // feasible candidate of the history, its objective the mean of its evaluations, and the
    // solver beside the optimum, the runners-up and the spread candidates.
    let optimise = show(ws.path(), "study[study=quiet_car_body]", &[]);
    let history = read_parquet(named(&optimise, "history.parquet")[0], None).unwrap();
    let evals = read_parquet(named(&optimise, "evaluations.parquet")[0], None).unwrap();
    let excitations = 8;
    assert!(history.num_rows() > 40, "{} candidates", history.num_rows());
    assert_eq!(evals.num_rows(), history.num_rows() * excitations);
    let (objective, feasible) = (
        history.f64("objective").unwrap(),
        history.bool("feasible").unwrap(),
    );
    let best = (0..history.num_rows())
        .filter(|&c| feasible[c])
        .min_by(|&a, &b| objective[a].total_cmp(&objective[b]))
        .expect("a feasible candidate");
    let optimum = read_parquet(named(&optimise, "optimum.parquet")[0], None).unwrap();
    let (role, source) = (optimum.str("role").unwrap(), optimum.str("source").unwrap());
    let row = (0..optimum.num_rows())
        .find(|&r| role[r] == "optimum" && source[r] == "surrogate")
        .expect("the optimum's surrogate row");
    let chosen = optimum.i64("candidate").unwrap()[row] as usize;
    assert_eq!(
        objective[chosen], objective[best],
        "the optimum is the best feasible"
    );
    let rms = evals.f64("car_body_acc_rms_centre_ms2").unwrap();
    let mean = rms[chosen * excitations..(chosen + 1) * excitations]
        .iter()
        .sum::<f64>()
        / excitations as f64;
    assert!((mean - objective[chosen]).abs() <= 1e-12 * mean.abs());
    let n_checked = optimum.num_rows() / 2;
    assert!(
        (4..=7).contains(&n_checked) && role.iter().filter(|r| *r == "runner_up").count() == 4,
        "{role:?}"
    );
    assert_eq!(checked(&evals), n_checked * excitations);
    let solver = read_parquet(named(&optimise, "solver.parquet")[0], None).unwrap();
    assert_eq!(solver.num_rows(), n_checked * excitations);

    // Each kind's plots.
    for (files, plots) in [
        (
            &study,
            &[
                "histograms.png",
                "exceedance.png",
                "surrogate_vs_solver.png",
            ][..],
        ),
        (&sensitivity, &["sobol.png", "surrogate_vs_solver.png"][..]),
        (&optimise, &["history.png", "surrogate_vs_solver.png"][..]),
    ] {
        for plot in plots {
            let png = std::fs::read(named(files, plot)[0]).unwrap();
            assert_eq!(&png[1..4], b"PNG", "{plot}");
        }
    }

    // The pipeline ran each unit on all cores; again by hand on 1 and 2 threads (the
    // sensitivity study and the optimisation, the costlier, on 1).
    same_bytes_by_hand(ws.path(), &study, &[1, 2]);
    same_bytes_by_hand(ws.path(), &sensitivity, &[1]);
    same_bytes_by_hand(ws.path(), &optimise, &[1]);

    // Same inputs: nothing to do.
    let second = pipeline(ws.path(), &["run"]);
    assert!(second.status.success(), "{}", output_text(&second));
    assert!(
        output_text(&second).contains("Nothing to do"),
        "second run should do nothing: {}",
        output_text(&second)
    );
}

/// Runs the study unit of `files` (its outputs) again by hand from its context on each of
/// `threads`: every file but the timings has the same bytes.
fn same_bytes_by_hand(ws: &Path, files: &[PathBuf], threads: &[usize]) {
    let unit = files[0]
        .parent()
        .and_then(Path::parent)
        .expect("objects/<id>/out");
    let ctx: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(unit.join("context.json")).unwrap()).unwrap();
    for &threads in threads {
        let scratch = tempfile::tempdir().unwrap();
        let (path, out) = pino_mbd_tests::stage_context(
            scratch.path(),
            ctx["stage"].as_str().unwrap(),
            ctx["params"].clone(),
            ctx["inputs"].clone(),
            false,
        );
        let o =
            pino_mbd_tests::run_stage("study", Some(&ws.join("systems/vtcd.yaml")), &path, threads);
        assert!(o.status.success(), "{}", output_text(&o));
        for f in files.iter().filter(|f| !f.ends_with("speed.csv")) {
            let again = out.join(f.file_name().unwrap());
            assert!(
                std::fs::read(f).unwrap() == std::fs::read(&again).unwrap(),
                "{} differs on {threads} thread(s)",
                f.display()
            );
        }
    }
}

/// Every stage file of a workspace's store (none when nothing ran).
fn stored_objects(ws: &Path) -> usize {
    std::fs::read_dir(ws.join("artifacts/objects")).map_or(0, |d| d.count())
}

/// A bad description, or a time step above the stability bound over the box of sampling
/// ranges, stops `pipeline run` during planning: exit 2, the checker's message (file, line and
/// the offending name; both time steps), and nothing runs.
#[test]
fn a_bad_description_or_time_step_stops_the_run_before_anything_runs() {
    let ws = pino_mbd_tests::product_workspace("pipeline.yaml");
    let path = ws.path().join("systems/vtcd.yaml");
    let good = std::fs::read_to_string(&path).unwrap();
    let line = good
        .lines()
        .position(|l| l.starts_with("  s1: {kind: spring_damper"))
        .expect("the secondary suspension s1")
        + 1;
    std::fs::write(
        &path,
        good.replacen("to: t1, k: k_s,", "to: t1, k: k_ss,", 1),
    )
    .unwrap();
    let o = pipeline(ws.path(), &["run"]);
    let text = output_text(&o);
    assert_eq!(o.status.code(), Some(2), "{text}");
    assert!(
        text.contains(&format!("systems/vtcd.yaml:{line}:")) && text.contains("`k_ss`"),
        "{text}"
    );
    assert_eq!(stored_objects(ws.path()), 0, "nothing ran: {text}");

    std::fs::write(&path, &good).unwrap();
    let o = pipeline_cmd(ws.path(), &["simulate.dt=1.0e-3"])
        .arg("run")
        .output()
        .expect("pipeline runs");
    let text = output_text(&o);
    assert_eq!(o.status.code(), Some(2), "{text}");
    assert!(
        text.contains("stage `simulate`") && text.contains("0.001") && text.contains("bound"),
        "{text}"
    );
    assert_eq!(stored_objects(ws.path()), 0, "nothing ran: {text}");
}
