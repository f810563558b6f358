//! Shared helpers for the end-to-end tests: locating the workspace's built binaries and
//! making scratch workspaces.
//!
//! The binaries must be built first (`cargo build --workspace --bins`, which the README's
//! test command does); tests use the ones of the same profile as themselves. Because `cargo
//! test` does not rebuild the binaries of other packages, every binary a test runs is checked
//! to be newer than each of its sources in the workspace ([`bin`], [`pipeline_bin_dir`]): the
//! list is Cargo's own dep-info file beside the binary (`target/<profile>/<name>.d`, every
//! source file rustc read for it, dependencies included), so editing a stage or any crate it
//! uses and forgetting the build fails the test with the command to run, instead of testing
//! the old code. Sources outside the workspace (crates.io) only change with `Cargo.lock`,
//! which Cargo tracks by version, not by time, so they are not compared.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::SystemTime;

/// The directory holding this profile's binaries (`target/debug` or `target/release`).
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("current test executable");
    // target/<profile>/deps/<test-binary>
    exe.parent()
        .and_then(Path::parent)
        .expect("test binary lives in target/<profile>/deps")
        .to_path_buf()
}

/// The command that brings the binaries up to date.
pub const BUILD: &str = "cargo build --workspace --bins";

/// Path of the workspace binary `name`; panics with the command to run if it is missing or
/// older than one of its sources ([`check_fresh`]).
pub fn bin(name: &str) -> PathBuf {
    let p = bin_dir().join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        p.is_file(),
        "binary {} is missing: run `{BUILD}` before the tests",
        p.display()
    );
    static CHECKED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    let mut checked = CHECKED.lock().unwrap_or_else(|e| e.into_inner());
    if !checked.contains(&p) {
        if let Err(why) = check_fresh(&p, &workspace_root()) {
            panic!("{why}");
        }
        checked.push(p.clone());
    }
    p
}

/// The source files listed in a Makefile-style dep-info text (`target: dep dep ...`, spaces
/// in names escaped as `\ `, lines continued with a trailing `\`).
pub fn dep_info_sources(text: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for rule in text.replace("\\\n", " ").lines() {
        // The target ends at the first `: ` (a colon inside a name would be escaped).
        let Some((_, deps)) = rule.split_once(": ") else {
            continue;
        };
        let mut cur = String::new();
        let mut chars = deps.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '\\' if chars.peek() == Some(&' ') => {
                    cur.push(' ');
                    chars.next();
                }
                ' ' | '\t' => {
                    if !cur.is_empty() {
                        out.push(PathBuf::from(std::mem::take(&mut cur)));
                    }
                }
                c => cur.push(c),
            }
        }
        if !cur.is_empty() {
            out.push(PathBuf::from(cur));
        }
    }
    out
}

fn mtime(p: &Path) -> std::io::Result<SystemTime> {
    std::fs::metadata(p)?.modified()
}

/// Checks that the binary `exe` is newer than every source it was built from that lies under
/// `root` (outside `root/target`), reading the list from Cargo's dep-info file `exe.d`. The
/// error names the binary, the newest such source and the command to run.
pub fn check_fresh(exe: &Path, root: &Path) -> Result<(), String> {
    let name = exe.file_name().unwrap_or_default().to_string_lossy();
    let dep_info = exe.with_file_name(format!("{name}.d"));
    let built = mtime(exe).map_err(|e| format!("binary {}: {e}", exe.display()))?;
    let text = std::fs::read_to_string(&dep_info).map_err(|e| {
        format!(
            "binary {} has no readable dep-info file {} ({e}), so its freshness cannot be \
             checked: run `{BUILD}`",
            exe.display(),
            dep_info.display()
        )
    })?;
    let target = root.join("target");
    let mut newest: Option<(SystemTime, PathBuf)> = None;
    for src in dep_info_sources(&text) {
        let src = if src.is_absolute() {
            src
        } else {
            root.join(src)
        };
        if !src.starts_with(root) || src.starts_with(&target) {
            continue;
        }
        // A source that no longer exists changed too (a module was deleted or renamed).
        let changed = mtime(&src).unwrap_or(SystemTime::now());
        if changed > built && newest.as_ref().is_none_or(|(t, _)| changed > *t) {
            newest = Some((changed, src));
        }
    }
    match newest {
        None => Ok(()),
        Some((_, src)) => Err(format!(
            "binary {} is older than its source {}: run `{BUILD}` (the tests run the built \
             binaries, and `cargo test` does not rebuild them)",
            exe.display(),
            src.display()
        )),
    }
}

/// The binary directory for `pipeline --bin-dir`, after checking with [`bin`] that the binary
/// of every stage of the workspace's pipeline file `file` (each bare `cmd[0]`) is there and
/// fresh.
pub fn pipeline_bin_dir(file: &str) -> PathBuf {
    let root = workspace_root();
    let p = orchestrator::spec::Pipeline::load(
        &root,
        &root.join(file),
        &orchestrator::spec::LoadOptions {
            bin_dir: Some(bin_dir()),
            sets: Vec::new(),
        },
    )
    .unwrap_or_else(|e| panic!("{file}: {e}"));
    for stage in &p.stages {
        let exe = &stage.cmd[0];
        if !exe.contains('/') {
            bin(exe);
        }
    }
    bin_dir()
}

/// A temporary workspace directory for `pipeline` runs, removed on drop even when it holds a
/// store: committed objects are sealed (read-only directories), which a plain
/// [`tempfile::TempDir`] cannot remove unless the tests run as root.
pub struct TempWorkspace(tempfile::TempDir);

impl TempWorkspace {
    /// A new empty directory under the system's temporary directory.
    pub fn new() -> Self {
        Self(tempfile::tempdir().expect("temporary directory"))
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        self.0.path()
    }
}

impl Default for TempWorkspace {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for TempWorkspace {
    fn drop(&mut self) {
        let _ = orchestrator::store::remove_tree(self.0.path());
    }
}

/// Runs the built binary `binary` with `args` to completion.
pub fn run_bin(binary: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new(bin(binary))
        .args(args)
        .output()
        .expect("binary runs")
}

/// A finished command's exit code, stdout and stderr, for assertion messages.
pub fn output_text(o: &std::process::Output) -> String {
    format!(
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Root of the source workspace (for fixtures).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ lives in the workspace root")
        .to_path_buf()
}

/// The definition of `stage` in the workspace's pipeline file `file` (relative to the
/// workspace root), loaded by the orchestrator's own loader: `${constants.NAME}` references
/// substituted in its command and parameters.
pub fn stage_spec(file: &str, stage: &str) -> orchestrator::spec::Stage {
    shipped_pipeline(file)
        .stage(stage)
        .unwrap_or_else(|| panic!("{file}: no stage `{stage}`"))
        .clone()
}

/// The shipped pipeline file `file` (relative to the workspace root), loaded as `pipeline`
/// loads it with no `--set`.
pub fn shipped_pipeline(file: &str) -> orchestrator::spec::Pipeline {
    let root = workspace_root();
    orchestrator::spec::Pipeline::load(
        &root,
        &root.join(file),
        &orchestrator::spec::LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{file}: {e}"))
}

/// The resolved parameters of `stage` (first matrix expansion) in the pipeline file `file`, as
/// the orchestrator hands them to the stage.
pub fn stage_params(file: &str, stage: &str) -> serde_json::Value {
    stage_spec(file, stage).expansions[0].params.clone()
}

/// The resolved command of `stage` in the pipeline file `file`: `cmd[0]` as written, then its
/// arguments (the description path).
pub fn stage_cmd(file: &str, stage: &str) -> Vec<String> {
    stage_spec(file, stage).cmd
}

/// Path of the shipped system description `systems/<name>.yaml` (`vtcd`, `quarter-car`,
/// `bridge`).
pub fn system_path(name: &str) -> PathBuf {
    workspace_root()
        .join("systems")
        .join(format!("{name}.yaml"))
}

/// The shipped description `name` as a run records it (`system.json`), with the overrides
/// `values`, and compiled; panics with every problem of the description.
pub fn system(
    name: &str,
    values: &[(&str, mbd_system::Override)],
) -> (mbd_system::SystemSource, mbd_system::System) {
    let source = mbd_system::SystemSource::read(
        &system_path(name),
        values
            .iter()
            .map(|(n, v)| ((*n).to_owned(), v.clone()))
            .collect(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let system = source.compile().unwrap_or_else(|e| panic!("{e}"));
    (source, system)
}

/// Copies the shipped descriptions (`systems/*.yaml`) into the workspace `ws`: the pipeline
/// files name their description relative to the workspace (`constants.system`).
pub fn copy_systems(ws: &Path) {
    let to = ws.join("systems");
    std::fs::create_dir_all(&to).expect("systems directory");
    for entry in std::fs::read_dir(workspace_root().join("systems")).expect("systems/") {
        let p = entry.expect("systems/ entry").path();
        if p.extension().is_some_and(|e| e == "yaml") {
            std::fs::copy(&p, to.join(p.file_name().expect("a file name")))
                .expect("copy a description");
        }
    }
}

/// A scratch workspace holding the workspace's pipeline file `file` as `pipeline.yaml` and
/// the shipped descriptions under `systems/`.
pub fn product_workspace(file: &str) -> TempWorkspace {
    let ws = TempWorkspace::new();
    std::fs::copy(workspace_root().join(file), ws.path().join("pipeline.yaml"))
        .expect("copy the pipeline file");
    copy_systems(ws.path());
    ws
}

/// Writes the context file `<dir>/<name>.json` of a stage run by hand (as the orchestrator
/// would: `params`, `inputs` as JSON, an empty output directory `<dir>/<name>-out`), with
/// `check` set for check mode. Returns (context path, output directory).
pub fn stage_context(
    dir: &Path,
    name: &str,
    params: serde_json::Value,
    inputs: serde_json::Value,
    check: bool,
) -> (PathBuf, PathBuf) {
    let out = dir.join(format!("{name}-out"));
    std::fs::create_dir_all(&out).expect("output directory");
    let mut ctx = serde_json::json!({
        "protocol": 1, "stage": name, "params": params, "inputs": inputs, "output": out,
    });
    if check {
        ctx["check"] = serde_json::Value::Bool(true);
    }
    let path = dir.join(format!("{name}.json"));
    std::fs::write(&path, serde_json::to_string(&ctx).expect("JSON")).expect("context file");
    (path, out)
}

/// Runs the stage binary `exe` by hand: `exe [DESCRIPTION] --context CTX` with
/// `RAYON_NUM_THREADS=threads`.
pub fn run_stage(
    exe: &str,
    description: Option<&Path>,
    ctx: &Path,
    threads: usize,
) -> std::process::Output {
    let mut cmd = std::process::Command::new(bin(exe));
    if let Some(d) = description {
        cmd.arg(d);
    }
    cmd.arg("--context")
        .arg(ctx)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .expect("the stage binary runs")
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
    "sample-params.n_calibration=10",
    "irregularity.length=120.0",
    "simulate.duration=0.5",
    "constants.system_values.n_f=200",
    "constants.system_values.n_m=100",
    "train.epochs=2",
    "train.width=8",
    "train.modes=8",
    "train.projection_width=16",
    "train.batch_size=2",
    // Two epochs of a width-8 network: the default's 3e-3 (chosen for 18 epochs of the real
    // network) leaves it too rough for the optimisation study to find a feasible design.
    "train.learning_rate=1.0e-3",
    "evaluate.plot_samples=1",
    "study.bootstrap=100",
    // Judged on the 90 % upper ends, every candidate of the car-body optimisation (on the
    // 2-epoch rate-output model, whose accelerations are noise) breaks a Sperling limit; on
    // the median's a feasible optimum exists and the optimum's contract is checked.
    "study.coverage=0.5",
];

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn dep_info_lists_every_source_with_escaped_spaces() {
        let text = "/t/debug/x: /w/src/main.rs /w/a\\ b.rs \\\n /w/c.rs\n\n/w/src/main.rs:\n";
        assert_eq!(
            dep_info_sources(text),
            ["/w/src/main.rs", "/w/a b.rs", "/w/c.rs"].map(PathBuf::from)
        );
    }

    /// A binary older than a source of its (after an edit without a build) is refused with the
    /// command that fixes it; sources outside the workspace or under `target/` do not count.
    #[test]
    fn a_binary_older_than_its_sources_is_stale() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("ws");
        std::fs::create_dir_all(root.join("crates/a/src")).unwrap();
        std::fs::create_dir_all(root.join("target/debug")).unwrap();
        let src = root.join("crates/a/src/lib.rs");
        let generated = root.join("target/debug/gen.rs");
        let foreign = dir.path().join("registry.rs");
        let exe = root.join("target/debug/stage");
        for f in [&src, &generated, &foreign, &exe] {
            std::fs::write(f, b"x").unwrap();
        }
        std::fs::write(
            root.join("target/debug/stage.d"),
            format!(
                "{}: {} {} {}\n",
                exe.display(),
                src.display(),
                generated.display(),
                foreign.display()
            ),
        )
        .unwrap();
        let set = |p: &Path, t: SystemTime| {
            std::fs::File::options()
                .write(true)
                .open(p)
                .unwrap()
                .set_modified(t)
                .unwrap()
        };
        let t0 = SystemTime::now() - Duration::from_secs(86_400);
        set(&exe, t0);
        set(&src, t0 - Duration::from_secs(5));
        // Newer, but not the workspace's own sources.
        set(&generated, t0 + Duration::from_secs(5));
        set(&foreign, t0 + Duration::from_secs(5));
        check_fresh(&exe, &root).unwrap();

        set(&src, t0 + Duration::from_secs(1));
        let e = check_fresh(&exe, &root).unwrap_err();
        assert!(
            e.contains("older than its source")
                && e.contains("crates/a/src/lib.rs")
                && e.contains(BUILD),
            "{e}"
        );
        // A deleted source is a change too.
        std::fs::remove_file(&src).unwrap();
        assert!(check_fresh(&exe, &root).is_err());
        // No dep-info: cannot be checked, which is an error with the same remedy.
        std::fs::remove_file(root.join("target/debug/stage.d")).unwrap();
        let e = check_fresh(&exe, &root).unwrap_err();
        assert!(e.contains("dep-info") && e.contains(BUILD), "{e}");
    }

    /// The binaries of this very build pass (the README's command built them first).
    #[test]
    fn the_binaries_of_this_build_are_fresh() {
        bin("pipeline");
        pipeline_bin_dir("pipeline.yaml");
    }
}
