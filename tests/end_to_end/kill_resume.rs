//! Randomized kill-and-resume of the whole pipeline: `pipeline run` is killed with SIGKILL at
//! seeded pseudo-random moments (stages die with it), rerun to completion, and every final
//! artifact is compared byte for byte with an uninterrupted run. This is the README's promise
//! ("interrupt it at any moment; the next run keeps every finished stage, shard and epoch")
//! checked end to end, training checkpoints included.
//!
//! Bounded for CI: the TINY configuration with 6 epochs, [`TRIALS`] trials of one or two kills
//! each. The kill moments are fractions of the uninterrupted run's wall time, drawn from a
//! fixed seed; the assertion is on bytes only, never on time.

use super::{pipeline_cmd, show};
use pino_mbd_tests::output_text;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

const TRIALS: u64 = 3;
const SEED: u64 = 0x6b69_6c6c;
/// More epochs than the other end-to-end test, so kills land between checkpoints.
const EPOCHS: &str = "train.epochs=6";
/// What each run builds: [`STAGES`]' last stages and everything upstream (the studies after
/// them are checked for byte-identical outputs by the other end-to-end test).
const TARGETS: [&str; 2] = ["indices", "evaluate"];
/// Stages whose outputs are compared (everything [`TARGETS`] need).
const STAGES: [&str; 8] = [
    "sample-params",
    "irregularity",
    "simulate",
    "indices",
    "weights",
    "train",
    "calibrate",
    "evaluate",
];

/// SplitMix64: a fixed, dependency-free stream for the kill moments.
fn next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn workspace() -> pino_mbd_tests::TempWorkspace {
    pino_mbd_tests::product_workspace("pipeline.yaml")
}

/// Every output file of every stage: path relative to the workspace (identities included,
/// so equal keys mean equal inputs all the way up) -> bytes. `speed.csv` is a measurement of
/// the machine, the one output that is not a function of the inputs.
fn artifacts(ws: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut all = BTreeMap::new();
    for stage in STAGES {
        for f in show(ws, stage, &[EPOCHS]) {
            if f.file_name().is_some_and(|n| n == "speed.csv") {
                continue;
            }
            let rel = f.strip_prefix(ws).unwrap().to_string_lossy().into_owned();
            all.insert(rel, std::fs::read(&f).unwrap());
        }
    }
    all
}

#[test]
fn killed_at_random_moments_the_pipeline_ends_byte_identical() {
    let reference = workspace();
    let t0 = Instant::now();
    let o = pipeline_cmd(reference.path(), &[EPOCHS])
        .arg("run")
        .args(TARGETS)
        .args(["-j", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", output_text(&o));
    let wall = t0.elapsed();
    let expected = artifacts(reference.path());
    assert!(expected.keys().any(|k| k.ends_with("model.safetensors")));

    let mut rng = SEED;
    for trial in 0..TRIALS {
        let ws = workspace();
        let kills = 1 + next(&mut rng) % 2;
        let mut moments = Vec::new();
        for _ in 0..kills {
            // Between 5% and 95% of an uninterrupted run.
            let f = 0.05 + 0.9 * (next(&mut rng) % 1000) as f64 / 1000.0;
            let after = wall.mul_f64(f);
            let mut child = pipeline_cmd(ws.path(), &[EPOCHS])
                .arg("run")
                .args(TARGETS)
                .args(["-j", "2"])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::null())
                .spawn()
                .unwrap();
            let start = Instant::now();
            while start.elapsed() < after {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = child.kill(); // SIGKILL; a run that already ended is left as it is
            child.wait().unwrap();
            moments.push(format!("{f:.3}"));
        }
        let o = pipeline_cmd(ws.path(), &[EPOCHS])
            .arg("run")
            .args(TARGETS)
            .args(["-j", "2"])
            .output()
            .unwrap();
        assert!(o.status.success(), "trial {trial}: {}", output_text(&o));
        let got = artifacts(ws.path());
        assert_eq!(
            got.keys().collect::<Vec<_>>(),
            expected.keys().collect::<Vec<_>>(),
            "trial {trial} (killed at {moments:?} of {wall:?}): other artifacts"
        );
        for (k, v) in &expected {
            assert!(
                got[k] == *v,
                "trial {trial} (killed at {moments:?} of {wall:?}): {k} differs from the uninterrupted run"
            );
        }
    }
}
