//! The explorer's JSON API as a script drives it: every bad request a 400 naming its field,
//! the numbers equal to the `predict` command's and the `simulate` stage's, the solve gate and
//! the cancellation of a solve whose client left, the host and token checks.

use crate::Trained;
use pino_explore::client::Client;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

/// The test sample of the TINY split (ids after 4 training and 2 validation samples).
const TEST_SAMPLE: i64 = 6;

fn names(v: &Value, key: &str) -> Vec<String> {
    v[key]
        .as_array()
        .unwrap_or_else(|| panic!("no `{key}` in {v}"))
        .iter()
        .map(|x| x["name"].as_str().unwrap().to_owned())
        .collect()
}

fn series(v: &Value, name: &str) -> Vec<f64> {
    v["channels"][name]
        .as_array()
        .unwrap_or_else(|| panic!("no channel `{name}`"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// `max |a - b| / max |b|` (the tolerance rule of the project).
fn rel(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

#[test]
fn every_bad_request_is_a_400_naming_its_field_and_the_server_keeps_serving() {
    let trained = Trained::new(&[]);
    let mut served = trained.serve(&[]);
    let mut c = served.client();
    let model = c.get("/api/model").unwrap().json();
    let params = names(&model, "parameters");
    let (_, system) = pino_mbd_tests::system("vtcd", &[]);
    assert_eq!(
        params,
        system.sampled_names(),
        "the model's parameters, in its order"
    );
    // Each index with the limit `failed` judges it by (the railway defaults here).
    let limit = |name: &str| {
        let ix = model["indices"].as_array().unwrap();
        let i = ix.iter().find(|i| i["name"] == name).unwrap();
        i["limit"]["value"].as_f64()
    };
    assert_eq!(limit("peak_wheel_rail_force_kn"), Some(170.0));
    assert_eq!(limit("wheel_load_reduction_rate"), Some(0.6));
    for point in ["centre", "front", "rear"] {
        assert_eq!(limit(&format!("sperling_wz_{point}")), Some(2.5));
    }
    assert_eq!(limit("rail_deflection_peak_mm"), None);

    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "/api/predict",
            br#"{"design": {"k_pz": 1.0}}"#.to_vec(),
            "design.k_pz",
        ),
        (
            "/api/predict",
            br#"{"design": {"k_p": "NaN"}}"#.to_vec(),
            "design.k_p",
        ),
        (
            "/api/predict",
            br#"{"design": {"k_p": null}}"#.to_vec(),
            "design.k_p",
        ),
        (
            "/api/predict",
            br#"{"design": {"k_p": NaN}}"#.to_vec(),
            "body",
        ),
        (
            "/api/predict",
            br#"{"design": {"k_p": 1e999}}"#.to_vec(),
            "body",
        ),
        ("/api/predict", br#"{"design": "#.to_vec(), "body"),
        (
            "/api/predict",
            br#"{"design": {"m_c": -5.0}}"#.to_vec(),
            "design",
        ),
        (
            "/api/predict",
            br#"{"excitation": {"kind": "test", "sample_id": 0}}"#.to_vec(),
            "excitation.sample_id",
        ),
        (
            "/api/solve",
            br#"{"design": {}, "extra": 1}"#.to_vec(),
            "extra",
        ),
        (
            "/api/sweep",
            br#"{"parameter": "k_p", "steps": 1000000}"#.to_vec(),
            "steps",
        ),
        (
            "/api/sweep",
            br#"{"parameter": "nope"}"#.to_vec(),
            "parameter",
        ),
        ("/api/download/curves?format=xlsx", b"{}".to_vec(), "format"),
    ];
    for (path, body, field) in cases {
        let a = c.request("POST", path, &body).unwrap();
        let v = a.json();
        assert_eq!(
            a.status,
            400,
            "{path} {}: {v}",
            String::from_utf8_lossy(&body)
        );
        let got = v["field"].as_str().unwrap_or_default();
        assert!(
            got.starts_with(field),
            "{path}: field {got:?}, expected {field:?}: {v}"
        );
        assert!(!v["error"].as_str().unwrap_or_default().is_empty(), "{v}");
    }
    // A value outside the training range is accepted and flagged.
    let a = c
        .post_json("/api/predict", &json!({"design": {"k_p": 1.0e9}}))
        .unwrap();
    assert_eq!(a.status, 200);
    assert_eq!(names(&a.json(), "outside"), ["k_p"]);
    // Oversized bodies, unknown paths, paths that try to leave the assets, other hosts.
    let big = vec![b' '; pino_explore::server::BODY_LIMIT + 1];
    assert_eq!(c.request("POST", "/api/predict", &big).unwrap().status, 413);
    for path in [
        "/nope",
        "/assets/../Cargo.toml",
        "/assets/..%2F..%2FCargo.toml",
        "/api/pipeline/plot/..%2Fmodel.json",
    ] {
        assert_eq!(c.get(path).unwrap().status, 404, "{path}");
    }
    let a = Client::new(served.addr)
        .with_host("attacker.example:80")
        .get("/api/model")
        .unwrap();
    assert_eq!(a.status, 403);
    assert!(a.header("access-control-allow-origin").is_none());
    assert!(a.header("content-security-policy").is_none() || a.status == 403);
    let page = c.get("/").unwrap();
    assert_eq!(page.status, 200);
    assert!(page
        .header("content-security-policy")
        .is_some_and(|v| v.contains("script-src 'self'")));
    assert!(c.get("/api/health").unwrap().json()["ok"]
        .as_bool()
        .unwrap());
    assert!(served.alive());
}

#[test]
fn the_pipeline_page_shows_what_pipeline_status_shows_and_the_latest_evaluation() {
    let trained = Trained::new(&[]);
    let served = trained.serve(&[]);
    let mut c = served.client();
    let g = c.get("/api/pipeline").unwrap().json();
    let units = g["units"].as_array().unwrap();
    let status = crate::pipeline(trained.ws.path(), &trained.sets, &["status"]);
    let text = String::from_utf8_lossy(&status.stdout);
    assert_eq!(units.len(), text.lines().count() - 2, "{text}");
    for u in units {
        let key = u["key"].as_str().unwrap();
        assert_eq!(u["state"], "fresh", "{key}: {u}");
        assert!(
            text.lines()
                .any(|l| l.starts_with(key) && l.contains("fresh")),
            "{key}"
        );
    }
    let table = g["evaluate"]["table4"].as_array().unwrap();
    assert_eq!(
        table.len(),
        7,
        "a header, the truth row and five algorithms: {table:?}"
    );
    let plots = g["evaluate"]["plots"].as_array().unwrap();
    assert!(!plots.is_empty());
    let png = c
        .get(&format!(
            "/api/pipeline/plot/{}",
            plots[0].as_str().unwrap()
        ))
        .unwrap();
    assert_eq!(png.status, 200);
    assert_eq!(&png.body[1..4], b"PNG");
    assert_eq!(c.get("/api/pipeline/plot/model.json").unwrap().status, 404);
}

/// The designs file `predict --params` reads.
fn design_file(dir: &Path, design: &BTreeMap<String, f64>) -> std::path::PathBuf {
    let path = dir.join("design.yaml");
    let text = serde_yaml::to_string(&json!({"sets": [design]})).unwrap();
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn predictions_equal_the_predict_command_and_solves_equal_the_simulation() {
    let trained = Trained::new(&[]);
    let served = trained.serve(&[]);
    let mut c = served.client();
    let model = c.get("/api/model").unwrap().json();
    let channels = names(&model, "channels");
    let model_dir = model["model"]["dir"].as_str().unwrap().to_owned();
    let test = &model["excitation"]["test_samples"][0];
    assert_eq!(test["sample_id"], TEST_SAMPLE);

    // A design outside the training range, predicted by the server and by `predict`.
    let mut design: BTreeMap<String, f64> = serde_json::from_value(test["design"].clone()).unwrap();
    design.insert("k_s".into(), design["k_s"] * 3.0);
    let excitation = json!({"kind": "test", "sample_id": TEST_SAMPLE});
    let a = c
        .post_json(
            "/api/predict",
            &json!({"design": design, "excitation": excitation}),
        )
        .unwrap();
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let served_pred = a.json();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.parquet");
    let o = std::process::Command::new(pino_mbd_tests::bin("predict"))
        .arg("--model")
        .arg(&model_dir)
        .arg("--params")
        .arg(design_file(dir.path(), &design))
        .arg("--profile")
        .arg(trained.file("irregularity", "irregularity.parquet"))
        .args(["--profile-id", &TEST_SAMPLE.to_string(), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", pino_mbd_tests::output_text(&o));
    let table = pino_data::read_parquet(&out, None).unwrap();
    assert_eq!(floats(&served_pred["t"]), table.f64("t").unwrap());
    for name in &channels {
        let got = series(&served_pred, name);
        assert_eq!(
            got,
            table.f64(name).unwrap(),
            "{name}: the page's numbers are predict's"
        );
    }

    // The test sample's own design through the solver equals its simulated record.
    let a = c
        .post_json(
            "/api/solve",
            &json!({"design": test["design"], "excitation": excitation}),
        )
        .unwrap();
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let solved = a.json();
    let t = floats(&solved["t"]);
    let sims: Vec<_> = trained
        .show("simulate")
        .into_iter()
        .filter(|p| p.file_name().is_some_and(|n| n == "simulation.parquet"))
        .collect();
    let sim = pino_data::read_parquet_files(&sims, None).unwrap();
    let (ids, times) = (sim.i64("sample_id").unwrap(), sim.f64("t").unwrap());
    let rows: Vec<usize> = t
        .iter()
        .map(|&tt| {
            (0..ids.len())
                .find(|&r| ids[r] == TEST_SAMPLE && (times[r] - tt).abs() < 1e-9)
                .unwrap_or_else(|| panic!("no simulated row at t = {tt}"))
        })
        .collect();
    for name in &channels {
        let col = sim.f64(name).unwrap();
        let expected: Vec<f64> = rows.iter().map(|&r| col[r]).collect();
        let e = rel(&series(&solved, name), &expected);
        assert!(e <= 1e-12, "{name}: solve vs simulate {e:e}");
    }
    // Each channel's error of the surrogate is reported, and equals the one computed here.
    let pred = c
        .post_json(
            "/api/predict",
            &json!({"design": test["design"], "excitation": excitation}),
        )
        .unwrap()
        .json();
    for name in &channels {
        let (p, x) = (series(&pred, name), series(&solved, name));
        let num: f64 = p.iter().zip(&x).map(|(a, b)| (a - b) * (a - b)).sum();
        let den: f64 = x.iter().map(|b| b * b).sum();
        let reported = solved["errors"][name].as_f64();
        if den > 0.0 {
            let expected = (num / den).sqrt();
            assert!(
                (reported.unwrap() - expected).abs() <= 1e-9 * expected.max(1e-12),
                "{name}"
            );
        }
    }
    let ix = names(&solved, "indices");
    assert_eq!(ix, names(&model, "indices"));
    assert_eq!(solved["index_errors"].as_object().unwrap().len(), ix.len());
}

/// Polls `/api/health` until `field` reaches `at_least` (or a minute passes).
fn wait_health(c: &mut Client, field: &str, at_least: u64) -> Value {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let h = c.get("/api/health").unwrap().json();
        if h[field].as_u64().unwrap_or(0) >= at_least || Instant::now() > deadline {
            return h;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn the_solver_is_bounded_and_a_client_that_leaves_is_cancelled() {
    // Solves of a few seconds: the full track, 3 s runs.
    let trained = Trained::new(&[
        "simulate.duration=3.0",
        "irregularity.length=540.0",
        "constants.system_values.n_f=900",
        "constants.system_values.n_m=450",
    ]);
    let mut served = trained.serve(&["--solve-workers", "1", "--solve-queue", "0"]);
    let mut c = served.client();
    // One solve runs; a second one finds the gate full: 429 with a retry hint.
    let addr = served.addr;
    let first = std::thread::spawn(move || Client::new(addr).post_json("/api/solve", &json!({})));
    let h = wait_health(&mut c, "solves_waiting_or_running", 1);
    assert_eq!(h["solves_waiting_or_running"], 1, "{h}");
    let busy = c.post_json("/api/solve", &json!({})).unwrap();
    assert_eq!(busy.status, 429, "{}", String::from_utf8_lossy(&busy.body));
    assert!(busy.header("retry-after").is_some());
    assert!(busy.json()["retry_after_s"].as_u64().is_some());
    // Predictions are not held up by the solve.
    assert_eq!(c.post_json("/api/predict", &json!({})).unwrap().status, 200);
    let first = first.join().unwrap().unwrap();
    assert_eq!(first.status, 200);
    let completed = c.get("/api/health").unwrap().json()["solves_completed"]
        .as_u64()
        .unwrap();

    // A client that disconnects mid-solve: the solve is cancelled and the server serves on.
    let leaving = c.send_only("POST", "/api/solve", b"{}").unwrap();
    let h = wait_health(&mut c, "solves_waiting_or_running", 1);
    assert_eq!(h["solves_waiting_or_running"], 1, "{h}");
    drop(leaving);
    let h = wait_health(&mut c, "solves_cancelled", 1);
    assert_eq!(
        h["solves_cancelled"], 1,
        "the abandoned solve was not cancelled: {h}"
    );
    let h = wait_health(&mut c, "solves_completed", completed + 1);
    assert_eq!(h["solves_waiting_or_running"], 0, "{h}");
    assert_eq!(c.post_json("/api/predict", &json!({})).unwrap().status, 200);
    assert!(served.alive());
}

#[test]
fn beyond_loopback_every_request_needs_the_token() {
    let trained = Trained::new(&[]);
    let served = trained.serve(&["--bind", "0.0.0.0:0", "--token", "s3cret"]);
    assert!(served.url.ends_with("/?token=s3cret"), "{}", served.url);
    let port = served.addr.port();
    let local: std::net::SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
    let mut c = Client::new(local);
    assert_eq!(c.get("/api/model").unwrap().status, 403);
    let page = c.get("/?token=s3cret").unwrap();
    assert_eq!(page.status, 200);
    let cookie = page.header("set-cookie").unwrap().to_owned();
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    let mut with_cookie = Client::new(local);
    with_cookie
        .headers
        .push(format!("Cookie: {}", cookie.split(';').next().unwrap()));
    assert_eq!(with_cookie.get("/api/model").unwrap().status, 200);
    let mut bearer = Client::new(local);
    bearer.headers.push("Authorization: Bearer s3cret".into());
    assert_eq!(bearer.get("/api/model").unwrap().status, 200);
    let mut wrong = Client::new(local);
    wrong.headers.push("Authorization: Bearer s3creT".into());
    assert_eq!(wrong.get("/api/model").unwrap().status, 403);
}
