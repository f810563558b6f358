//! Matrix stages, sharded stages, and resuming after `kill -9`.

use crate::harness::{ok, sorted, wait_until, Ws};

#[test]
fn matrix_expansions_are_cached_separately() {
    let ws = Ws::new("matrix.yaml");
    let r = ok(ws.run(&["run"]));
    assert_eq!(
        ws.ran(),
        sorted(&[
            "data",
            "train[algorithm=1]",
            "train[algorithm=2]",
            "train[algorithm=3]",
            "evaluate"
        ])
    );
    assert!(r.stdout.contains("train[algorithm=2]"), "{}", r.stdout);
    // The matrix key is added to the params; downstream sees one input dir per expansion.
    let eval = ws.output_of("evaluate");
    for k in 0..3 {
        assert!(
            eval.contains(&format!("input models[{k}] out.txt")),
            "{eval}"
        );
    }
    assert!(eval.contains(r#""algorithm":3,"epochs":2"#), "{eval}");
    assert_eq!(ws.show("train").len(), 3);
    assert_eq!(ws.show("train[algorithm=2]").len(), 1);

    ok(ws.run(&["run", "train[algorithm=2]", "--force"]));
    assert_eq!(ws.ran(), sorted(&["train[algorithm=2]"]));
    ok(ws.run(&["run", "--set", "train.epochs=3"]));
    assert_eq!(
        ws.ran(),
        sorted(&[
            "train[algorithm=1]",
            "train[algorithm=2]",
            "train[algorithm=3]",
            "evaluate"
        ])
    );
}

#[test]
fn sharded_stage_killed_mid_run_resumes_from_finished_shards() {
    let ws = Ws::new("sharded.yaml");
    std::fs::write(ws.gate(), b"").unwrap();
    // Shards 2 and 3 wait on the gate; 0 and 1 finish and are committed.
    let mut child = ws.spawn(&["run", "-j", "4"], "killed");
    wait_until("shards 0 and 1 committed while 2 and 3 run", || {
        let lock = ws.read("artifacts/pipeline.lock.json");
        let log = std::fs::read_to_string(ws.log_path()).unwrap_or_default();
        lock.contains("\"simulate#0\"")
            && lock.contains("\"simulate#1\"")
            && log.contains("start simulate#2")
            && log.contains("start simulate#3")
    });
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    // The gated shards die with the orchestrator (they would wait on the gate forever).
    let log = std::fs::read_to_string(ws.log_path()).unwrap();
    for shard in ["simulate#2", "simulate#3"] {
        let pid = log
            .lines()
            .find_map(|l| l.strip_prefix(&format!("pid {shard} ")))
            .expect("pid line");
        wait_until(&format!("{shard} (pid {pid}) to die"), || {
            // Gone, or a zombie waiting for init to reap it.
            std::fs::read_to_string(format!("/proc/{pid}/stat")).map_or(true, |s| {
                s.rsplit(')')
                    .next()
                    .unwrap_or("")
                    .trim_start()
                    .starts_with('Z')
            })
        });
    }
    std::fs::remove_file(ws.gate()).unwrap();
    let first = ws.ran();
    assert!(
        !first.contains(&"simulate#2".to_string()) && !first.contains(&"collect".to_string()),
        "{first:?}"
    );

    // --no-wait: a stale lock would refuse; the kernel released it with the dead process.
    let r = ok(ws.run(&["run", "--no-wait", "-j", "2"]));
    assert_eq!(
        ws.ran(),
        sorted(&["simulate#2", "simulate#3", "collect"]),
        "{}",
        r.stdout
    );
    assert!(r.stdout.contains("simulate#0  cached"), "{}", r.stdout);

    // Byte-identical to an uninterrupted run in a fresh workspace (same object ids too).
    let clean = Ws::new("sharded.yaml");
    ok(clean.run(&["run"]));
    for stage in ["simulate", "collect"] {
        let a = ws.show(stage);
        let b = clean.show(stage);
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(
                std::fs::read(x).unwrap(),
                std::fs::read(y).unwrap(),
                "{stage}"
            );
            assert_eq!(
                x.strip_prefix(ws.path()).unwrap(),
                y.strip_prefix(clean.path()).unwrap()
            );
        }
    }
    let collect = ws.output_of("collect");
    assert!(
        collect.contains("input sim[3] out.txt") && collect.contains("shard 3/4"),
        "{collect}"
    );
    assert!(
        std::fs::read_dir(ws.path().join("artifacts/tmp"))
            .unwrap()
            .next()
            .is_none(),
        "debris of the killed run is cleaned"
    );
}
