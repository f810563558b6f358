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

/// Paths are checked after following symbolic links: a link in the workspace that points
/// outside is refused for `cmd[0]` and `bin_dir`; a link that stays inside is fine.
#[test]
fn symbolic_links_out_of_the_workspace_are_refused() {
    let ws = Ws::new("basic.yaml");
    let outside = tempfile::tempdir().unwrap();
    std::fs::copy(
        env!("CARGO_BIN_EXE_test-stage"),
        outside.path().join("test-stage"),
    )
    .unwrap();
    std::os::unix::fs::symlink(outside.path(), ws.path().join("tools")).unwrap();
    std::fs::write(
        ws.path().join("bad.yaml"),
        "stages:\n  a:\n    cmd: [tools/test-stage]\n",
    )
    .unwrap();
    assert_bad(
        &ws,
        &["-f", "bad.yaml", "run"],
        &["bad.yaml:3:", "symbolic link", "outside the workspace"],
    );
    std::fs::write(
        ws.path().join("bad.yaml"),
        "bin_dir: tools\nstages:\n  a:\n    cmd: [test-stage]\n",
    )
    .unwrap();
    assert_bad(
        &ws,
        &["-f", "bad.yaml", "run"],
        &["bad.yaml:1:", "bin_dir `tools`", "symbolic link"],
    );
    // The same program behind a link that stays inside the workspace runs.
    std::fs::create_dir(ws.path().join("bin")).unwrap();
    std::fs::copy(
        env!("CARGO_BIN_EXE_test-stage"),
        ws.path().join("bin/test-stage"),
    )
    .unwrap();
    std::os::unix::fs::symlink("bin", ws.path().join("local")).unwrap();
    std::fs::write(
        ws.path().join("good.yaml"),
        "stages:\n  a:\n    cmd: [local/test-stage]\n",
    )
    .unwrap();
    let r = ws.run(&["-f", "good.yaml", "run"]);
    assert_eq!(r.code, 0, "{r:?}");
    assert_eq!(ws.ran(), ["a".to_string()]);
}
