//! Two runs in one workspace: the second waits (or refuses with --no-wait).

use crate::harness::{ok, wait_until, Ws};

#[test]
fn second_run_waits_or_refuses_and_nothing_runs_twice() {
    let ws = Ws::new("gated.yaml");
    std::fs::write(ws.gate(), b"").unwrap();
    let mut first = ws.spawn(&["run"], "first");
    wait_until("the first run's stage started", || {
        ws.read("stage-log.txt").contains("start slow")
    });

    let refused = ws.run(&["run", "--no-wait"]);
    assert_eq!(refused.code, 2, "{refused:?}");
    assert!(
        refused
            .stderr
            .contains(&format!("another `pipeline run` (pid {})", first.id())),
        "{}",
        refused.stderr
    );

    let mut second = ws.spawn(&["run"], "second");
    wait_until("the second run says it waits", || {
        ws.read("second.err")
            .contains("waiting for another `pipeline run`")
    });
    std::fs::remove_file(ws.gate()).unwrap();
    assert!(first.wait().unwrap().success(), "{}", ws.read("first.err"));
    assert!(
        second.wait().unwrap().success(),
        "{}",
        ws.read("second.err")
    );
    assert!(
        ws.read("second.out").contains("Nothing to do"),
        "{}",
        ws.read("second.out")
    );
    assert_eq!(
        ws.ran(),
        vec!["slow".to_string()],
        "the stage ran exactly once"
    );
    assert!(ok(ws.run(&["status"])).stdout.contains("slow  fresh"));
}
