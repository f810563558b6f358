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
pub(crate) const TEST_SAMPLE: i64 = 6;

pub(crate) fn names(v: &Value, key: &str) -> Vec<String> {
    v[key]
        .as_array()
        .unwrap_or_else(|| panic!("no `{key}` in {v}"))
        .iter()
        .map(|x| x["name"].as_str().unwrap().to_owned())
        .collect()
}

pub(crate) fn series(v: &Value, name: &str) -> Vec<f64> {
    v["channels"][name]
        .as_array()
        .unwrap_or_else(|| panic!("no channel `{name}`"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

pub(crate) fn floats(v: &Value) -> Vec<f64> {
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
    let trained = Trained::shared();
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
            "design.m_c",
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
        // The level of the intervals: in (0, 1), a number, and one the calibration's 10
        // samples support (at most 10/11).
        ("/api/predict", br#"{"coverage": 1.5}"#.to_vec(), "coverage"),
        ("/api/predict", br#"{"coverage": 0}"#.to_vec(), "coverage"),
        (
            "/api/predict",
            br#"{"coverage": "0.9"}"#.to_vec(),
            "coverage",
        ),
        (
            "/api/predict",
            br#"{"coverage": 0.95}"#.to_vec(),
            "coverage",
        ),
        ("/api/solve", br#"{"coverage": 0.95}"#.to_vec(), "coverage"),
        (
            "/api/sweep",
            br#"{"parameter": "k_p", "coverage": -0.1}"#.to_vec(),
            "coverage",
        ),
        (
            "/api/sweep",
            br#"{"parameter": "k_p", "coverage": 0.95}"#.to_vec(),
            "coverage",
        ),
        // The bands asked for: channels with a band (the excitations have none).
        ("/api/predict", br#"{"bands": ["eta_1"]}"#.to_vec(), "bands"),
        ("/api/predict", br#"{"bands": "z_c"}"#.to_vec(), "bands"),
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
    input_errors_name_the_users_parameter_and_its_limit(&mut c);
    assert!(served.alive());
    calibrations_that_are_not_the_models_are_refused_at_startup(trained);
}

/// Input errors in the user's words (issue 26, items 2-3): a value that makes a field of the
/// description leave its domain is blamed on the design parameter typed, with the value typed
/// (not the description's internal field or a derived value); a speed or a length that makes
/// the run leave its track (a refusing beam, a profile) is blamed on that parameter with its
/// limit, and the limit itself is accepted while a value 1 % beyond is refused; a sweep to an
/// unreadable value blames the sweep's end.
fn input_errors_name_the_users_parameter_and_its_limit(c: &mut Client) {
    let refused = |c: &mut Client, path: &str, body: Value| -> Value {
        let a = c.post_json(path, &body).unwrap();
        assert_eq!(a.status, 400, "{path} {body}: {}", a.json());
        a.json()
    };
    for (name, value, internal) in [
        ("m_c", -1.0_f64, "bodies.c.mass"),
        ("j_c", -5.0, "bodies.c.inertia"),
        ("m_c", 1e308, "parameters.W"),
    ] {
        let v = refused(c, "/api/predict", json!({"design": {name: value}}));
        assert_eq!(v["field"], format!("design.{name}"), "{v}");
        let error = v["error"].as_str().unwrap();
        // A value of many digits is quoted in exponent form (1e308, not 309 digits).
        let typed = if value.abs() >= 1e9 {
            format!("{value:e}")
        } else {
            format!("{value}")
        };
        assert!(
            error.contains(&format!("`design.{name}` = {typed} ")),
            "{v}"
        );
        assert!(error.len() < 200, "{v}");
        let allowed = v["allowed"].as_str().unwrap();
        assert!(allowed.contains(internal), "{v}");
    }
    for name in ["v_kmh", "l_c"] {
        let v = refused(c, "/api/predict", json!({"design": {name: 1e6}}));
        assert_eq!(v["field"], format!("design.{name}"), "{v}");
        let allowed = v["allowed"].as_str().unwrap();
        let limit: f64 = allowed
            .strip_prefix("at most ")
            .and_then(|r| r.split_whitespace().next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("no limit in {v}"));
        assert!(allowed.contains(" covers x in "), "{v}");
        let at = c
            .post_json("/api/predict", &json!({"design": {name: limit}}))
            .unwrap();
        assert_eq!(
            at.status,
            200,
            "{name} = {limit} (the limit given): {}",
            at.json()
        );
        let beyond = refused(c, "/api/predict", json!({"design": {name: limit * 1.01}}));
        assert_eq!(beyond["field"], format!("design.{name}"), "{beyond}");
    }
    let v = refused(c, "/api/predict", json!({"design": {"m_c": 1e300}}));
    let error = v["error"].as_str().unwrap();
    assert!(error.contains("= 1e300 ") && error.len() < 200, "{v}");
    let v = refused(
        c,
        "/api/sweep",
        json!({"parameter": "m_c", "from": 1e300, "to": 1e300, "steps": 2}),
    );
    assert_eq!(v["field"], "from", "{v}");
    assert!(v["error"].as_str().unwrap().contains("design.m_c"), "{v}");
    let v = refused(
        c,
        "/api/sweep",
        json!({"parameter": "v_kmh", "from": 300, "to": 1e6, "steps": 3}),
    );
    assert_eq!(v["field"], "to", "{v}");
}

/// `explore --model M --calibration X`: a calibration of another model, a corrupt file or a
/// missing one exit 2 naming the file; without `--calibration` the answers say there is no
/// error bar.
fn calibrations_that_are_not_the_models_are_refused_at_startup(trained: &Trained) {
    let model = trained.file("train[algorithm=5]", "model.json");
    let model_dir = model.parent().unwrap();
    let calibrations: Vec<_> = trained
        .show("calibrate")
        .into_iter()
        .filter(|p| p.file_name().is_some_and(|n| n == "calibration.json"))
        .collect();
    let other = calibrations
        .iter()
        .find(|p| p.parent().unwrap().ends_with("algorithm-1"))
        .unwrap_or_else(|| panic!("no calibration of algorithm 1: {calibrations:?}"));
    let dir = tempfile::tempdir().unwrap();
    let corrupt = dir.path().join("calibration.json");
    std::fs::write(&corrupt, "{\"format\": ").unwrap();
    let missing = dir.path().join("nope.json");
    for (file, says) in [
        (other.clone(), "another model"),
        (corrupt.clone(), "not a calibration"),
        (missing.clone(), "no such"),
    ] {
        let o = std::process::Command::new(pino_mbd_tests::bin("explore"))
            .arg("--model")
            .arg(model_dir)
            .arg("--calibration")
            .arg(&file)
            .args(["--bind", "127.0.0.1:0"])
            .output()
            .unwrap();
        let text = pino_mbd_tests::output_text(&o);
        assert_eq!(o.status.code(), Some(2), "{}: {text}", file.display());
        assert!(
            text.contains(&file.display().to_string()) && text.contains(says),
            "the message names {} and says {says:?}: {text}",
            file.display()
        );
    }
    // Its own calibration (the stage's output directory: the model's file is found in it).
    let stage_dir = other.parent().unwrap().parent().unwrap();
    let mut cmd = std::process::Command::new(pino_mbd_tests::bin("explore"));
    cmd.arg("--model")
        .arg(model_dir)
        .arg("--calibration")
        .arg(stage_dir)
        .args(["--bind", "127.0.0.1:0"]);
    let served = crate::Served::start(cmd);
    let summary = served.client().get("/api/model").unwrap().json();
    assert_eq!(
        summary["calibration"]["n"], 10,
        "{}",
        summary["calibration"]
    );
    drop(served);
    // Without one: no error bar, and why.
    let mut cmd = std::process::Command::new(pino_mbd_tests::bin("explore"));
    cmd.arg("--model")
        .arg(model_dir)
        .args(["--bind", "127.0.0.1:0"]);
    let served = crate::Served::start(cmd);
    let mut c = served.client();
    let summary = c.get("/api/model").unwrap().json();
    assert!(summary["calibration"].is_null(), "{summary}");
    assert!(
        summary["calibration_note"]
            .as_str()
            .is_some_and(|n| n.contains("no error bar")),
        "{summary}"
    );
    let a = c
        .post_json(
            "/api/predict",
            &json!({"excitation": {"kind": "seed", "seed": 1, "id": 0}}),
        )
        .unwrap();
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let p = a.json();
    assert!(p["coverage"].is_null() && p["verdict"].is_null(), "{p}");
    assert!(p["bands"].as_object().unwrap().is_empty());
    assert!(p["indices"][0]["lo"].is_null());
    assert!(p["no_intervals"].as_str().unwrap().contains("no error bar"));
}

/// The width `hi - lo` of every index of a prediction.
fn widths(p: &Value) -> Vec<f64> {
    p["indices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["hi"].as_f64().unwrap() - i["lo"].as_f64().unwrap())
        .collect()
}

/// The calibrated parts of a prediction: every index inside its interval with a verdict per
/// limit (never `pass` when extrapolated), every predicted channel inside its band.
pub(crate) fn check_intervals(model: &Value, p: &Value, coverage: f64) {
    assert_eq!(p["coverage"].as_f64(), Some(coverage), "{}", p["coverage"]);
    let extrapolated = p["extrapolated"].as_bool().expect("extrapolated");
    assert_eq!(extrapolated, !p["outside"].as_array().unwrap().is_empty());
    let limits: BTreeMap<String, bool> = model["indices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| {
            (
                i["name"].as_str().unwrap().to_owned(),
                !i["limit"].is_null(),
            )
        })
        .collect();
    let mut verdicts = Vec::new();
    for ix in p["indices"].as_array().unwrap() {
        let name = ix["name"].as_str().unwrap();
        let (v, lo, hi) = (
            ix["value"].as_f64().unwrap(),
            ix["lo"]
                .as_f64()
                .unwrap_or_else(|| panic!("{name}: no lo: {ix}")),
            ix["hi"].as_f64().unwrap(),
        );
        assert!(lo <= v && v <= hi, "{name}: {lo} <= {v} <= {hi}");
        match ix["verdict"].as_str() {
            Some(verdict) => {
                assert!(limits[name], "{name} has no limit but a verdict");
                assert!(
                    ["pass", "uncertain", "fail"].contains(&verdict),
                    "{verdict}"
                );
                assert!(
                    !(extrapolated && verdict == "pass"),
                    "{name}: extrapolated and pass"
                );
                verdicts.push(verdict.to_owned());
            }
            None => assert!(!limits[name], "{name} has a limit but no verdict"),
        }
    }
    let combined = p["verdict"].as_str().expect("the combined verdict");
    let expected = if verdicts.iter().any(|v| v == "fail") {
        "fail"
    } else if verdicts.iter().any(|v| v == "uncertain") {
        "uncertain"
    } else {
        "pass"
    };
    assert_eq!(combined, expected, "{verdicts:?}");
    let bands = p["bands"].as_object().unwrap();
    let t = p["t"].as_array().unwrap().len();
    for c in model["channels"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let Some(b) = bands.get(name) else {
            assert_eq!(c["group"], "excitation", "{name} has no band");
            continue;
        };
        let (lo, hi, x) = (floats(&b["lo"]), floats(&b["hi"]), series(p, name));
        assert_eq!((lo.len(), hi.len()), (t, t), "{name}");
        for n in 0..t {
            assert!(lo[n] <= x[n] && x[n] <= hi[n], "{name} row {n}");
        }
        assert!(
            lo.iter().zip(&hi).any(|(l, h)| h > l),
            "{name}: a zero-width band"
        );
    }
    assert!(!bands.is_empty());
}

#[test]
fn the_pipeline_page_shows_what_pipeline_status_shows_and_the_latest_evaluation() {
    let trained = Trained::shared();
    let served = trained.serve(&[]);
    let mut c = served.client();
    let g = c.get("/api/pipeline").unwrap().json();
    let units = g["units"].as_array().unwrap();
    let status = crate::pipeline(trained.path(), &trained.sets, &["status"]);
    let text = String::from_utf8_lossy(&status.stdout);
    assert_eq!(units.len(), text.lines().count() - 2, "{text}");
    for u in units {
        let key = u["key"].as_str().unwrap();
        let state = u["state"].as_str().unwrap();
        let served = crate::SERVED_STAGES.iter().any(|s| key.starts_with(s));
        assert!(!served || state == "fresh", "{key}: {u}");
        assert!(
            text.lines()
                .any(|l| l.split_whitespace().next() == Some(key) && l.contains(state)),
            "{key} {state}: {text}"
        );
    }
    assert!(
        units.iter().any(|u| u["state"] != "fresh"),
        "the studies were not run: the page shows them as status does"
    );
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

/// Asserts that `pred` (a `/api/predict` answer of `design` on the test sample's track) equals
/// the `predict` command's table through the served surrogate, every channel to the bit.
pub(crate) fn assert_equals_predict_command(
    trained: &Trained,
    model: &Value,
    design: &BTreeMap<String, f64>,
    pred: &Value,
) {
    let dir = tempfile::tempdir().unwrap();
    let surrogate = Path::new(model["model"]["dir"].as_str().unwrap());
    let table = trained.predict(
        surrogate,
        &design_file(dir.path(), design),
        TEST_SAMPLE,
        dir.path(),
    );
    assert_eq!(floats(&pred["t"]), table.f64("t").unwrap());
    for name in names(model, "channels") {
        assert_eq!(
            series(pred, &name),
            table.f64(&name).unwrap(),
            "{name}: the page's numbers are predict's"
        );
    }
}

/// The test sample's simulated record of each of `channels` at the times of `solved` (a
/// `/api/solve` answer), read from the `simulate` stage's files.
pub(crate) fn simulated<S: AsRef<str>>(
    trained: &Trained,
    solved: &Value,
    channels: &[S],
) -> Vec<Vec<f64>> {
    let sim = trained.sample_rows(TEST_SAMPLE);
    let times = sim.f64("t").unwrap();
    let rows: Vec<usize> = floats(&solved["t"])
        .iter()
        .map(|&t| {
            (0..times.len())
                .find(|&r| (times[r] - t).abs() < 1e-9)
                .unwrap_or_else(|| panic!("no simulated row at t = {t}"))
        })
        .collect();
    channels
        .iter()
        .map(|name| {
            let col = sim.f64(name.as_ref()).unwrap();
            rows.iter().map(|&r| col[r]).collect()
        })
        .collect()
}

#[test]
fn predictions_equal_the_predict_command_and_solves_equal_the_simulation() {
    let trained = Trained::shared();
    let served = trained.serve(&[]);
    let mut c = served.client();
    let model = c.get("/api/model").unwrap().json();
    let channels = names(&model, "channels");
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
    // The surrogate's calibrations: 10 samples support 0.8 and 0.9.
    let cal = &model["calibration"];
    assert_eq!(cal["n"], 10, "{cal}");
    let supported: Vec<(f64, bool)> = cal["levels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            (
                l["level"].as_f64().unwrap(),
                l["supported"].as_bool().unwrap(),
            )
        })
        .collect();
    assert_eq!(supported, [(0.8, true), (0.9, true), (0.95, false)]);
    assert!(cal["levels"][2]["why"].as_str().unwrap().contains("0.95"));
    check_intervals(&model, &served_pred, 0.9);
    assert_eq!(served_pred["extrapolated"], true);
    assert_equals_predict_command(trained, &model, &design, &served_pred);

    // The test sample's own design through the solver equals its simulated record.
    let a = c
        .post_json(
            "/api/solve",
            &json!({"design": test["design"], "excitation": excitation}),
        )
        .unwrap();
    assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
    let solved = a.json();
    for (name, expected) in channels.iter().zip(simulated(trained, &solved, &channels)) {
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
    check_intervals(&model, &pred, 0.9);
    assert_eq!(pred["extrapolated"], false);
    // A lower level: every interval at most as wide, some narrower.
    let at_08 = c
        .post_json(
            "/api/predict",
            &json!({"design": test["design"], "excitation": excitation, "coverage": 0.8}),
        )
        .unwrap()
        .json();
    check_intervals(&model, &at_08, 0.8);
    // Only the bands asked for (the page asks for the channels it plots), the same values.
    let some = c
        .post_json(
            "/api/predict",
            &json!({"design": test["design"], "excitation": excitation, "bands": ["z_c", "p_1"]}),
        )
        .unwrap()
        .json();
    let asked: Vec<&String> = some["bands"].as_object().unwrap().keys().collect();
    assert_eq!(asked, ["p_1", "z_c"]);
    assert_eq!(some["bands"]["z_c"], pred["bands"]["z_c"]);
    assert_eq!(some["indices"], pred["indices"]);
    let (w8, w9) = (widths(&at_08), widths(&pred));
    assert!(w8.iter().zip(&w9).all(|(a, b)| a <= b), "{w8:?} {w9:?}");
    assert!(w8.iter().zip(&w9).any(|(a, b)| a < b), "{w8:?} {w9:?}");
    // The solve says whether the solver's curves and indices lie inside the prediction's.
    assert_eq!(solved["coverage"].as_f64(), Some(0.9));
    let inside = solved["inside"].as_object().unwrap();
    let bands = pred["bands"].as_object().unwrap();
    assert_eq!(inside.len(), bands.len(), "{inside:?}");
    for (name, band) in bands {
        let (lo, hi, x) = (
            floats(&band["lo"]),
            floats(&band["hi"]),
            series(&solved, name),
        );
        let n_in = (0..x.len())
            .filter(|&n| lo[n] <= x[n] && x[n] <= hi[n])
            .count();
        let f = inside[name]["fraction_inside"].as_f64().unwrap();
        assert!(
            (f - n_in as f64 / x.len() as f64).abs() <= 2.0 / x.len() as f64,
            "{name}: {f} vs {n_in}/{}",
            x.len()
        );
        assert_eq!(inside[name]["inside"].as_bool(), Some(f == 1.0), "{name}");
    }
    let index_inside = solved["index_inside"].as_object().unwrap();
    for (p, s) in pred["indices"]
        .as_array()
        .unwrap()
        .iter()
        .zip(solved["indices"].as_array().unwrap())
    {
        let name = p["name"].as_str().unwrap();
        let x = s["value"].as_f64().unwrap();
        let within = p["lo"].as_f64().unwrap() <= x && x <= p["hi"].as_f64().unwrap();
        assert_eq!(index_inside[name].as_bool(), Some(within), "{name}");
    }
    // The sweep's index curves carry their intervals.
    let sw = c
        .post_json(
            "/api/sweep",
            &json!({"design": test["design"], "excitation": excitation, "parameter": "k_p", "steps": 4, "coverage": 0.8}),
        )
        .unwrap();
    assert_eq!(sw.status, 200, "{}", String::from_utf8_lossy(&sw.body));
    let sw = sw.json();
    assert_eq!(sw["coverage"].as_f64(), Some(0.8));
    for (name, values) in sw["indices"].as_object().unwrap() {
        let iv = &sw["intervals"][name];
        let (lo, hi, v) = (floats(&iv["lo"]), floats(&iv["hi"]), floats(values));
        assert_eq!((lo.len(), hi.len()), (4, 4), "{name}");
        for k in 0..4 {
            assert!(lo[k] <= v[k] && v[k] <= hi[k], "{name} design {k}");
        }
        assert_eq!(iv["verdict"].as_array().unwrap().len(), 4);
    }
    assert_eq!(sw["verdict"].as_array().unwrap().len(), 4);
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
    // Solves of a few seconds: the full track, 3 s runs. Only the model and its calibration
    // are made: the studies' hundreds of solves would cost minutes at this duration.
    let trained = Trained::up_to(
        &[
            "simulate.duration=3.0",
            "irregularity.length=540.0",
            "constants.system_values.n_f=900",
            "constants.system_values.n_m=450",
        ],
        &[crate::SERVED_SURROGATE],
    );
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
    const TOKEN: &str = "s3cret-token-0123";
    let trained = Trained::shared();
    let served = trained.serve(&["--bind", "0.0.0.0:0", "--token", TOKEN]);
    assert!(
        served.url.ends_with(&format!("/?token={TOKEN}")),
        "{}",
        served.url
    );
    let port = served.addr.port();
    let local: std::net::SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
    let mut c = Client::new(local);
    assert_eq!(c.get("/api/model").unwrap().status, 403);
    assert_eq!(
        c.get("/api/model?token=").unwrap().status,
        403,
        "an empty token passed"
    );
    let page = c.get(&format!("/?token={TOKEN}")).unwrap();
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
    // The scheme is case-insensitive (RFC 7235); the token is not.
    for scheme in ["Bearer", "bearer", "BEARER"] {
        let mut bearer = Client::new(local);
        bearer
            .headers
            .push(format!("Authorization: {scheme} {TOKEN}"));
        assert_eq!(bearer.get("/api/model").unwrap().status, 200, "{scheme}");
    }
    let mut wrong = Client::new(local);
    wrong
        .headers
        .push(format!("Authorization: Bearer {}", TOKEN.to_uppercase()));
    assert_eq!(wrong.get("/api/model").unwrap().status, 403);
}

#[test]
fn a_token_shorter_than_16_characters_is_refused_at_startup() {
    let trained = Trained::shared();
    for token in ["", "fifteen-chars-x"] {
        let o = std::process::Command::new(pino_mbd_tests::bin("explore"))
            .arg("-C")
            .arg(trained.path())
            .args(["--bind", "0.0.0.0:0", "--token", token])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{token:?}: {err}");
        assert!(
            err.contains("--token") && err.contains("at least 16"),
            "{err}"
        );
    }
}

#[test]
fn every_error_is_json_and_a_post_must_say_it_is_json() {
    let trained = Trained::shared();
    let served = trained.serve(&[]);
    let mut c = served.client();
    let predict = json!({}).to_string();
    // A cross-site form or `fetch` without a preflight sends text/plain or a form type.
    for content_type in [
        None,
        Some("text/plain"),
        Some("application/x-www-form-urlencoded"),
        Some("multipart/form-data; boundary=x"),
    ] {
        let mut raw = Client::new(served.addr);
        let a = match content_type {
            None => raw.request_without_content_type("POST", "/api/predict", predict.as_bytes()),
            Some(t) => {
                raw.headers.push(format!("Content-Type: {t}"));
                raw.request_without_content_type("POST", "/api/predict", predict.as_bytes())
            }
        }
        .unwrap();
        assert_eq!(a.status, 415, "{content_type:?}");
        assert_eq!(a.json()["field"], "Content-Type");
    }
    let mut charset = Client::new(served.addr);
    charset
        .headers
        .push("Content-Type: Application/JSON; charset=utf-8".into());
    assert_eq!(
        charset
            .request_without_content_type("POST", "/api/predict", predict.as_bytes())
            .unwrap()
            .status,
        200
    );
    // The framework's own answers carry the API's JSON error body too.
    let wrong_method = c.get("/api/predict").unwrap();
    assert_eq!(wrong_method.status, 405);
    assert!(wrong_method
        .header("content-type")
        .unwrap()
        .starts_with("application/json"));
    assert!(wrong_method.json()["error"]
        .as_str()
        .unwrap()
        .contains("method"));
    assert!(wrong_method
        .header("allow")
        .is_some_and(|a| a.contains("POST")));
    let big = vec![b' '; pino_explore::server::BODY_LIMIT + 1];
    let too_large = c.request("POST", "/api/predict", &big).unwrap();
    assert_eq!(too_large.status, 413);
    assert!(too_large
        .header("content-type")
        .unwrap()
        .starts_with("application/json"));
    assert_eq!(too_large.json()["field"], "body");
    let missing = c.get("/api/nope").unwrap();
    assert_eq!(missing.status, 404);
    assert!(missing.json()["error"].is_string());
    let foreign = Client::new(served.addr)
        .with_host("attacker.example:80")
        .get("/api/model")
        .unwrap();
    assert_eq!(foreign.status, 403);
    assert!(foreign.json()["error"].is_string());
    the_documented_statuses_and_metadata_keys_are_the_servers(&mut c);
}

/// docs/explore.md says which error statuses carry a JSON body and which `pino.*` keys a
/// downloaded Parquet file carries: the statuses listed are exactly the ones the server gives
/// (each provoked in these tests: 403, 404, 405, 413, 415 above, 400, 408 and 431 in
/// `serving`, 409 in `studies`, 429 in
/// `the_solver_is_bounded_and_a_client_that_leaves_is_cancelled`; 500 only for a fault of the
/// server itself), and the keys are exactly the downloaded file's.
fn the_documented_statuses_and_metadata_keys_are_the_servers(c: &mut Client) {
    let docs = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/explore.md"))
        .unwrap();
    let flat = docs.split_whitespace().collect::<Vec<_>>().join(" ");
    let between = |from: &str, to: &str| -> String {
        let a = flat
            .find(from)
            .unwrap_or_else(|| panic!("docs/explore.md: no `{from}`"));
        let b = a + flat[a..]
            .find(to)
            .unwrap_or_else(|| panic!("docs/explore.md: no `{to}` after `{from}`"));
        flat[a..b].to_owned()
    };
    let sentence = between(
        "every error status carries such a body:",
        "only for a fault",
    );
    let documented: Vec<u16> = sentence
        .split(|ch: char| !ch.is_ascii_digit())
        .filter(|w| w.len() == 3)
        .map(|w| w.parse().unwrap())
        .collect();
    assert_eq!(
        documented,
        [400, 403, 404, 405, 408, 409, 413, 415, 429, 431, 500],
        "{sentence}"
    );

    let answer = c
        .post_json("/api/download/curves?format=parquet", &json!({}))
        .unwrap();
    assert_eq!(answer.status, 200);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("curves.parquet");
    std::fs::write(&file, &answer.body).unwrap();
    let served: Vec<String> = pino_data::metadata::read_metadata(&file)
        .unwrap()
        .key_value
        .into_keys()
        .filter(|k| k.starts_with("pino."))
        .collect();
    let paragraph = between("`POST /api/download/curves", "### `GET /api/health`");
    let mut named: Vec<String> = paragraph
        .split('`')
        .filter(|w| w.starts_with("pino.") && !w.contains(' '))
        .map(str::to_owned)
        .collect();
    named.sort();
    named.dedup();
    assert_eq!(
        named, served,
        "docs/explore.md names {named:?}, the file carries {served:?}"
    );
}

/// Polls the Studies list until the started study `name` has ended (two minutes at most).
pub(crate) fn wait_study(c: &mut Client, name: &str) -> Value {
    let t0 = Instant::now();
    loop {
        let list = c.get("/api/studies").unwrap().json();
        let s = list["explorer"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["name"] == name)
            .unwrap_or_else(|| panic!("{name} is not listed: {list}"))
            .clone();
        if s["state"] != "running" {
            return s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "{name} still running: {s}"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn a_study_started_from_the_sweep_view_is_the_stage_s_study_on_the_served_model() {
    let trained = Trained::shared();
    let dir = tempfile::tempdir().unwrap();
    let study_dir = dir.path().join("studies");
    let dir_arg = study_dir.to_str().unwrap();
    let mut served = trained.serve(&["--study-dir", dir_arg]);
    let mut c = served.client();
    let model = c.get("/api/model").unwrap().json();
    let params = names(&model, "parameters");
    let limits = &model["studies"];
    assert_eq!(limits["max_varied"], 2, "{model}");

    // The pipeline's studies, of both its study stages in the pipeline's order, are listed
    // with their state (the shared workspace runs none).
    let list = c.get("/api/studies").unwrap().json();
    let pipeline: Vec<(&str, &str)> = list["pipeline"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["name"].as_str().unwrap(), s["state"].as_str().unwrap()))
        .collect();
    assert_eq!(
        pipeline,
        [
            ("drivers", "never run"),
            ("quiet_car_body", "never run"),
            ("wheel_unloading", "never run")
        ],
        "{list}"
    );
    assert_eq!(list["explorer"], json!([]));

    // Bad starts: 400 naming the field; nothing is claimed in the directory.
    let p0 = params[0].as_str();
    let one = json!([{"name": p0}]);
    for (body, field) in [
        (json!({"kind": "optimise", "parameters": one}), "kind"),
        (json!({"parameters": one}), "kind"),
        (
            json!({"kind": "monte_carlo", "parameters": []}),
            "parameters",
        ),
        (
            json!({"kind": "monte_carlo", "parameters": [{"name": p0}, {"name": p0}]}),
            "parameters[1].name",
        ),
        (
            json!({"kind": "monte_carlo", "parameters": [{"name": "nope"}]}),
            "parameters[0].name",
        ),
        (
            json!({"kind": "monte_carlo", "parameters": [{"name": p0, "from": 2.0, "to": 1.0}]}),
            "parameters[0].to",
        ),
        (
            json!({"kind": "monte_carlo", "parameters": one, "n": 5001}),
            "n",
        ),
        (
            json!({"kind": "sensitivity", "parameters": one, "n": 48}),
            "n",
        ),
        (
            json!({"kind": "sensitivity", "parameters": one, "n": 16, "solver_check": 3}),
            "solver_check",
        ),
        (
            json!({"kind": "monte_carlo", "parameters": one, "n": 10, "solver_check": 11}),
            "solver_check",
        ),
        (
            json!({"kind": "monte_carlo", "parameters": one, "design": {"nope": 1.0}}),
            "design.nope",
        ),
    ] {
        let a = c.post_json("/api/studies", &body).unwrap();
        assert_eq!(a.status, 400, "{body}: {}", a.json());
        assert_eq!(a.json()["field"], field, "{body}: {}", a.json());
    }
    assert!(!study_dir.exists(), "a refused study claimed a directory");

    // A Monte Carlo study of one parameter over part of its range, the others at a design.
    let range = &model["parameters"][0];
    let (lo, hi) = (
        range["min"].as_f64().unwrap(),
        range["max"].as_f64().unwrap(),
    );
    let (from, to) = (lo + 0.25 * (hi - lo), lo + 0.75 * (hi - lo));
    let p1 = params[1].as_str();
    let fixed = model["parameters"][1]["nominal"].as_f64().unwrap() * 1.01;
    let body = json!({"kind": "monte_carlo", "n": 40, "solver_check": 2,
                      "parameters": [{"name": p0, "from": from, "to": to}],
                      "design": {p1: fixed}});
    let a = c.post_json("/api/studies", &body).unwrap();
    assert_eq!(a.status, 202, "{}", a.json());
    let name = a.json()["name"].as_str().unwrap().to_owned();
    assert_eq!(name, format!("monte_carlo-{p0}-1"));
    let s = wait_study(&mut c, &name);
    assert_eq!(s["state"], "finished", "{s}");
    assert_eq!(s["kind"], "monte_carlo");
    assert_eq!(s["table"]["file"], "summary.csv");
    let files: Vec<&str> = s["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    for f in [
        "evaluations.parquet",
        "solver.parquet",
        "summary.md",
        "summary.csv",
        "histograms.png",
        "study.yaml",
    ] {
        assert!(files.contains(&f), "{f} missing: {files:?}");
    }
    assert!(s["summary_md"].as_str().unwrap().contains(&name), "{s}");

    // Its declaration: the parameter uniform over the interval, every other one fixed at the
    // design's value (nominal where the request named none).
    let decl: Value = serde_yaml::from_str(
        &std::fs::read_to_string(study_dir.join(&name).join("study.yaml")).unwrap(),
    )
    .unwrap();
    assert_eq!(decl["parameters"][p0], json!({"uniform": [from, to]}));
    assert_eq!(decl["parameters"][p1], json!(fixed));
    for (k, p) in params.iter().enumerate().skip(2) {
        assert_eq!(
            decl["parameters"][p.as_str()],
            model["parameters"][k]["nominal"],
            "{p}"
        );
    }

    // The evaluations: 40 designs, the varied parameter inside the interval, and each design's
    // indices those `/api/predict` gives for the same design under the same generated profile
    // (the study's seed, the design's excitation id).
    let t =
        pino_data::read_parquet(&study_dir.join(&name).join("evaluations.parquet"), None).unwrap();
    let x = t.f64(p0).unwrap();
    assert_eq!(x.len(), 40);
    assert!(x.iter().all(|v| (from..=to).contains(v)), "{x:?}");
    assert!(t.f64(p1).unwrap().iter().all(|&v| v == fixed));
    let excitation = t.i64("excitation").unwrap();
    for row in [0, 39] {
        let design: serde_json::Map<String, Value> = params
            .iter()
            .map(|p| (p.clone(), json!(t.f64(p).unwrap()[row])))
            .collect();
        let p = c
            .post_json(
                "/api/predict",
                &json!({"design": design, "bands": false,
                        "excitation": {"kind": "seed", "seed": 7, "id": excitation[row]}}),
            )
            .unwrap()
            .json();
        for i in p["indices"].as_array().unwrap() {
            let name = i["name"].as_str().unwrap();
            let stored = t.f64(name).unwrap()[row];
            let got = i["value"].as_f64().unwrap();
            assert!(
                (got - stored).abs() <= 1e-9 * stored.abs().max(1e-12),
                "design {row}, {name}: predict {got}, study {stored}"
            );
        }
    }

    // Its files are served; nothing else is.
    let md = c
        .get(&format!("/api/studies/explorer/{name}/summary.md"))
        .unwrap();
    assert_eq!(md.status, 200);
    assert!(md
        .header("content-type")
        .unwrap()
        .starts_with("text/markdown"));
    let png = c
        .get(&format!("/api/studies/explorer/{name}/histograms.png"))
        .unwrap();
    assert_eq!((png.status, &png.body[1..4]), (200, &b"PNG"[..]));
    for bad in [
        format!("/api/studies/explorer/{name}/nope.csv"),
        format!("/api/studies/explorer/{name}/..%2Fstudy.yaml"),
        format!("/api/studies/other/{name}/summary.md"),
        "/api/studies/explorer/nope/summary.md".to_owned(),
        "/api/studies/pipeline/drivers/summary.md".to_owned(),
    ] {
        assert_eq!(c.get(&bad).unwrap().status, 404, "{bad}");
    }
    assert!(served.alive());

    // A later session on the same directory lists it again, finished, and names the next
    // study of the same parameter `-2`.
    drop(served);
    let served = trained.serve(&["--study-dir", dir_arg]);
    let mut c = served.client();
    let again = c.get("/api/studies").unwrap().json();
    assert_eq!(again["explorer"][0]["name"], name.as_str(), "{again}");
    assert_eq!(again["explorer"][0]["state"], "finished");
    let a = c
        .post_json(
            "/api/studies",
            &json!({"kind": "monte_carlo", "n": 10, "parameters": [{"name": p0}]}),
        )
        .unwrap();
    assert_eq!(a.json()["name"], format!("monte_carlo-{p0}-2"));
    assert_eq!(
        wait_study(&mut c, &format!("monte_carlo-{p0}-2"))["state"],
        "finished"
    );
}

/// Whether the server closed `s` within its read timeout: EOF or a reset, not a timeout.
pub(crate) fn closed_by_server(s: &mut std::net::TcpStream) -> bool {
    use std::io::Read;
    let mut buf = [0u8; 4096];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => continue, // an answer before the close
            Err(e) => {
                return !matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                )
            }
        }
    }
}

#[test]
fn idle_and_half_sent_connections_are_closed_and_the_connection_cap_holds() {
    use std::io::Write;
    use std::net::TcpStream;
    let trained = Trained::shared();
    let served = trained.serve(&["--header-timeout", "1"]);
    let connect = || {
        let s = TcpStream::connect(served.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        s
    };
    let mut silent = connect();
    let mut half = connect();
    half.write_all(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
        .unwrap();
    let mut kept_alive = connect();
    let host = format!("127.0.0.1:{}", served.addr.port());
    kept_alive
        .write_all(format!("GET /api/health HTTP/1.1\r\nHost: {host}\r\n\r\n").as_bytes())
        .unwrap();
    for (what, s) in [
        ("a connection that sends nothing", &mut silent),
        ("a connection stuck mid-header", &mut half),
        (
            "a kept-alive connection left idle after its answer",
            &mut kept_alive,
        ),
    ] {
        assert!(
            closed_by_server(s),
            "{what} was not closed by the 1-s timeout"
        );
    }
    let mut c = served.client();
    assert_eq!(c.post_json("/api/predict", &json!({})).unwrap().status, 200);

    // A cap of 4 connections: the fifth is closed at once while four idle ones hold theirs
    // (a 60-s timeout, so none of them is closed meanwhile); then predicts answer again.
    let capped = trained.serve(&["--header-timeout", "60", "--max-connections", "4"]);
    // Each of the four is answered once, so the server holds it, kept alive.
    let hold: Vec<Client> = (0..4)
        .map(|_| {
            let mut c = capped.client();
            assert_eq!(c.get("/api/health").unwrap().status, 200);
            c
        })
        .collect();
    let mut fifth = TcpStream::connect(capped.addr).unwrap();
    fifth
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    assert!(
        closed_by_server(&mut fifth),
        "the fifth connection was kept"
    );
    drop(hold);
    let t0 = Instant::now();
    let mut c = capped.client();
    loop {
        match c.get("/api/health") {
            Ok(a) if a.status == 200 => break,
            _ if t0.elapsed() < Duration::from_secs(10) => {
                std::thread::sleep(Duration::from_millis(100))
            }
            other => panic!("no answer after the idle connections left: {other:?}"),
        }
    }
}
