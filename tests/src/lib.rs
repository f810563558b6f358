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
