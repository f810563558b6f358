//! `status`, `dag` and `show` output.

use crate::harness::{ok, Run, Ws};

#[test]
fn status_dag_and_show() {
    let ws = Ws::new("basic.yaml");
    let st = ok(ws.run(&["status"]));
    assert!(st.stdout.contains("prepare    never run"), "{}", st.stdout);
    assert!(st.stdout.contains("4 never run"), "{}", st.stdout);
    assert!(
        !ws.path().join("artifacts").exists(),
        "status writes nothing"
    );

    let dag = ok(ws.run(&["dag"])).stdout;
    assert_eq!(
        dag,
        "prepare\nside\ntransform <- data: prepare\nreport <- data: transform, raw: prepare\n"
    );
    let dot = ok(ws.run(&["dag", "--dot"])).stdout;
    assert!(dot.starts_with("digraph pipeline {"), "{dot}");
    assert!(
        dot.contains("\"transform\" -> \"report\" [label=\"data\"];"),
        "{dot}"
    );
    assert!(
        dot.contains("\"prepare\" -> \"report\" [label=\"raw\"];"),
        "{dot}"
    );

    let r = ws.run(&["show", "report"]);
    assert_eq!(r.code, 1, "nothing to show before a run: {r:?}");
    assert!(r.stderr.contains("no outputs yet"), "{}", r.stderr);

    ok(ws.run(&["run"]));
    let st = ok(ws.run(&["status"]));
    assert!(st.stdout.contains("4 fresh"), "{}", st.stdout);
    let paths = ws.show("report");
    assert_eq!(paths.len(), 1);
    assert!(
        paths[0].is_absolute() && paths[0].ends_with("out/out.txt"),
        "{paths:?}"
    );
    assert!(std::fs::read_to_string(&paths[0])
        .unwrap()
        .starts_with("stage report\n"));
    let r = ws.run(&["show", "nope"]);
    assert_eq!(r.code, 2);
    assert!(r.stderr.contains("unknown stage `nope`"), "{}", r.stderr);
}

/// A pipeline file named from another directory runs in its own workspace: the file's
/// directory, or the `workspace:` it declares (relative to it); `show` before a run names the
/// workspace it looked in and the command that fills it.
#[test]
fn a_pipeline_file_named_from_elsewhere_runs_in_its_own_workspace() {
    let ws = Ws::new("basic.yaml");
    let elsewhere = pino_mbd_tests::TempWorkspace::new();
    let from = |args: &[&str]| -> Run {
        let mut c = ws.command(args);
        c.current_dir(elsewhere.path());
        c.output().unwrap().into()
    };
    let file = ws.path().join("pipeline.yaml");
    let file = file.to_str().unwrap();
    let r = from(&["-f", file, "show", "report"]);
    assert_eq!(r.code, 1, "{r:?}");
    let hint = format!(
        "stage `report` has no outputs yet in the workspace {0}: `pipeline -C {0} -f pipeline.yaml run report` makes them",
        ws.path().display()
    );
    assert!(r.stderr.contains(&hint), "{}", r.stderr);
    ok(from(&["-f", file, "run", "report"]));
    assert_eq!(ws.ran(), ["prepare", "report", "transform"]);
    assert!(ws.path().join("artifacts").is_dir());
    assert!(!elsewhere.path().join("artifacts").exists());
    assert_eq!(
        ok(from(&["-f", file, "show", "report"]))
            .stdout
            .lines()
            .count(),
        1
    );

    // A file one directory down that declares the workspace above: the same store, so the
    // same stages are found done (nothing runs again).
    std::fs::create_dir(ws.path().join("configs")).unwrap();
    let nested = ws.path().join("configs/p.yaml");
    std::fs::write(&nested, format!("workspace: ..\n{}", ws.pipeline_text())).unwrap();
    let nested = nested.to_str().unwrap();
    ok(from(&["-f", nested, "run", "report"]));
    assert!(ws.ran().is_empty(), "the nested file reruns nothing");
    let shown = ok(from(&["-f", nested, "show", "report"])).stdout;
    assert!(
        shown.starts_with(&ws.path().join("artifacts").display().to_string()),
        "{shown}"
    );
    // The workspace given on the command line wins.
    let r = from(&[
        "-C",
        ws.path().to_str().unwrap(),
        "-f",
        "configs/p.yaml",
        "status",
    ]);
    let status = ok(r).stdout;
    assert!(status.contains("3 fresh, 1 never run"), "{status}");

    // A workspace that does not contain the file is refused at its line.
    std::fs::write(
        ws.path().join("configs/bad.yaml"),
        format!("workspace: sub\n{}", ws.pipeline_text()),
    )
    .unwrap();
    let r = from(&[
        "-f",
        ws.path().join("configs/bad.yaml").to_str().unwrap(),
        "status",
    ]);
    assert_eq!(r.code, 2, "{r:?}");
    assert!(
        r.stderr.contains("bad.yaml:1")
            && r.stderr
                .contains("workspace `sub`: allowed the file's directory"),
        "{}",
        r.stderr
    );
}
