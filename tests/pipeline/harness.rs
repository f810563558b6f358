//! A scratch workspace with a fixture pipeline, and helpers to drive `pipeline` in it.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A temporary workspace holding `pipeline.yaml` copied from a fixture.
pub struct Ws {
    pub dir: pino_mbd_tests::TempWorkspace,
}

/// The result of one `pipeline` invocation.
#[derive(Debug)]
pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

pub fn fixture(name: &str) -> PathBuf {
    pino_mbd_tests::workspace_root()
        .join("tests/pipeline/fixtures")
        .join(name)
}

fn stage_bin_dir() -> PathBuf {
    Path::new(env!("CARGO_BIN_EXE_test-stage"))
        .parent()
        .unwrap()
        .to_path_buf()
}

impl From<Output> for Run {
    fn from(o: Output) -> Self {
        Run {
            code: o.status.code().unwrap_or(-1),
            stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        }
    }
}

impl Ws {
    pub fn new(fixture_name: &str) -> Ws {
        let ws = Ws {
            dir: pino_mbd_tests::TempWorkspace::new(),
        };
        std::fs::copy(fixture(fixture_name), ws.path().join("pipeline.yaml")).unwrap();
        ws
    }

    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    pub fn log_path(&self) -> PathBuf {
        self.path().join("stage-log.txt")
    }

    pub fn gate(&self) -> PathBuf {
        self.path().join("gate")
    }

    /// A `pipeline` command in this workspace with the test stage's bin dir.
    pub fn command(&self, args: &[&str]) -> Command {
        let mut c = Command::new(pino_mbd_tests::bin("pipeline"));
        c.current_dir(self.path())
            .arg("--bin-dir")
            .arg(stage_bin_dir())
            .args(args)
            .env_remove("PINO_BIN_DIR")
            .env("TEST_STAGE_LOG", self.log_path())
            .env("TEST_STAGE_GATE", self.gate())
            .stdin(Stdio::null());
        c
    }

    pub fn run(&self, args: &[&str]) -> Run {
        self.command(args).output().unwrap().into()
    }

    /// Starts `pipeline` in the background with stdout/stderr going to files `<tag>.out/.err`.
    pub fn spawn(&self, args: &[&str], tag: &str) -> Child {
        let out = std::fs::File::create(self.path().join(format!("{tag}.out"))).unwrap();
        let err = std::fs::File::create(self.path().join(format!("{tag}.err"))).unwrap();
        self.command(args).stdout(out).stderr(err).spawn().unwrap()
    }

    pub fn read(&self, rel: &str) -> String {
        std::fs::read_to_string(self.path().join(rel)).unwrap_or_default()
    }

    /// Units that ran to the end since the last call (from the stages' log), sorted; clears it.
    pub fn ran(&self) -> Vec<String> {
        let text = std::fs::read_to_string(self.log_path()).unwrap_or_default();
        let _ = std::fs::remove_file(self.log_path());
        let mut v: Vec<String> = text
            .lines()
            .filter_map(|l| l.strip_prefix("end "))
            .map(str::to_owned)
            .collect();
        v.sort();
        v
    }

    pub fn set_pipeline(&self, text: &str) {
        std::fs::write(self.path().join("pipeline.yaml"), text).unwrap();
    }

    pub fn pipeline_text(&self) -> String {
        self.read("pipeline.yaml")
    }

    /// `pipeline show STAGE` paths.
    pub fn show(&self, stage: &str) -> Vec<PathBuf> {
        let r = self.run(&["show", stage]);
        assert_eq!(r.code, 0, "show {stage}: {r:?}");
        r.stdout.lines().map(PathBuf::from).collect()
    }

    /// Contents of the stage's current output files, concatenated in order.
    pub fn output_of(&self, stage: &str) -> String {
        self.show(stage)
            .iter()
            .map(|p| std::fs::read_to_string(p).unwrap())
            .collect()
    }

    /// Number of committed objects in the store.
    pub fn objects(&self) -> usize {
        std::fs::read_dir(self.path().join("artifacts/objects")).map_or(0, |d| d.count())
    }
}

pub fn sorted(v: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = v.iter().map(|s| s.to_string()).collect();
    v.sort();
    v
}

/// Polls `cond` every 20 ms; panics with `what` after 30 s (a hang, not a timing assertion).
pub fn wait_until(what: &str, mut cond: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !cond() {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "timed out waiting for: {what}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Asserts success and returns the run.
pub fn ok(r: Run) -> Run {
    assert_eq!(r.code, 0, "expected success: {r:#?}");
    r
}
