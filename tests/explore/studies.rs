//! Studies started from the sweep view beside the interactive work: a running study never
//! holds up a prediction or the Studies list, shows its progress and can be cancelled; a study
//! the model cannot run is refused at once, as a sweep of the same range is.

use crate::api::wait_study;
use crate::Trained;
use serde_json::{json, Value};
use std::time::{Duration, Instant};

/// The started study `name` as `GET /api/studies` lists it.
fn listed(c: &mut pino_explore::client::Client, name: &str) -> Value {
    let list = c.get("/api/studies").unwrap();
    assert_eq!(list.status, 200);
    list.json()["explorer"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .unwrap_or_else(|| panic!("{name} is not listed"))
        .clone()
}

#[test]
fn a_running_study_never_holds_up_a_prediction_shows_its_progress_and_can_be_cancelled() {
    let trained = Trained::shared();
    let dir = tempfile::tempdir().unwrap();
    // One study thread: slices of 32 designs (4 batches of 8), so the last study below runs
    // in four slices.
    let served = trained.serve(&[
        "--study-dir",
        dir.path().to_str().unwrap(),
        "--study-threads",
        "1",
    ]);
    let mut c = served.client();
    let model = c.get("/api/model").unwrap().json();
    let p0 = model["parameters"][0]["name"].as_str().unwrap().to_owned();
    // The largest study the sweep view starts: 5000 designs and 32 solves.
    let start = json!({"kind": "monte_carlo", "parameters": [{"name": p0}], "n": 5000,
                       "solver_check": 32});
    let a = c.post_json("/api/studies", &start).unwrap();
    assert_eq!(a.status, 202, "{}", a.json());
    let name = a.json()["name"].as_str().unwrap().to_owned();
    // Predictions and the list are answered while it runs (before, they waited for it).
    for _ in 0..3 {
        let p = c.post_json("/api/predict", &json!({})).unwrap();
        assert_eq!(p.status, 200);
        let s = listed(&mut c, &name);
        assert_eq!(
            s["state"], "running",
            "the prediction waited for the study: {s}"
        );
    }
    // Its progress: designs through the surrogate, counted as they are answered.
    let t0 = Instant::now();
    let s = loop {
        let s = listed(&mut c, &name);
        assert_eq!(s["state"], "running", "{s}");
        if s["progress"]["done"].as_u64().unwrap_or(0) > 0 {
            break s;
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "no progress: {s}");
        std::thread::sleep(Duration::from_millis(50));
    };
    let p = &s["progress"];
    assert_eq!(p["total"], 5000, "{s}");
    assert!(p["done"].as_u64().unwrap() < 5000, "{s}");
    assert!(
        p["message"].as_str().unwrap().contains("of 5000 designs"),
        "{s}"
    );
    assert!(
        s["detail"]
            .as_str()
            .unwrap()
            .contains("through the surrogate"),
        "{s}"
    );
    // Cancelled: it stops, nothing is kept, and a study can be started again.
    let a = c
        .post_json("/api/studies/cancel", &json!({"name": name}))
        .unwrap();
    assert_eq!(a.status, 202, "{}", a.json());
    let s = wait_study(&mut c, &name);
    assert_eq!(s["state"], "cancelled", "{s}");
    let kept: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(kept.is_empty(), "a cancelled study left {kept:?}");
    let again = c
        .post_json("/api/studies/cancel", &json!({"name": name}))
        .unwrap();
    assert_eq!(again.status, 409, "{}", again.json());
    let unknown = c
        .post_json("/api/studies/cancel", &json!({"name": "nope"}))
        .unwrap();
    assert_eq!(unknown.status, 404, "{}", unknown.json());
    let small = json!({"kind": "monte_carlo", "parameters": [{"name": p0}], "n": 100});
    let a = c.post_json("/api/studies", &small).unwrap();
    assert_eq!(a.status, 202, "{}", a.json());
    let name = a.json()["name"].as_str().unwrap().to_owned();
    assert_ne!(
        name,
        s["name"].as_str().unwrap(),
        "a cancelled study's name given again"
    );
    let s = wait_study(&mut c, &name);
    assert_eq!(s["state"], "finished", "{s}");
    // Its one-line summary quotes the study's name as `code`.
    assert!(s["detail"].as_str().unwrap().contains('`'), "{s}");
    // Answered slice by slice, each design's indices are those `/api/predict` gives it under
    // the same generated profile: at either end of every slice.
    let t =
        pino_data::read_parquet(&dir.path().join(&name).join("evaluations.parquet"), None).unwrap();
    let params: Vec<String> = model["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap().to_owned())
        .collect();
    let excitation = t.i64("excitation").unwrap();
    for row in [0, 31, 32, 63, 64, 99] {
        let design: serde_json::Map<String, Value> = params
            .iter()
            .map(|p| (p.clone(), json!(t.f64(p).unwrap()[row])))
            .collect();
        let body = json!({"design": design, "bands": false,
                          "excitation": {"kind": "seed", "seed": 7, "id": excitation[row]}});
        let p = c.post_json("/api/predict", &body).unwrap().json();
        for i in p["indices"].as_array().unwrap() {
            let index = i["name"].as_str().unwrap();
            let (got, stored) = (i["value"].as_f64().unwrap(), t.f64(index).unwrap()[row]);
            assert!(
                (got - stored).abs() <= 1e-9 * stored.abs().max(1e-12),
                "design {row}, {index}: predict {got}, study {stored}"
            );
        }
    }
}

#[test]
fn a_study_the_model_cannot_run_is_refused_at_once() {
    let trained = Trained::shared();
    let dir = tempfile::tempdir().unwrap();
    let served = trained.serve(&["--study-dir", dir.path().to_str().unwrap()]);
    let mut c = served.client();
    let refused = |c: &mut pino_explore::client::Client, body: Value| -> Value {
        let a = c.post_json("/api/studies", &body).unwrap();
        assert_eq!(a.status, 400, "{body}: {}", a.json());
        a.json()
    };
    // A speed that leaves the track: refused at once, as the sweep refuses the same range,
    // naming the end of the interval.
    let sweep = c
        .post_json(
            "/api/sweep",
            &json!({"parameter": "v_kmh", "from": 300, "to": 5000, "steps": 3}),
        )
        .unwrap()
        .json();
    assert_eq!(sweep["field"], "to", "{sweep}");
    let v = refused(
        &mut c,
        json!({"kind": "monte_carlo", "parameters": [{"name": "v_kmh", "from": 300, "to": 5000}]}),
    );
    assert_eq!(v["field"], "parameters[0].to", "{v}");
    assert!(v["error"].as_str().unwrap().contains("design.v_kmh"), "{v}");
    // The same limit as the sweep's (its example design is another: the sweep's second value).
    let limit = |v: &Value| {
        v["allowed"]
            .as_str()
            .unwrap()
            .split(" with ")
            .next()
            .unwrap()
            .to_owned()
    };
    assert!(limit(&v).starts_with("at most "), "{v}");
    assert_eq!(limit(&v), limit(&sweep), "{v}");
    let v = refused(
        &mut c,
        json!({"kind": "sensitivity", "n": 16, "parameters": [
            {"name": "m_c"}, {"name": "v_kmh", "from": 300, "to": 5000}]}),
    );
    assert_eq!(v["field"], "parameters[1].to", "{v}");
    // Sobol rows: a power of two up to the explorer's own cap, which the message names.
    for n in [48, 2] {
        let v = refused(
            &mut c,
            json!({"kind": "sensitivity", "n": n, "parameters": [{"name": "m_c"}]}),
        );
        assert_eq!(v["field"], "n", "{v}");
        let text = format!("{} {}", v["error"], v["allowed"]);
        assert!(text.contains("power of two from 4 to 1024"), "{v}");
        assert!(!text.contains("65536"), "{v}");
    }
    assert!(
        std::fs::read_dir(dir.path()).unwrap().next().is_none(),
        "a refused study claimed a directory"
    );
}
