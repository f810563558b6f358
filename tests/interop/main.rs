//! Interop: the artifacts of a small real pipeline run, read from Python with pyarrow, polars
//! and DuckDB by `tests/interop/check_parquet.py` (schema with units, provenance, the same
//! values in all three, one figure per file type recomputed independently, the README's
//! "Reading the outputs" examples run against the files).
//!
//! The run is the real `pipeline.yaml` with the [`TINY`] overrides, plus one `predict` output.
//! The workspace gets a `target/release` of links to this profile's binaries (checked fresh),
//! so the pipeline file's `bin_dir` (inside the workspace, as the orchestrator requires) and
//! the README's `target/release/pipeline show` work there unchanged.
//!
//! Needs Python 3 with the pinned readers: `PINO_PYTHON` when set, else the virtual environment
//! `scripts/test` installs them into (`target/test-env/python`) when it exists, else `python3`
//! (`pip install -r tests/interop/requirements.txt`); without them this test fails, it never
//! skips.

mod onnx;

use pino_mbd_tests::output_text;
use pino_mbd_tests::{bin, pipeline_bin_dir, product_workspace, workspace_root, TINY};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const INSTALL: &str = "scripts/test --install-only` (into target/test-env/python) or `pip \
     install -r tests/interop/requirements.txt";

/// The Python interpreter (`PINO_PYTHON`, else `scripts/test`'s virtual environment when it
/// exists, else `python3`), checked for the readers before any work is done.
fn python() -> String {
    python_with("pyarrow, polars, duckdb, pandas")
}

/// The interpreter as [`python`] finds it, checked for the Python `modules` (comma-separated)
/// before any work is done: without them the test fails, naming how to install them.
fn python_with(modules: &str) -> String {
    let venv = workspace_root().join("target/test-env/python/bin/python");
    let python = std::env::var("PINO_PYTHON").unwrap_or_else(|_| {
        if venv.is_file() {
            venv.display().to_string()
        } else {
            "python3".to_owned()
        }
    });
    let probe = Command::new(&python)
        .args(["-c", &format!("import {modules}")])
        .output();
    match probe {
        Err(e) => panic!(
            "the interop test needs Python 3 (`{python}`: {e}) with {modules}: install Python 3, \
             then run `{INSTALL}`, or set PINO_PYTHON"
        ),
        Ok(o) if !o.status.success() => panic!(
            "the interop test needs {modules} in `{python}`: run `{INSTALL}`, or set PINO_PYTHON \
             to an interpreter that has them\n{}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Ok(_) => python,
    }
}

fn pipeline(ws: &Path, args: &[&str]) -> Output {
    let mut cmd = Command::new(ws.join("target/release/pipeline"));
    cmd.current_dir(ws).env_remove("PINO_BIN_DIR");
    for s in TINY {
        cmd.arg("--set").arg(s);
    }
    cmd.args(args).output().expect("pipeline runs")
}

/// The directory of `file` among the outputs of `target`.
fn output_dir(ws: &Path, target: &str, file: &str) -> PathBuf {
    let o = pipeline(ws, &["show", target]);
    assert!(o.status.success(), "show {target}: {}", output_text(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let path = out
        .lines()
        .map(Path::new)
        .find(|p| p.file_name().is_some_and(|n| n == file))
        .unwrap_or_else(|| panic!("{target} has no {file}: {out}"));
    path.parent().expect("a file has a directory").to_owned()
}

#[test]
fn every_artifact_reads_the_same_in_pyarrow_polars_and_duckdb() {
    let python = python();
    let ws = product_workspace("pipeline.yaml");
    let ws = ws.path();
    bin("pipeline"); // a clear message when the binaries are not built or stale
    let release = ws.join("target/release");
    std::fs::create_dir_all(&release).unwrap();
    for entry in std::fs::read_dir(pipeline_bin_dir("pipeline.yaml")).unwrap() {
        let exe = entry.unwrap().path();
        if exe.is_file() && exe.extension().is_none() {
            std::os::unix::fs::symlink(&exe, release.join(exe.file_name().unwrap())).unwrap();
        }
    }

    let run = pipeline(ws, &["run"]);
    assert!(run.status.success(), "{}", output_text(&run));

    let model = output_dir(ws, "train[algorithm=1]", "model.safetensors");
    let predictions = ws.join("predictions.parquet");
    let o = Command::new(bin("predict"))
        .arg("--model")
        .arg(&model)
        .args(["--set", "k_s=4.0e5", "--seed", "7", "--out"])
        .arg(&predictions)
        .output()
        .unwrap();
    assert!(o.status.success(), "predict: {}", output_text(&o));

    // The binary each stage runs (`train-rates` runs `train`), from the pipeline file.
    let spec = orchestrator::spec::Pipeline::load(
        ws,
        &ws.join("pipeline.yaml"),
        &orchestrator::spec::LoadOptions::default(),
    )
    .unwrap();
    let commands: serde_json::Map<String, serde_json::Value> = spec
        .stages
        .iter()
        .map(|s| {
            let exe = Path::new(&s.cmd[0]).file_name().unwrap().to_string_lossy();
            (s.name.clone(), exe.into_owned().into())
        })
        .collect();
    let check = workspace_root().join("tests/interop/check_parquet.py");
    let o = Command::new(&python)
        .arg(&check)
        .arg(ws)
        .arg("--file")
        .arg(&predictions)
        .arg("--commands")
        .arg(serde_json::Value::Object(commands).to_string())
        .output()
        .unwrap();
    let report = output_text(&o);
    assert!(o.status.success(), "{}", report);
    println!("{report}");
}
