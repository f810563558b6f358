//! Shared helpers for the end-to-end tests: locating the workspace's built binaries and
//! making scratch workspaces.
//!
//! The binaries must be built first (`cargo build --workspace --bins`, which the README's
//! test command does); tests use the ones of the same profile as themselves.

use std::path::{Path, PathBuf};

/// The directory holding this profile's binaries (`target/debug` or `target/release`).
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("current test executable");
    // target/<profile>/deps/<test-binary>
    exe.parent()
        .and_then(Path::parent)
        .expect("test binary lives in target/<profile>/deps")
        .to_path_buf()
}

/// Path of the workspace binary `name`; panics with the command to run if it is missing.
pub fn bin(name: &str) -> PathBuf {
    let p = bin_dir().join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        p.is_file(),
        "binary {} is missing: run `cargo build --workspace --bins` before the tests",
        p.display()
    );
    p
}

/// Root of the source workspace (for fixtures).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ lives in the workspace root")
        .to_path_buf()
}

/// The resolved parameters of `stage` (first matrix expansion) in the workspace's pipeline
/// file `file` (relative to the workspace root), as the orchestrator hands them to the stage:
/// `${constants.NAME}` references substituted.
pub fn stage_params(file: &str, stage: &str) -> serde_json::Value {
    let root = workspace_root();
    let p = orchestrator::spec::Pipeline::load(
        &root,
        &root.join(file),
        &orchestrator::spec::LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{file}: {e}"));
    p.stage(stage)
        .unwrap_or_else(|| panic!("{file}: no stage `{stage}`"))
        .expansions[0]
        .params
        .clone()
}

/// `--set` overrides of the real `pipeline.yaml` that keep the real physics and wiring but
/// cost seconds in the dev profile (the end-to-end and interop tests).
/// The track is 200 fasteners (120 m): the front wheel starts at most 20 + 2 (1.2 * 9 + 1.2 *
/// 1.2) = 44.5 m and travels at most 350/3.6 * 0.5 = 48.6 m, so it ends at 93 m, inside both
/// the rail and the 120 m irregularity profile.
pub const TINY: &[&str] = &[
    "sample-params.n_train=4",
    "sample-params.n_validation=2",
    "sample-params.n_test=1",
    "irregularity.length=120.0",
    "simulate.duration=0.5",
    "simulate.n_f=200",
    "simulate.n_m=100",
    "train.epochs=2",
    "train.width=8",
    "train.modes=8",
    "train.projection_width=16",
    "train.batch_size=2",
    "evaluate.plot_samples=1",
];
