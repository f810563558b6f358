//! Every bad-input case: a message naming the file and line, exit 2, nothing run.

use crate::harness::{fixture, Ws};

fn assert_bad(ws: &Ws, args: &[&str], wanted: &[&str]) {
    let r = ws.run(args);
    assert_eq!(r.code, 2, "{args:?}: {r:?}");
    for w in wanted {
        assert!(
            r.stderr.contains(w),
            "{args:?}: expected `{w}` in:\n{}",
            r.stderr
        );
    }
    assert!(ws.ran().is_empty(), "{args:?}: nothing may run");
    assert!(
        !ws.path().join("artifacts").exists(),
        "{args:?}: bad input must leave no trace in the store"
    );
}

#[test]
fn bad_pipeline_files_are_refused_with_file_and_line() {
    let cases: &[(&str, &[&str])] = &[
        (
            "unknown_key.yaml",
            &["bad.yaml:6:5:", "unknown field `shard`"],
        ),
        (
            "missing_dep.yaml",
            &["bad.yaml:8:", "unknown stage `nowhere`"],
        ),
        (
            "cycle.yaml",
            &["bad.yaml:4:", "dependency cycle: a -> c -> b -> a"],
        ),
        (
            "wrong_type.yaml",
            &["bad.yaml:4:13:", "shards: invalid type"],
        ),
        ("malformed.yaml", &["bad.yaml:4:", "flow sequence"]),
        (
            "missing_exe.yaml",
            &["bad.yaml:5:", "executable `no-such-stage-binary` not found"],
        ),
        ("escape_cmd.yaml", &["bad.yaml:5:", "inside the workspace"]),
        (
            "escape_bin_dir.yaml",
            &["bad.yaml:1:", "bin_dir `../elsewhere/bin`"],
        ),
        (
            "duplicate_stage.yaml",
            &["bad.yaml:6:", "duplicate key `a`"],
        ),
    ];
    for (file, wanted) in cases {
        let ws = Ws::new("basic.yaml");
        std::fs::copy(fixture(&format!("bad/{file}")), ws.path().join("bad.yaml")).unwrap();
        assert_bad(&ws, &["-f", "bad.yaml", "run"], wanted);
    }
}

#[test]
fn bad_overrides_are_refused_with_file_and_line() {
    let ws = Ws::new("basic.yaml");
    // Line 9 is transform's `params:`, line 10 its `scale:`, line 2 `stages:`.
    assert_bad(
        &ws,
        &["run", "--set", "transform.scal=3"],
        &["pipeline.yaml:9:", "no parameter `scal`", "label, scale"],
    );
    assert_bad(
        &ws,
        &["run", "--set", "transform.scale=fast"],
        &["pipeline.yaml:10:", "is a float but `fast` is a string"],
    );
    assert_bad(
        &ws,
        &["run", "--set", "side.n=1.5"],
        &["pipeline.yaml:18:", "is an integer but `1.5` is a float"],
    );
    assert_bad(
        &ws,
        &["run", "--set", "nope.x=1"],
        &["pipeline.yaml:2:", "no stage `nope`"],
    );
    assert_bad(
        &ws,
        &["run", "--set", "transform"],
        &["expected STAGE.KEY=VALUE"],
    );
    assert_bad(&ws, &["run", "nope"], &["unknown stage `nope`"]);
}
