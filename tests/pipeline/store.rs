//! The store: sealed (read-only) objects and `pipeline gc` (what it keeps, what it removes,
//! and that it cannot pull an object from under a concurrent run).

use crate::harness::{ok, sorted, wait_until, Ws};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

/// Every file and directory under `dir` (itself included) with its permission bits.
fn modes(dir: &Path, out: &mut Vec<(PathBuf, bool, u32)>) {
    let meta = std::fs::symlink_metadata(dir).unwrap();
    out.push((
        dir.to_owned(),
        meta.is_dir(),
        meta.permissions().mode() & 0o7777,
    ));
    if meta.is_dir() {
        for e in std::fs::read_dir(dir).unwrap() {
            modes(&e.unwrap().path(), out);
        }
    }
}

fn object_ids(ws: &Ws) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(ws.path().join("artifacts/objects"))
        .map(|d| {
            d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// Identities the lock record points to.
fn locked_ids(ws: &Ws) -> Vec<String> {
    let rec: serde_json::Value =
        serde_json::from_str(&ws.read("artifacts/pipeline.lock.json")).unwrap();
    let mut v: Vec<String> = rec["pipelines"]
        .as_object()
        .unwrap()
        .values()
        .flat_map(|units| units.as_object().unwrap().values())
        .map(|e| e["identity"].as_str().unwrap().to_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn committed_objects_are_read_only() {
    let ws = Ws::new("basic.yaml");
    ok(ws.run(&["run"]));
    let mut all = Vec::new();
    for id in object_ids(&ws) {
        modes(&ws.path().join("artifacts/objects").join(id), &mut all);
    }
    // 4 objects, each: its directory, out/, out.txt, manifest, context, log.
    assert_eq!(all.len(), 4 * 6, "{all:#?}");
    for (p, is_dir, mode) in &all {
        assert_eq!(
            *mode,
            if *is_dir { 0o555 } else { 0o444 },
            "{}",
            p.display()
        );
    }
    // A tool that opens an artifact for writing is refused by the kernel; as root (which
    // permission bits do not stop) its change is still caught before the object is reused.
    let path = ws.show("transform").remove(0);
    let good = std::fs::read(&path).unwrap();
    match std::fs::OpenOptions::new().write(true).open(&path) {
        Err(e) => {
            assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
            let e = std::fs::write(path.with_file_name("extra.txt"), b"x").unwrap_err();
            assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
            assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
        }
        Ok(mut f) => {
            std::io::Write::write_all(&mut f, b"X").unwrap();
            drop(f);
            ws.ran();
            let r = ok(ws.run(&["run"]));
            assert!(r.stderr.contains("corrupted"), "{}", r.stderr);
            assert_eq!(ws.ran(), sorted(&["transform"]));
            assert_eq!(std::fs::read(ws.show("transform").remove(0)).unwrap(), good);
        }
    }
}

#[test]
fn gc_keeps_what_the_lock_record_and_keep_need_and_removes_the_rest() {
    let ws = Ws::new("basic.yaml");
    let original = ws.pipeline_text();
    // Three versions of transform and report (scale 2, 3, 4); prepare and side once.
    for scale in ["2.0", "3.0", "4.0"] {
        ws.set_pipeline(&original.replace("scale: 2.0", &format!("scale: {scale}")));
        ok(ws.run(&["run"]));
    }
    ws.ran();
    assert_eq!(object_ids(&ws).len(), 8);
    let current = locked_ids(&ws);
    assert_eq!(current.len(), 4);

    // A dry run lists the four old objects and removes nothing.
    let dry = ok(ws.run(&["gc", "--dry-run"]));
    assert!(
        dry.stdout.contains("would remove (dry run) 4 object(s)"),
        "{}",
        dry.stdout
    );
    assert_eq!(object_ids(&ws).len(), 8);

    // --keep 1: the newest earlier object of each unit stays (scale 3), the oldest goes.
    let r = ok(ws.run(&["gc", "--keep", "1"]));
    assert!(r.stdout.contains("removed 2 object(s)"), "{}", r.stdout);
    assert!(r.stdout.contains("2 recent"), "{}", r.stdout);
    assert_eq!(object_ids(&ws).len(), 6);
    assert!(current.iter().all(|id| object_ids(&ws).contains(id)));
    assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
    ws.set_pipeline(&original.replace("scale: 2.0", "scale: 3.0"));
    ok(ws.run(&["run"]));
    assert!(ws.ran().is_empty(), "scale 3 was kept: restored, not rerun");
    ws.set_pipeline(&original);
    ok(ws.run(&["run"]));
    assert_eq!(
        ws.ran(),
        sorted(&["transform", "report"]),
        "scale 2 was removed: recomputed"
    );

    // Plain gc: exactly the lock record's objects remain, and they are all usable.
    let r = ok(ws.run(&["gc"]));
    assert!(r.stdout.contains("removed 4 object(s)"), "{}", r.stdout);
    assert_eq!(object_ids(&ws), locked_ids(&ws));
    let st = ok(ws.run(&["status"]));
    assert!(!st.stdout.contains("stale"), "{}", st.stdout);
    assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
    assert!(ws.ran().is_empty());
    // Nothing left to collect.
    let r = ok(ws.run(&["gc"]));
    assert!(r.stdout.contains("removed 0 object(s)"), "{}", r.stdout);
}

#[test]
fn gc_waits_for_a_running_pipeline_and_keeps_what_it_commits() {
    let ws = Ws::new("gated.yaml");
    ok(ws.run(&["run"]));
    let old = object_ids(&ws);
    assert_eq!(old.len(), 1);
    // A new version of the stage, held mid-run by the gate.
    ws.set_pipeline(
        &ws.pipeline_text()
            .replace("gated: true", "gated: true, n: 2"),
    );
    std::fs::write(ws.gate(), b"").unwrap();
    ws.ran();
    let mut run = ws.spawn(&["run"], "run");
    wait_until("the run's stage started", || {
        ws.read("stage-log.txt").contains("start slow")
    });
    let refused = ws.run(&["gc", "--no-wait"]);
    assert_eq!(refused.code, 2, "{refused:?}");
    assert!(
        refused.stderr.contains("another `pipeline run`"),
        "{refused:?}"
    );
    let mut gc = ws.spawn(&["gc"], "gc");
    wait_until("gc says it waits for the run", || {
        ws.read("gc.err")
            .contains("waiting for another `pipeline run`")
    });
    // While it waits, nothing is touched: the old object and the run's work are there.
    assert_eq!(object_ids(&ws), old);
    std::fs::remove_file(ws.gate()).unwrap();
    assert!(run.wait().unwrap().success(), "{}", ws.read("run.err"));
    assert!(gc.wait().unwrap().success(), "{}", ws.read("gc.err"));
    assert!(
        ws.read("gc.out").contains("removed 1 object(s)"),
        "{}",
        ws.read("gc.out")
    );
    // The run's new object survived, the old one is gone, and the run is not repeated.
    let now = object_ids(&ws);
    assert_eq!(now, locked_ids(&ws));
    assert_eq!(now.len(), 1);
    assert_ne!(now, old);
    assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
    assert_eq!(ws.ran(), sorted(&["slow"]));
}
