//! A failing stage: stderr tail shown, nothing cached, exit 1, independent stages complete.

use crate::harness::{sorted, Ws};

#[test]
fn failing_stage_shows_stderr_caches_nothing_and_others_finish() {
    let ws = Ws::new("failing.yaml");
    let r = ws.run(&["run"]);
    assert_eq!(r.code, 1, "{r:?}");
    assert!(
        r.stderr.contains("boom: deliberate failure in bad"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("[bad] FAILED"), "{}", r.stderr);
    assert!(r.stdout.contains("after-bad    skipped"), "{}", r.stdout);
    assert_eq!(ws.ran(), sorted(&["good", "independent"]));
    assert_eq!(ws.objects(), 2, "only the two successful units are stored");
    assert!(ws.path().join("artifacts/logs/bad.failed.log").is_file());
    let st = ws.run(&["status"]);
    assert_eq!(st.code, 0);
    assert!(
        st.stdout.contains("bad          never run"),
        "{}",
        st.stdout
    );
    // Nothing of it was cached: the next run tries again (and fails again).
    assert_eq!(ws.run(&["run"]).code, 1);
    assert!(
        ws.ran().is_empty(),
        "bad fails before its end marker; good/independent are cached"
    );
    assert_eq!(ws.run(&["show", "bad"]).code, 1);
}
