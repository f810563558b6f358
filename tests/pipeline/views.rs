//! `status`, `dag` and `show` output.

use crate::harness::{ok, Ws};

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
