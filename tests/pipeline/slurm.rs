//! `pipeline run --executor slurm` against a real Slurm cluster: fixture pipelines, a sharded
//! stage as one array job (and only its unfinished shards resubmitted), the orchestrator killed
//! with SIGKILL (re-attach, no duplicate submission, resubmission of a vanished job), SIGTERM
//! (scancel), a failing and a cancelled job, and a small real physics run compared byte for
//! byte with the local executor.
//!
//! The cluster tests need `PINO_SLURM=1` (CI sets it after `.ci/slurm-up` started a one-node
//! cluster); with it set, an unreachable cluster FAILS the tests. Without it they print that
//! they were skipped and return. The missing-Slurm test needs no cluster and always runs.

use crate::harness::{ok, sorted, Ws};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// Whether to run the cluster tests (see the module doc); panics when asked for but absent.
fn cluster(test: &str) -> bool {
    if std::env::var("PINO_SLURM").as_deref() != Ok("1") {
        // Straight to stderr (not eprintln!), so that libtest's capture does not hide it.
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED {test}: the Slurm tests need a cluster; run them with PINO_SLURM=1 (`.ci/slurm-up` starts a one-node cluster as root)"
        );
        return false;
    }
    let out = Command::new("sinfo").args(["-h", "-o", "%T"]).output();
    match out {
        Ok(o) if o.status.success() && !o.stdout.is_empty() => true,
        Ok(o) => panic!(
            "PINO_SLURM=1 but the cluster does not answer: sinfo: {} {}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => panic!("PINO_SLURM=1 but `sinfo` cannot run: {e}"),
    }
}

/// Like [`wait_until`] but for cluster round trips (a job start can take seconds): 120 s.
fn wait_long(what: &str, mut cond: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !cond() {
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "timed out waiting for: {what}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Job ids (`12`, `12_3`) in the queue.
fn queued() -> Vec<String> {
    let o = Command::new("squeue")
        .args(["-h", "-r", "-o", "%i"])
        .output()
        .unwrap();
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| l.trim().to_owned())
        .collect()
}

/// The batch scripts submitted in this workspace for `stage`, oldest first, as the (sorted)
/// array task ids each one covers.
fn submissions(ws: &Ws, stage: &str) -> Vec<Vec<usize>> {
    let dir = ws.path().join("artifacts/slurm/jobs");
    let mut scripts: Vec<(std::time::SystemTime, PathBuf)> = std::fs::read_dir(&dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| {
                    let n = p.file_name().unwrap().to_string_lossy().into_owned();
                    n.starts_with(&format!("{stage}-")) && n.ends_with(".sh")
                })
                .map(|p| (p.metadata().unwrap().modified().unwrap(), p))
                .collect()
        })
        .unwrap_or_default();
    scripts.sort();
    scripts
        .iter()
        .map(|(_, p)| {
            let mut ids: Vec<usize> = std::fs::read_to_string(p)
                .unwrap()
                .lines()
                .filter_map(|l| l.trim().split_once(") d=").map(|(i, _)| i.parse().unwrap()))
                .collect();
            ids.sort_unstable();
            ids
        })
        .collect()
}

/// Every current output file of `stage` in `a` equals the one in `b` (same bytes, same
/// object ids).
fn same_outputs(a: &Ws, b: &Ws, stage: &str) {
    let x = a.show(stage);
    let y = b.show(stage);
    assert_eq!(x.len(), y.len(), "{stage}");
    for (p, q) in x.iter().zip(&y) {
        assert_eq!(
            std::fs::read(p).unwrap(),
            std::fs::read(q).unwrap(),
            "{stage}: {p:?}"
        );
        assert_eq!(
            p.strip_prefix(a.path()).unwrap(),
            q.strip_prefix(b.path()).unwrap()
        );
    }
}

fn count(text: &str, line: &str) -> usize {
    text.lines().filter(|l| *l == line).count()
}

#[test]
fn slurm_missing_is_bad_input_and_nothing_runs() {
    let ws = Ws::new("basic.yaml");
    // A PATH without Slurm's commands (the stage itself is found in --bin-dir).
    let empty = tempfile::tempdir().unwrap();
    let r: crate::harness::Run = ws
        .command(&["run", "--executor", "slurm"])
        .env("PATH", empty.path())
        .output()
        .unwrap()
        .into();
    assert_eq!(r.code, 2, "{r:#?}");
    assert!(
        r.stderr.contains("executor slurm") && r.stderr.contains("not found on PATH"),
        "{}",
        r.stderr
    );
    assert!(!ws.path().join("artifacts").exists(), "nothing was run");
    assert!(ws.ran().is_empty());

    // The same through the file's `executor:` key.
    ws.set_pipeline(&format!("executor: slurm\n{}", ws.pipeline_text()));
    let r: crate::harness::Run = ws
        .command(&["run"])
        .env("PATH", empty.path())
        .output()
        .unwrap()
        .into();
    assert_eq!(r.code, 2, "{r:#?}");
    // ... and `--executor local` overrides it.
    ok(ws.run(&["run", "--executor", "local"]));
}

#[test]
fn fixture_pipeline_on_slurm_matches_local_and_is_then_fresh() {
    if !cluster("fixture_pipeline_on_slurm_matches_local_and_is_then_fresh") {
        return;
    }
    let ws = Ws::new("basic.yaml");
    let r = ok(ws.run(&["run", "--executor", "slurm"]));
    assert_eq!(
        ws.ran(),
        sorted(&["prepare", "transform", "report", "side"]),
        "{}",
        r.stdout
    );
    assert!(
        r.stdout.contains("prepared 3 rows"),
        "summary travels: {}",
        r.stdout
    );
    let local = Ws::new("basic.yaml");
    ok(local.run(&["run"]));
    for s in ["prepare", "transform", "report", "side"] {
        same_outputs(&ws, &local, s);
    }
    // Cached on either executor.
    let again = ok(ws.run(&["run", "--executor", "slurm"]));
    assert!(again.stdout.contains("Nothing to do"), "{}", again.stdout);
    assert!(ws.ran().is_empty());
    // The unit directories were committed (renamed into objects/), none is left behind.
    let left: Vec<_> = std::fs::read_dir(ws.path().join("artifacts/slurm"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name() != "jobs")
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn sharded_stage_is_one_array_job_of_the_unfinished_shards() {
    if !cluster("sharded_stage_is_one_array_job_of_the_unfinished_shards") {
        return;
    }
    let ws = Ws::new("sharded.yaml");
    let r = ok(ws.run(&["run", "--executor", "slurm"]));
    assert_eq!(
        ws.ran(),
        sorted(&[
            "source",
            "simulate#0",
            "simulate#1",
            "simulate#2",
            "simulate#3",
            "collect"
        ]),
        "{}",
        r.stdout
    );
    assert_eq!(submissions(&ws, "simulate"), [vec![0, 1, 2, 3]]);
    // Progress lines of the jobs reach the orchestrator (plain lines when not a terminal).
    assert!(r.stderr.contains("[simulate#3]"), "{}", r.stderr);

    // Lose two shards' objects: only those two are resubmitted, as one array.
    let rec = ws.read("artifacts/pipeline.lock.json");
    let rec: serde_json::Value = serde_json::from_str(&rec).unwrap();
    let units = rec["pipelines"]["pipeline.yaml"].as_object().unwrap();
    for shard in ["simulate#1", "simulate#3"] {
        let id = units[shard]["identity"].as_str().unwrap();
        std::fs::remove_dir_all(ws.path().join("artifacts/objects").join(id)).unwrap();
    }
    let r = ok(ws.run(&["run", "--executor", "slurm"]));
    assert_eq!(
        ws.ran(),
        sorted(&["simulate#1", "simulate#3"]),
        "{}",
        r.stdout
    );
    assert_eq!(submissions(&ws, "simulate"), [vec![0, 1, 2, 3], vec![1, 3]]);
    assert!(r.stdout.contains("collect"), "{}", r.stdout);
    let local = Ws::new("sharded.yaml");
    ok(local.run(&["run"]));
    for s in ["simulate", "collect"] {
        same_outputs(&ws, &local, s);
    }
}

#[test]
fn killed_orchestrator_reattaches_and_resubmits_only_vanished_jobs() {
    if !cluster("killed_orchestrator_reattaches_and_resubmits_only_vanished_jobs") {
        return;
    }
    let ws = Ws::new("sharded.yaml");
    std::fs::write(ws.gate(), b"").unwrap();
    // Shards 2 and 3 wait on the gate; 0 and 1 finish and are committed.
    let mut child = ws.spawn(&["run", "--executor", "slurm"], "killed");
    wait_long("shards 0 and 1 committed while 2 and 3 run", || {
        let lock = ws.read("artifacts/pipeline.lock.json");
        let log = std::fs::read_to_string(ws.log_path()).unwrap_or_default();
        lock.contains("\"simulate#0\"")
            && lock.contains("\"simulate#1\"")
            && log.contains("start simulate#2")
            && log.contains("start simulate#3")
    });
    child.kill().unwrap(); // SIGKILL: the jobs stay queued or running on the cluster
    child.wait().unwrap();
    let arrays = submissions(&ws, "simulate");
    assert_eq!(arrays, [vec![0, 1, 2, 3]]);

    // `status` names the jobs still on the cluster.
    let st = ok(ws.run(&["status"]));
    let line = |unit: &str| {
        st.stdout
            .lines()
            .find(|l| l.starts_with(unit))
            .unwrap_or_default()
            .to_owned()
    };
    assert!(line("simulate#2").contains("submitted"), "{}", st.stdout);
    assert!(
        line("simulate#2").contains("running on Slurm: job"),
        "{}",
        st.stdout
    );
    let job3 = line("simulate#3")
        .split("job ")
        .nth(1)
        .expect("job id of shard 3")
        .trim()
        .to_owned();
    assert!(job3.ends_with("_3"), "{job3}");
    assert!(line("simulate#0").contains("fresh"), "{}", st.stdout);

    // Shard 3's job vanishes while nobody watches; shard 2's keeps running.
    assert!(Command::new("scancel")
        .arg(&job3)
        .status()
        .unwrap()
        .success());
    wait_long("shard 3's job to leave the queue", || {
        !queued().contains(&job3)
    });

    let mut second = ws.spawn(&["run", "--executor", "slurm"], "second");
    wait_long("the second run to re-attach to shard 2", || {
        ws.read("second.err")
            .contains("[simulate#2] re-attaching to Slurm job")
    });
    wait_long("shard 3 resubmitted", || {
        submissions(&ws, "simulate").len() == 2
    });
    std::fs::remove_file(ws.gate()).unwrap();
    let status = second.wait().unwrap();
    assert!(
        status.success(),
        "{}\n{}",
        ws.read("second.out"),
        ws.read("second.err")
    );
    // Only shard 3 was submitted again; shard 2 ran once, in its first job.
    assert_eq!(submissions(&ws, "simulate"), [vec![0, 1, 2, 3], vec![3]]);
    let log = std::fs::read_to_string(ws.log_path()).unwrap();
    assert_eq!(count(&log, "start simulate#2"), 1, "{log}");
    assert_eq!(count(&log, "end simulate#2"), 1, "{log}");
    assert_eq!(count(&log, "start simulate#3"), 2, "{log}");
    assert_eq!(count(&log, "end simulate#3"), 1, "{log}");
    assert_eq!(count(&log, "end collect"), 1, "{log}");

    let clean = Ws::new("sharded.yaml");
    ok(clean.run(&["run"]));
    for s in ["source", "simulate", "collect"] {
        same_outputs(&ws, &clean, s);
    }
}

#[test]
fn sigterm_cancels_the_jobs_and_caches_nothing() {
    if !cluster("sigterm_cancels_the_jobs_and_caches_nothing") {
        return;
    }
    let ws = Ws::new("gated.yaml");
    std::fs::write(ws.gate(), b"").unwrap();
    let mut child = ws.spawn(&["run", "--executor", "slurm"], "term");
    wait_long("the gated job to start", || {
        std::fs::read_to_string(ws.log_path())
            .unwrap_or_default()
            .contains("start slow")
    });
    let job = std::fs::read_dir(ws.path().join("artifacts/slurm"))
        .unwrap()
        .filter_map(|e| e.ok())
        .find_map(|e| std::fs::read_to_string(e.path().join("job")).ok())
        .expect("a recorded job id");
    assert!(queued().contains(&job), "{job} queued");
    assert!(Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(143), "{}", ws.read("term.err"));
    assert!(
        ws.read("term.err").contains("cancelling 1 Slurm job(s)"),
        "{}",
        ws.read("term.err")
    );
    wait_long("the job to leave the queue", || !queued().contains(&job));
    assert_eq!(ws.objects(), 0, "nothing cached");
    let units: Vec<_> = std::fs::read_dir(ws.path().join("artifacts/slurm"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name() != "jobs")
        .collect();
    assert!(units.is_empty(), "unit directories removed: {units:?}");

    // The next run starts it afresh.
    std::fs::remove_file(ws.gate()).unwrap();
    let _ = ws.ran();
    ok(ws.run(&["run", "--executor", "slurm"]));
    assert_eq!(ws.ran(), ["slow"]);
}

#[test]
fn failing_job_shows_stderr_and_independent_units_complete() {
    if !cluster("failing_job_shows_stderr_and_independent_units_complete") {
        return;
    }
    let ws = Ws::new("failing.yaml");
    let r = ws.run(&["run", "--executor", "slurm"]);
    assert_eq!(r.code, 1, "{r:#?}");
    assert!(
        r.stderr.contains("boom: deliberate failure in bad"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("exit status 1"), "{}", r.stderr);
    assert_eq!(ws.ran(), sorted(&["good", "independent"]));
    assert!(r.stdout.contains("after-bad"), "{}", r.stdout);
    assert!(ws.path().join("artifacts/logs/bad.failed.log").is_file());
    // Nothing of the failed unit is cached: the next run tries it again.
    let r = ws.run(&["run", "--executor", "slurm"]);
    assert_eq!(r.code, 1);
    assert_eq!(ws.ran(), Vec::<String>::new());
    assert!(r.stderr.contains("boom"), "{}", r.stderr);
}

#[test]
fn job_cancelled_by_the_cluster_fails_the_unit() {
    if !cluster("job_cancelled_by_the_cluster_fails_the_unit") {
        return;
    }
    let ws = Ws::new("gated.yaml");
    std::fs::write(ws.gate(), b"").unwrap();
    let child = ws.spawn(&["run", "--executor", "slurm"], "cancelled");
    wait_long("the gated job to start", || {
        std::fs::read_to_string(ws.log_path())
            .unwrap_or_default()
            .contains("start slow")
    });
    let job = std::fs::read_dir(ws.path().join("artifacts/slurm"))
        .unwrap()
        .filter_map(|e| e.ok())
        .find_map(|e| std::fs::read_to_string(e.path().join("job")).ok())
        .expect("a recorded job id");
    assert!(Command::new("scancel")
        .arg(&job)
        .status()
        .unwrap()
        .success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = ws.read("cancelled.err");
    assert!(
        err.contains("ended without an exit status") && err.contains("CANCELLED"),
        "{err}"
    );
    assert_eq!(ws.objects(), 0, "nothing cached");
    let _ = std::fs::remove_file(ws.gate());
}

/// The real physics stages, tiny: sample-params, irregularity and the sharded simulate through
/// Slurm give byte-identical artifacts (and object ids) to the local executor.
#[test]
fn physics_stages_on_slurm_are_byte_identical_to_local() {
    if !cluster("physics_stages_on_slurm_are_byte_identical_to_local") {
        return;
    }
    const TINY: &[&str] = &[
        "sample-params.n_train=2",
        "sample-params.n_validation=1",
        "irregularity.length=120.0",
        "simulate.duration=0.2",
        "constants.system_values.n_f=200",
        "constants.system_values.n_m=100",
    ];
    let run = |ws: &Path, executor: &str| {
        let mut c = Command::new(pino_mbd_tests::bin("pipeline"));
        c.current_dir(ws)
            .arg("--bin-dir")
            .arg(pino_mbd_tests::pipeline_bin_dir("pipeline.yaml"))
            .env_remove("PINO_BIN_DIR");
        for s in TINY {
            c.arg("--set").arg(s);
        }
        let o = c
            .args(["run", "simulate", "--executor", executor])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{executor}: {}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    };
    let mk = || pino_mbd_tests::product_workspace("pipeline.yaml");
    let (a, b) = (mk(), mk());
    run(a.path(), "slurm");
    run(b.path(), "local");
    let files = |ws: &Path| -> Vec<PathBuf> {
        let mut v = Vec::new();
        for stage in ["sample-params", "irregularity", "simulate"] {
            let mut c = Command::new(pino_mbd_tests::bin("pipeline"));
            c.current_dir(ws)
                .arg("--bin-dir")
                .arg(pino_mbd_tests::pipeline_bin_dir("pipeline.yaml"))
                .env_remove("PINO_BIN_DIR");
            for s in TINY {
                c.arg("--set").arg(s);
            }
            let o = c.args(["show", stage]).output().unwrap();
            assert!(o.status.success());
            v.extend(
                String::from_utf8_lossy(&o.stdout)
                    .lines()
                    .map(PathBuf::from),
            );
        }
        v
    };
    let (fa, fb) = (files(a.path()), files(b.path()));
    assert!(
        fa.iter().any(|p| p.ends_with("simulation.parquet")),
        "{fa:?}"
    );
    assert_eq!(fa.len(), fb.len());
    for (x, y) in fa.iter().zip(&fb) {
        assert_eq!(
            x.strip_prefix(a.path()).unwrap(),
            y.strip_prefix(b.path()).unwrap()
        );
        assert!(
            std::fs::read(x).unwrap() == std::fs::read(y).unwrap(),
            "{x:?} differs"
        );
    }
    // The sharded simulate went to the cluster as one array job.
    let jobs: Vec<String> = std::fs::read_dir(a.path().join("artifacts/slurm/jobs"))
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("simulate-") && n.ends_with(".sh"))
        .collect();
    assert_eq!(jobs.len(), 1, "{jobs:?}");
}
