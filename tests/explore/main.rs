//! The design explorer end to end: the real `pipeline` makes a small model of the default
//! pipeline (the TINY overrides of the end-to-end test), the real `explore` binary serves it,
//! and the tests talk to it as a script would (`api`: validation, the numbers against
//! `predict` and `simulate`, the solve gate, cancellation, host and token checks) and as a user
//! would, in a real browser (`browser`: Chromium driven by Playwright); `page_logic` runs the
//! page's own unit tests under Node.js's test runner.

use pino_data::{read_parquet, Column, Table};
use pino_explore::client::Client;
use pino_mbd_tests::{output_text, TempWorkspace, TINY};
use std::io::BufRead;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::Duration;

mod api;
mod browser;
mod page_logic;
mod serving;
mod spatial;
mod studies;

/// The shared workspace's targets: every stage but the studies and the export (the explorer
/// serves the surrogate, each member with its calibration, and shows Table 4 and the indices;
/// the studies are left unrun).
const SERVED_STAGES: &[&str] = &["evaluate", "indices"];

/// The stage whose output `explore` serves in the default pipeline: its surrogate.
pub const SERVED_SURROGATE: &str = "surrogate";

/// A workspace in which the default pipeline ran with the TINY overrides and then `extra`.
pub struct Trained {
    /// The workspace.
    ws: Workspace,
    /// The `--set` overrides of the run.
    pub sets: Vec<String>,
}

/// Where a [`Trained`] lives: its own temporary directory, or the shared one under `target/`
/// (a static is never dropped, so that one is wiped when the next test process makes it).
enum Workspace {
    Temporary(TempWorkspace),
    Shared(PathBuf),
}

impl Trained {
    /// The workspace the tests that need no overrides of their own share (they only read
    /// it): the pipeline up to [`SERVED_STAGES`] with the TINY overrides, run once per test
    /// process in `target/explore-shared`.
    pub fn shared() -> &'static Self {
        static SHARED: OnceLock<Trained> = OnceLock::new();
        SHARED.get_or_init(|| {
            let dir = pino_mbd_tests::workspace_root()
                .join("target")
                .join("explore-shared");
            if dir.exists() {
                std::fs::remove_dir_all(&dir).expect("remove the last shared workspace");
            }
            std::fs::create_dir_all(&dir).expect("target/explore-shared");
            std::fs::copy(
                pino_mbd_tests::workspace_root().join("pipeline.yaml"),
                dir.join("pipeline.yaml"),
            )
            .expect("copy the pipeline file");
            pino_mbd_tests::copy_systems(&dir);
            Self::run(Workspace::Shared(dir), &[], SERVED_STAGES)
        })
    }

    /// Runs the pipeline's `targets` and what they read (all of it when `targets` is empty)
    /// with the TINY overrides and `extra`, in a fresh copy of the product.
    pub fn up_to(extra: &[&str], targets: &[&str]) -> Self {
        let ws = pino_mbd_tests::product_workspace("pipeline.yaml");
        Self::run(Workspace::Temporary(ws), extra, targets)
    }

    /// Runs `targets` of the job `file` (a file of `configs/`) and what they read with the
    /// TINY overrides and `extra`, in a fresh copy of the product with the job as its
    /// `pipeline.yaml`.
    pub fn job(file: &str, extra: &[&str], targets: &[&str]) -> Self {
        let ws = TempWorkspace::new();
        let text = std::fs::read_to_string(pino_mbd_tests::workspace_root().join(file))
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        // The file becomes the workspace's own, as `pipeline.yaml` is: its `workspace:` line
        // dropped, its binaries where the root pipeline's are (`--bin-dir` names them).
        let text: String = text
            .lines()
            .filter(|l| !l.starts_with("workspace:"))
            .map(|l| match l.starts_with("bin_dir:") {
                true => "bin_dir: target/release\n".to_owned(),
                false => format!("{l}\n"),
            })
            .collect();
        std::fs::write(ws.path().join("pipeline.yaml"), text).expect("write the job file");
        pino_mbd_tests::copy_systems(ws.path());
        Self::run(Workspace::Temporary(ws), extra, targets)
    }

    fn run(ws: Workspace, extra: &[&str], targets: &[&str]) -> Self {
        let sets: Vec<String> = TINY.iter().chain(extra).map(|s| s.to_string()).collect();
        let args: Vec<&str> = ["run", "-j", "2"].iter().chain(targets).copied().collect();
        let trained = Self { ws, sets };
        let o = self::pipeline(trained.path(), &trained.sets, &args);
        assert!(o.status.success(), "{}", output_text(&o));
        trained
    }

    /// The workspace's directory.
    pub fn path(&self) -> &Path {
        match &self.ws {
            Workspace::Temporary(t) => t.path(),
            Workspace::Shared(p) => p,
        }
    }

    /// The files of `stage`'s current output.
    pub fn show(&self, stage: &str) -> Vec<PathBuf> {
        let o = pipeline(self.path(), &self.sets, &["show", stage]);
        assert!(o.status.success(), "{}", output_text(&o));
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(PathBuf::from)
            .collect()
    }

    /// The one file named `name` of `stage`'s output.
    pub fn file(&self, stage: &str, name: &str) -> PathBuf {
        let files = self.show(stage);
        files
            .iter()
            .find(|p| p.file_name().is_some_and(|n| n == name))
            .unwrap_or_else(|| panic!("{stage} wrote no {name}: {files:?}"))
            .clone()
    }

    /// `predict --surrogate surrogate --params params` on the track of test sample
    /// `sample_id` (this workspace's irregularity), its `--out` table (written under `dir`).
    pub fn predict(&self, surrogate: &Path, params: &Path, sample_id: i64, dir: &Path) -> Table {
        let profile = self.file("irregularity", "irregularity.parquet");
        let stem = params.file_stem().unwrap().to_string_lossy();
        let to = dir.join(format!("{stem}-predicted.parquet"));
        let o = Command::new(pino_mbd_tests::bin("predict"))
            .arg("--surrogate")
            .arg(surrogate)
            .arg("--params")
            .arg(params)
            .arg("--profile")
            .arg(&profile)
            .arg("--profile-id")
            .arg(sample_id.to_string())
            .arg("--out")
            .arg(&to)
            .output()
            .expect("predict runs");
        assert!(o.status.success(), "predict: {}", output_text(&o));
        read_parquet(&to, None).unwrap()
    }

    /// The rows of `sample_id` from the `simulate` stage's shards (every f64 column).
    pub fn sample_rows(&self, sample_id: i64) -> Table {
        let files: Vec<PathBuf> = self
            .show("simulate")
            .into_iter()
            .filter(|p| p.file_name().is_some_and(|n| n == "simulation.parquet"))
            .collect();
        for f in &files {
            let t = read_parquet(f, None).unwrap();
            let ids = t.i64("sample_id").unwrap();
            if !ids.contains(&sample_id) {
                continue;
            }
            let rows: Vec<usize> = (0..ids.len()).filter(|&i| ids[i] == sample_id).collect();
            let mut out = Table::with_origin(f);
            for name in t.names() {
                if let Ok(col) = t.f64(name) {
                    let v: Vec<f64> = rows.iter().map(|&i| col[i]).collect();
                    out.push(name, Column::F64(v)).unwrap();
                }
            }
            return out;
        }
        panic!("no simulate shard holds sample {sample_id}: {files:?}");
    }

    /// Starts `explore` on this workspace's served surrogate ([`SERVED_SURROGATE`]), on a free loopback port unless
    /// `extra` binds elsewhere.
    pub fn serve(&self, extra: &[&str]) -> Served {
        let mut cmd = Command::new(pino_mbd_tests::bin("explore"));
        cmd.arg("-C")
            .arg(self.path())
            .arg("--bin-dir")
            .arg(pino_mbd_tests::pipeline_bin_dir("pipeline.yaml"))
            .env_remove("PINO_BIN_DIR");
        for s in &self.sets {
            cmd.arg("--set").arg(s);
        }
        if !extra.contains(&"--bind") {
            cmd.args(["--bind", "127.0.0.1:0"]);
        }
        cmd.args(extra);
        Served::start(cmd)
    }
}

fn pipeline(ws: &Path, sets: &[String], args: &[&str]) -> std::process::Output {
    let mut cmd = Command::new(pino_mbd_tests::bin("pipeline"));
    cmd.current_dir(ws)
        .arg("--bin-dir")
        .arg(pino_mbd_tests::pipeline_bin_dir("pipeline.yaml"))
        .env_remove("PINO_BIN_DIR");
    for s in sets {
        cmd.arg("--set").arg(s);
    }
    cmd.args(args).output().expect("pipeline runs")
}

/// A running `explore`, killed on drop.
pub struct Served {
    child: Child,
    /// Its address.
    pub addr: SocketAddr,
    /// The URL it printed.
    pub url: String,
}

impl Served {
    /// Spawns `cmd` and waits (up to two minutes) for the URL line.
    pub fn start(mut cmd: Command) -> Self {
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("explore starts");
        let stdout = child.stdout.take().expect("piped");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(stdout)
                .lines()
                .map_while(Result::ok)
            {
                let _ = tx.send(line);
            }
        });
        let line = match rx.recv_timeout(Duration::from_secs(120)) {
            Ok(line) => line,
            Err(_) => {
                let _ = child.kill();
                panic!(
                    "explore printed no URL: {:?}",
                    child.wait_with_output().ok()
                )
            }
        };
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .unwrap_or_else(|| panic!("no URL in {line:?}"))
            .to_owned();
        let host = url
            .trim_start_matches("http://")
            .split('/')
            .next()
            .unwrap_or_default();
        // An IPv4-mapped IPv6 address is reached at the IPv4 address it maps.
        let addr: SocketAddr = std::net::ToSocketAddrs::to_socket_addrs(host)
            .unwrap_or_else(|e| panic!("{host}: {e}"))
            .map(|a| match a {
                SocketAddr::V6(v6) => v6
                    .ip()
                    .to_ipv4_mapped()
                    .map_or(a, |ip| SocketAddr::new(ip.into(), v6.port())),
                v4 => v4,
            })
            .find(SocketAddr::is_ipv4)
            .unwrap_or_else(|| panic!("{host}: no IPv4 address"));
        Self { child, addr, url }
    }

    /// A client of this server.
    pub fn client(&self) -> Client {
        Client::new(self.addr)
    }

    /// Whether the process is still running.
    pub fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
