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

#[test]
fn scratch_survives_a_failed_attempt_and_is_dropped_after_success() {
    // The scratch directory is how a long stage (training) resumes after a crash: it must be
    // handed to the next attempt of the same unit, and removed once the output is committed.
    let ws = Ws::new("basic.yaml");
    ws.set_pipeline(
        "stages:\n  resumable:\n    cmd: [test-stage]\n    params: {fail_first_attempts: 1}\n",
    );
    let first = ws.run(&["run"]);
    assert_eq!(first.code, 1, "{first:?}");
    let scratch_root = ws.path().join("artifacts/scratch");
    let kept: Vec<_> = std::fs::read_dir(&scratch_root).unwrap().collect();
    assert_eq!(kept.len(), 1, "one scratch dir kept for the failed unit");
    let second = ws.run(&["run"]);
    assert_eq!(second.code, 0, "{second:?}");
    assert!(
        ws.output_of("resumable").contains("earlier attempts 1"),
        "the retry saw the first attempt's scratch: {}",
        ws.output_of("resumable")
    );
    assert_eq!(std::fs::read_dir(&scratch_root).unwrap().count(), 0);
}
