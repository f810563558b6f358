//! Freshness, targeted reruns, the run-cache, --force, --set and corruption.

use crate::harness::{ok, sorted, Ws};

#[test]
fn second_run_does_nothing_and_says_so() {
    let ws = Ws::new("basic.yaml");
    let r = ok(ws.run(&["run"]));
    assert_eq!(
        ws.ran(),
        sorted(&["prepare", "transform", "report", "side"])
    );
    assert!(r.stdout.contains("prepare    ran"), "{}", r.stdout);
    assert!(
        r.stdout.contains("prepared 3 rows"),
        "stage summary in the table: {}",
        r.stdout
    );
    let r = ok(ws.run(&["run"]));
    assert!(r.stdout.contains("Nothing to do"), "{}", r.stdout);
    assert!(ws.ran().is_empty());
}

#[test]
fn changed_parameter_reruns_only_downstream_then_revert_hits_run_cache() {
    let ws = Ws::new("basic.yaml");
    ok(ws.run(&["run"]));
    ws.ran();
    let original = ws.pipeline_text();
    let before = ws.output_of("report");
    ws.set_pipeline(&original.replace("scale: 2.0", "scale: 3.0"));
    let st = ok(ws.run(&["status"]));
    assert!(
        st.stdout.contains("parameter `scale` changed: 2.0 -> 3.0"),
        "{}",
        st.stdout
    );
    ok(ws.run(&["run"]));
    assert_eq!(ws.ran(), sorted(&["transform", "report"]));
    assert!(ws.output_of("transform").contains(r#""scale":3.0"#));

    // Back to the earlier value: restored from the run-cache, nothing executes.
    ws.set_pipeline(&original);
    let r = ok(ws.run(&["run"]));
    assert!(
        ws.ran().is_empty(),
        "run-cache must restore without running"
    );
    assert!(r.stdout.contains("transform  cached"), "{}", r.stdout);
    assert_eq!(ws.output_of("report"), before);
    assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
}

#[test]
fn set_override_is_part_of_identity_and_recorded() {
    let ws = Ws::new("basic.yaml");
    ok(ws.run(&["run"]));
    ws.ran();
    // An integer for a float parameter is accepted and becomes 5.0.
    ok(ws.run(&["run", "--set", "transform.scale=5"]));
    assert_eq!(ws.ran(), sorted(&["transform", "report"]));
    assert!(ws.output_of("transform").contains(r#""scale":5.0"#));
    assert!(
        ws.read("artifacts/pipeline.lock.json").contains("scale=5"),
        "override recorded"
    );
    let st = ok(ws.run(&["status"]));
    assert!(
        st.stdout.contains("parameter `scale` changed: 5.0 -> 2.0"),
        "{}",
        st.stdout
    );
    assert!(st.stdout.contains("run-cache"), "{}", st.stdout);
    ok(ws.run(&["run"]));
    assert!(ws.ran().is_empty());
}

#[test]
fn force_reruns_one_stage_and_reuses_the_rest() {
    let ws = Ws::new("basic.yaml");
    ok(ws.run(&["run"]));
    ws.ran();
    let r = ok(ws.run(&["run", "transform", "--force"]));
    // Only the target reran; its output is byte-identical, so `report` (downstream) stays
    // fresh, and `prepare` (upstream) was reused.
    assert_eq!(ws.ran(), sorted(&["transform"]));
    assert!(r.stdout.contains("transform  ran"), "{}", r.stdout);
    assert!(r.stdout.contains("prepare    cached"), "{}", r.stdout);
    assert!(
        !r.stdout.contains("report"),
        "report is not a target: {}",
        r.stdout
    );
    assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
}

#[test]
fn corrupted_cached_file_is_detected_and_recomputed() {
    let ws = Ws::new("basic.yaml");
    ok(ws.run(&["run"]));
    ws.ran();
    let path = ws.show("transform").remove(0);
    let good = std::fs::read(&path).unwrap();
    // Same length, different bytes: only the content hash can tell.
    let mut bad = good.clone();
    bad[0] ^= 0x20;
    let mut perm = std::fs::metadata(&path).unwrap().permissions();
    #[allow(clippy::permissions_set_readonly_false)]
    perm.set_readonly(false);
    std::fs::set_permissions(&path, perm).unwrap();
    std::fs::write(&path, &bad).unwrap();

    let st = ok(ws.run(&["status"]));
    assert!(st.stdout.contains("corrupted"), "{}", st.stdout);
    let r = ok(ws.run(&["run"]));
    assert!(r.stderr.contains("corrupted"), "{}", r.stderr);
    // Recomputed to the same bytes, so downstream stays fresh.
    assert_eq!(ws.ran(), sorted(&["transform"]));
    let path = ws.show("transform").remove(0);
    assert_eq!(std::fs::read(&path).unwrap(), good);
    assert!(ok(ws.run(&["run"])).stdout.contains("Nothing to do"));
}

#[test]
fn changed_executable_makes_its_stages_stale() {
    let ws = Ws::new("basic.yaml");
    // A private copy of the stage binary, found through the file's `bin_dir`.
    let bin = ws.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    std::fs::copy(env!("CARGO_BIN_EXE_test-stage"), bin.join("test-stage")).unwrap();
    ws.set_pipeline(&format!("bin_dir: bin\n{}", ws.pipeline_text()));
    let run_local = || {
        let out = std::process::Command::new(pino_mbd_tests::bin("pipeline"))
            .current_dir(std::env::temp_dir())
            .args(["-C".as_ref(), ws.path().as_os_str(), "run".as_ref()])
            .env_remove("PINO_BIN_DIR")
            .env("TEST_STAGE_LOG", ws.log_path())
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
    };
    run_local();
    assert_eq!(ws.ran().len(), 4);
    // Same program, different bytes (trailing data is ignored by the ELF loader).
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(bin.join("test-stage"))
        .unwrap();
    std::io::Write::write_all(&mut f, b"new build").unwrap();
    drop(f);
    let st = std::process::Command::new(pino_mbd_tests::bin("pipeline"))
        .current_dir(ws.path())
        .arg("status")
        .env_remove("PINO_BIN_DIR")
        .output()
        .unwrap();
    let st = String::from_utf8_lossy(&st.stdout);
    assert!(st.contains("prepare    stale  code changed"), "{st}");
    run_local();
    assert_eq!(ws.ran().len(), 4, "every stage uses the changed binary");
}

#[test]
fn bin_dir_from_environment_and_plain_progress_lines() {
    let ws = Ws::new("basic.yaml");
    let dir = std::path::Path::new(env!("CARGO_BIN_EXE_test-stage"))
        .parent()
        .unwrap();
    let out = std::process::Command::new(pino_mbd_tests::bin("pipeline"))
        .current_dir(ws.path())
        .args(["run", "side"])
        .env("PINO_BIN_DIR", dir)
        .env("TEST_STAGE_LOG", ws.log_path())
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    assert_eq!(
        ws.ran(),
        sorted(&["side"]),
        "a target runs alone when it has no upstream"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    // Not a terminal: plain lines from the stage's `::progress 3 3`.
    assert!(
        err.contains("[side] started") && err.contains("[side] 3/3"),
        "{err}"
    );
}
