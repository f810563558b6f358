//! Progress of running units, seen by `pipeline status` from another process: shown while
//! the run is live, gone when the unit ends, and never claimed after the run was killed.

use crate::harness::{ok, Ws};
use std::path::PathBuf;
use std::time::{Duration, Instant};

const UNIT: &str = "train[algorithm=5]";

/// Polls `cond` every 50 ms; panics with `what` after 60 s (a hang, not a timing assertion).
fn wait_for(what: &str, mut cond: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !cond() {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "timed out waiting for: {what}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The STATE and REASON columns of `unit` in `pipeline status`.
fn state_of(ws: &Ws, unit: &str) -> (String, String) {
    let st = ok(ws.run(&["status"])).stdout;
    let line = st
        .lines()
        .find(|l| l.split_whitespace().next() == Some(unit))
        .unwrap_or_else(|| panic!("no line for {unit} in:\n{st}"));
    let rest = line[unit.len()..].trim_start();
    // States are one word except `never run`.
    let (state, reason) = if let Some(r) = rest.strip_prefix("never run") {
        ("never run", r)
    } else {
        rest.split_once(char::is_whitespace).unwrap_or((rest, ""))
    };
    (state.to_owned(), reason.trim().to_owned())
}

fn records(ws: &Ws) -> Vec<PathBuf> {
    std::fs::read_dir(ws.path().join("artifacts/running"))
        .map(|rd| rd.flatten().map(|e| e.path()).collect())
        .unwrap_or_default()
}

/// Starts `pipeline run` with the gate closed and waits until status shows the unit held
/// at 4 of 10.
fn start_held_run(ws: &Ws, tag: &str) -> std::process::Child {
    std::fs::write(ws.gate(), b"").unwrap();
    let child = ws.spawn(&["run"], tag);
    wait_for("status shows the unit running at 4/10", || {
        state_of(ws, UNIT) == ("running".into(), "4/10 (held here)".into())
    });
    child
}

#[test]
fn status_shows_progress_of_a_running_unit_until_it_ends() {
    let ws = Ws::new("progress.yaml");
    assert_eq!(state_of(&ws, UNIT).0, "never run");
    let mut run = start_held_run(&ws, "held");
    let files = records(&ws);
    assert_eq!(files.len(), 1, "{files:?}");
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&files[0]).unwrap()).unwrap();
    assert_eq!(record["unit"], UNIT);
    assert_eq!(record["stage"], "train");
    assert_eq!(record["pid"], run.id());
    assert_eq!(
        (record["done"].as_u64(), record["total"].as_u64()),
        (Some(4), Some(10))
    );
    assert!(ok(ws.run(&["status"])).stdout.contains("1 running"));

    std::fs::remove_file(ws.gate()).unwrap();
    assert!(run.wait().unwrap().success(), "{}", ws.read("held.err"));
    assert_eq!(state_of(&ws, UNIT), ("fresh".into(), String::new()));
    assert!(records(&ws).is_empty(), "{:?}", records(&ws));
}

#[test]
fn a_killed_run_is_not_reported_running() {
    let ws = Ws::new("progress.yaml");
    let mut run = start_held_run(&ws, "killed");
    run.kill().unwrap(); // SIGKILL: no cleanup runs
    run.wait().unwrap();
    // The record stays behind; the run lock, released by the kernel, says it is dead.
    assert_eq!(records(&ws).len(), 1);
    assert_eq!(state_of(&ws, UNIT).0, "never run");

    // The next run clears the leftovers and finishes the unit.
    std::fs::remove_file(ws.gate()).unwrap();
    ok(ws.run(&["run"]));
    assert_eq!(state_of(&ws, UNIT).0, "fresh");
    assert!(records(&ws).is_empty(), "{:?}", records(&ws));
}
