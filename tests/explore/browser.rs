//! The explorer as a user sees it: Chromium (Debian's, driven by the pinned `playwright-core`
//! of `tests/browser`) opens the page `explore` serves for a small trained model of the real
//! pipeline and works it (`tests/browser/explore.mjs`: parameters, test sample, "Solve
//! exactly", a slider move and a drag the plots follow, a value outside the training range,
//! refused inputs and a failed sweep marked out of date, a sweep, the design download, "Pin as
//! A" and a solve while requests are in flight or failed, a model without sampled parameters,
//! the pipeline page, studies started from the sweep view, one of 5000 designs running beside
//! a slider move and cancelled from the Studies page),
//! saving a screenshot of each step under `target/explore-browser/`. This test then checks
//! what the page plotted against the real `predict` and `simulate` outputs.
//!
//! Needs Node.js (20+) on PATH, `npm ci --prefix tests/browser` once, and Chromium at
//! `/usr/bin/chromium` (or `CHROMIUM`), which `scripts/test` installs when they are missing;
//! it fails, never skips, without them. With
//! `EXPLORE_BENCH=1` the script also prints the slider-release-to-redraw latency (p50/p99 over
//! 30 moves, measured in the page); nothing is asserted about it.

use crate::Trained;
use pino_data::{read_parquet, Table};
use pino_mbd_tests::{output_text, workspace_root};
use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

/// Where the screenshots, the downloaded design and `results.json` stay after the test.
fn out_dir() -> PathBuf {
    workspace_root().join("target").join("explore-browser")
}

#[test]
fn a_user_explores_designs_in_a_real_browser() {
    let trained = Trained::shared();
    let mut served = trained.serve(&[]);
    let out = out_dir();
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).expect("target/explore-browser");

    let script = workspace_root().join("tests/browser/explore.mjs");
    let o = Command::new("node")
        .current_dir(workspace_root())
        .arg(&script)
        .arg(&served.url)
        .arg(&out)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "`node` (Node.js 20 or newer, from PATH) does not run: {e}; install it \
                 (apt-get install nodejs npm), then `npm ci --prefix tests/browser` (or run \
                 `scripts/test`, which installs what is missing)"
            )
        });
    println!("{}", output_text(&o));
    assert!(
        o.status.success(),
        "the browser run failed (screenshots in {}):\n{}",
        out.display(),
        output_text(&o)
    );
    assert!(served.alive(), "explore exited during the browser run");

    let r: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("results.json")).expect("results.json"),
    )
    .expect("results.json is JSON");
    for s in arr(&r["steps"]) {
        let png = out.join(str_of(&s["screenshot"]));
        let len = std::fs::metadata(&png).map(|m| m.len()).unwrap_or(0);
        assert!(
            len > 1000,
            "screenshot {} is missing or empty",
            png.display()
        );
    }
    let names: Vec<&str> = arr(&r["steps"])
        .iter()
        .map(|s| str_of(&s["name"]))
        .collect();
    assert_eq!(
        names,
        [
            "loaded",
            "test-sample",
            "bands",
            "level",
            "solve",
            "slider",
            "drag-live",
            "outside",
            "invalid",
            "invalid-seed",
            "sweep",
            "sweep-failed",
            "download",
            "pin-in-flight",
            "solve-after-failed-prediction",
            "solve-cancelled",
            "no-parameters",
            "pipeline",
            "study-start",
            "studies",
            "study-beside",
            "study-cancel"
        ]
    );
    check_started_study(trained, &r);

    // The parameter rows are the model's sampled parameters, in its order.
    let ranges = read_parquet(&trained.file("sample-params", "ranges.parquet"), None).unwrap();
    let sampled = ranges.str("name").unwrap();
    let shown: Vec<&str> = arr(&r["parameters"]).iter().map(str_of).collect();
    assert_eq!(shown, sampled, "the page's parameter rows");
    let labels: Vec<&str> = arr(&r["parameterLabels"]).iter().map(str_of).collect();
    assert_eq!(labels, sampled, "the page's parameter labels");

    // Choosing the test sample set the design to its sampled parameters.
    let sample_id = r["sample"]["sample_id"].as_i64().expect("sample_id");
    let params = read_parquet(&trained.file("sample-params", "params.parquet"), None).unwrap();
    let row = params
        .i64("sample_id")
        .unwrap()
        .iter()
        .position(|&id| id == sample_id)
        .unwrap_or_else(|| panic!("sample {sample_id} is not in params.parquet"));
    let sample_design: BTreeMap<&str, f64> = sampled
        .iter()
        .map(|n| (n.as_str(), params.f64(n).unwrap()[row]))
        .collect();
    let test_excitation = serde_json::json!({"kind": "test", "sample_id": sample_id});

    // The bands: visible on every response chart (pixels of the band's fill), the intervals and
    // three-valued verdicts beside the indices; switching the level narrowed the intervals.
    for (group, p) in obj(&r["bands"]["pixels"]) {
        if group != "excitation" {
            assert!(num(&p["pixels"]) > 200.0, "{group}: {p}");
        }
    }
    let verdict = str_of(&r["bands"]["verdict"]);
    assert!(
        verdict.starts_with("at 90 %: ")
            && verdict.contains(str_of(&r["bands"]["prediction_verdict"])),
        "{verdict}"
    );
    let level = &r["level"];
    assert_eq!(num(&level["coverage"]), 0.8);
    assert!(str_of(&level["verdict"]).starts_with("at 80 %: "));
    let (w9, w8) = (arr(&level["widths_09"]), arr(&level["widths_08"]));
    assert!(w8.iter().zip(w9).all(|(a, b)| num(a) <= num(b)), "{level}");
    assert_ne!(
        r["bands"]["rows"], level["rows"],
        "the intervals shown did not change with the level"
    );

    // "Solve exactly" for the test sample's own design and profile: the dashed curves are the
    // `simulate` stage's output for that sample.
    let solve = &r["solve"];
    assert_eq!(solve["excitation"], test_excitation);
    assert_eq!(solve["answer"]["excitation"], test_excitation);
    for d in [&solve["design"], &solve["answer"]["design"]] {
        assert_same_design(obj(d), &sample_design, "the solved design");
    }
    let sim = trained.sample_rows(sample_id);
    let compared = compare_plotted(&solve["charts"], " (solver)", &sim, 1e-9, 1e-300);
    assert!(
        compared >= 2,
        "only {compared} solver curves were plotted after the solve"
    );

    // The slider move: the plotted curves are `predict`'s for the same design.
    let slider = &r["slider"];
    assert!(slider["changed"].as_bool() == Some(true));
    assert_ne!(slider["from"], slider["to"]);
    let param = str_of(&slider["param"]);
    assert_eq!(slider["design"][param], slider["to"]);
    assert_eq!(slider["excitation"], test_excitation);
    let scratch = tempfile::tempdir().expect("scratch directory");
    let equivalent = scratch.path().join("slider-design.yaml");
    let sets = serde_json::json!({"sets": [slider["design"]]});
    std::fs::write(&equivalent, serde_yaml::to_string(&sets).unwrap()).unwrap();
    let predicted = trained.predict(
        &served_surrogate(trained),
        &equivalent,
        sample_id,
        scratch.path(),
    );
    let compared = compare_plotted(&slider["charts"], "", &predicted, 1e-5, 1e-12);
    assert!(
        compared >= 2,
        "only {compared} curves were plotted after the slider move"
    );
    // ... and the move changed them by far more than that comparison's tolerance, so it tells
    // this design's curves from the previous one's.
    let change = largest_change(&solve["charts"], &slider["charts"]);
    assert!(
        change > 1e-3,
        "moving {param} changed the plotted curves by at most {change:e} (relative)"
    );

    // A typed value outside the training range is flagged.
    let outside = &r["outside"];
    let oname = str_of(&outside["param"]);
    let value = outside["value"].as_f64().unwrap();
    let max = ranges.f64("max").unwrap()[sampled.iter().position(|n| n == oname).unwrap()];
    assert!(
        value > max,
        "{oname} = {value} is not above the range's {max}"
    );
    assert_eq!(outside["design"][oname].as_f64(), Some(value));
    let banner = str_of(&outside["banner"]);
    assert!(
        banner.contains("outside training range") && banner.contains(oname),
        "banner: {banner:?}"
    );
    assert_eq!(str_of(&outside["row_flag"]), "outside training range");
    assert_eq!(outside["row_class_outside"], true);
    assert!(
        arr(&outside["answer_outside"])
            .iter()
            .any(|o| o["name"] == oname),
        "{outside}"
    );

    // An invalid input is named as the user typed it, its row marked, the results stale
    // until it is fixed (the message is the server's, in the design parameter's words).
    let invalid = &r["invalid"];
    let iname = str_of(&invalid["param"]);
    assert_eq!(invalid["field"], format!("design.{iname}"), "{invalid}");
    assert!(
        str_of(&invalid["message"]).contains(&format!("`design.{iname}` = -1 is out of range")),
        "{invalid}"
    );
    assert!(str_of(&invalid["allowed"]).contains("bodies."), "{invalid}");
    for key in ["rowInvalid", "staleBanner", "cleared"] {
        assert_eq!(invalid[key], true, "{key}: {invalid}");
    }

    // The sweep: `steps` designs evenly spaced over the asked range, every index for each,
    // `solve_points` of them solved.
    let sweep = &r["sweep"];
    let (req, ans) = (&sweep["request"], &sweep["answer"]);
    let steps = req["steps"].as_u64().unwrap() as usize;
    assert_eq!(ans["parameter"], req["parameter"]);
    let values: Vec<f64> = arr(&ans["values"]).iter().map(num).collect();
    assert_eq!(values.len(), steps, "{ans}");
    let (from, to) = (num(&req["from"]), num(&req["to"]));
    for (i, v) in values.iter().enumerate() {
        let want = from + (to - from) * i as f64 / (steps - 1) as f64;
        assert!(
            (v - want).abs() <= 1e-9 * (to - from).abs(),
            "value {i}: {v} != {want}"
        );
    }
    let indices = obj(&ans["indices"]);
    assert!(!indices.is_empty());
    for (name, series) in indices {
        assert_eq!(arr(series).len(), steps, "index {name}");
    }
    assert!(indices.contains_key(str_of(&req["index"])));
    assert_eq!(arr(&ans["outside"]).len(), steps);
    assert_eq!(
        arr(&ans["solved"]).len() as u64,
        req["solve_points"].as_u64().unwrap()
    );
    assert_eq!(
        arr(&sweep["chart"]["data"][0]).len(),
        steps,
        "sweep chart x"
    );

    // The downloaded design.yaml: `predict --params` reads it and gives what the page plotted
    // for that design.
    let download = &r["download"];
    assert_eq!(download["excitation"], test_excitation);
    let file = out.join(str_of(&download["file"]));
    let yaml: serde_yaml::Value =
        serde_yaml::from_str(&std::fs::read_to_string(&file).expect("design.yaml")).unwrap();
    let set = &yaml["sets"][0];
    let page_design: BTreeMap<&str, f64> = obj(&download["design"])
        .iter()
        .map(|(k, v)| (k.as_str(), num(v)))
        .collect();
    for (name, want) in &page_design {
        let got = set[*name]
            .as_f64()
            .unwrap_or_else(|| panic!("design.yaml has no {name}"));
        assert!(
            close(got, *want, 1e-15),
            "design.yaml {name} = {got}, page {want}"
        );
    }
    let read_back = trained.predict(&served_surrogate(trained), &file, sample_id, scratch.path());
    let compared = compare_plotted(&download["charts"], "", &read_back, 1e-5, 1e-12);
    assert!(
        compared >= 2,
        "only {compared} curves plotted at the download"
    );
    let first = &download["charts"]["displacement"]["labels"][1];
    println!(
        "browser test: {} screenshots in {}; the first channel ({first}) of design.yaml through \
         predict equals the page's",
        names.len(),
        out.display()
    );
}

/// The directory of the surrogate `explore` serves.
fn served_surrogate(trained: &Trained) -> PathBuf {
    let manifest = trained.file(crate::SERVED_SURROGATE, "surrogate.json");
    manifest
        .parent()
        .expect("surrogate directory")
        .to_path_buf()
}

/// Compares every plotted series whose label is `CHANNEL` + `suffix` (`charts`: {GROUP:
/// {labels, data}}, data[0] the times) with `table`'s column CHANNEL at the same `t`:
/// `|page - table| <= rel * max|table| + abs` over the plotted times. Returns how many series
/// were compared.
fn compare_plotted(charts: &Value, suffix: &str, table: &Table, rel: f64, abs: f64) -> usize {
    let t = table.f64("t").unwrap();
    let mut compared = 0;
    for (group, chart) in obj(charts) {
        if group == "sweep" {
            continue;
        }
        let labels: Vec<&str> = arr(&chart["labels"]).iter().map(str_of).collect();
        let data = arr(&chart["data"]);
        let x: Vec<f64> = arr(&data[0]).iter().map(num).collect();
        // The table's row at each plotted time.
        let rows: Vec<usize> = x
            .iter()
            .map(|&xi| {
                let i = t.partition_point(|&tj| tj < xi - 1e-9);
                assert!(
                    i < t.len() && (t[i] - xi).abs() <= 1e-9,
                    "{group}: no row at t = {xi} in {}",
                    table.origin().display()
                );
                i
            })
            .collect();
        for (j, label) in labels.iter().enumerate().skip(1) {
            let Some(channel) = label.strip_suffix(suffix) else {
                continue;
            };
            if channel.contains(" (") {
                continue;
            }
            let want = table
                .f64(channel)
                .unwrap_or_else(|e| panic!("{group}: plotted {label:?}, no column: {e}"));
            let got: Vec<f64> = arr(&data[j])
                .iter()
                .map(|v| {
                    v.as_f64()
                        .unwrap_or_else(|| panic!("{label}: non-number {v}"))
                })
                .collect();
            assert_eq!(got.len(), rows.len(), "{label}: length");
            let scale = rows.iter().map(|&i| want[i].abs()).fold(0.0, f64::max);
            let tol = rel * scale + abs;
            for (k, &i) in rows.iter().enumerate() {
                assert!(
                    (got[k] - want[i]).abs() <= tol,
                    "{group}/{label} at t = {}: page {} vs {} {} (tolerance {tol:e})",
                    x[k],
                    got[k],
                    table.origin().display(),
                    want[i]
                );
            }
            compared += 1;
        }
    }
    compared
}

/// The largest change, relative to the channel's largest magnitude before, of a prediction
/// series (label = channel name) plotted in both `before` and `after`.
fn largest_change(before: &Value, after: &Value) -> f64 {
    let mut largest: f64 = 0.0;
    for (group, chart) in obj(after) {
        let Some(old) = before.get(group) else {
            continue;
        };
        let old_labels = arr(&old["labels"]);
        for (j, label) in arr(&chart["labels"]).iter().enumerate().skip(1) {
            let Some(k) = old_labels.iter().position(|l| l == label) else {
                continue;
            };
            if str_of(label).contains(" (") {
                continue;
            }
            let a: Vec<f64> = arr(&chart["data"][j]).iter().map(num).collect();
            let b: Vec<f64> = arr(&old["data"][k]).iter().map(num).collect();
            let scale = b.iter().map(|v| v.abs()).fold(0.0, f64::max);
            if scale > 0.0 && a.len() == b.len() {
                let d = a
                    .iter()
                    .zip(&b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                largest = largest.max(d / scale);
            }
        }
    }
    largest
}

fn assert_same_design(page: &Map<String, Value>, sample: &BTreeMap<&str, f64>, what: &str) {
    for (name, want) in sample {
        let got = page
            .get(*name)
            .unwrap_or_else(|| panic!("{what} has no {name}"));
        assert!(
            close(num(got), *want, 1e-15),
            "{what}: {name} = {got}, the sample's {want}"
        );
    }
}

/// Equal up to a relative `rel` (JSON numbers parse to within an ulp).
fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

fn arr(v: &Value) -> &Vec<Value> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}"))
}

fn obj(v: &Value) -> &Map<String, Value> {
    v.as_object()
        .unwrap_or_else(|| panic!("not an object: {v}"))
}

fn str_of(v: &Value) -> &str {
    v.as_str().unwrap_or_else(|| panic!("not a string: {v}"))
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// The study started from the sweep view: its declaration is the page's two intervals and
/// design, the Studies page's table is its `sobol.csv`, and the pipeline's studies are listed
/// with their state.
fn check_started_study(trained: &Trained, r: &Value) {
    let start = &r["studyStart"];
    let name = str_of(&start["name"]);
    let dir = trained.path().join("explore-studies").join(name);
    let decl: Value = serde_yaml::from_str(
        &std::fs::read_to_string(dir.join("study.yaml")).expect("the study's study.yaml"),
    )
    .expect("study.yaml is YAML");
    assert_eq!(decl["kind"], "sensitivity");
    assert_eq!(decl["n"], 16);
    let varied: Vec<&str> = arr(&start["parameters"])
        .iter()
        .map(|p| str_of(&p["name"]))
        .collect();
    for p in arr(&start["parameters"]) {
        assert_eq!(
            decl["parameters"][str_of(&p["name"])],
            serde_json::json!({"uniform": [num(&p["from"]), num(&p["to"])]}),
            "{decl}"
        );
    }
    for (k, v) in obj(&start["design"]) {
        if !varied.contains(&k.as_str()) {
            assert_eq!(num(&decl["parameters"][k.as_str()]), num(v), "{k}");
        }
    }
    let s = &r["studies"];
    let csv = std::fs::read_to_string(dir.join("sobol.csv")).expect("sobol.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let shown: Vec<&str> = arr(&s["table"]["header"]).iter().map(str_of).collect();
    assert_eq!(shown, header, "the page's table header is sobol.csv's");
    assert_eq!(
        arr(&s["table"]["rows"]).len(),
        lines.count(),
        "one row per line of sobol.csv"
    );
    let listed: Vec<(&str, &str, &str)> = arr(&s["listed"])
        .iter()
        .map(|l| (str_of(&l[0]), str_of(&l[1]), str_of(&l[2])))
        .collect();
    assert!(
        listed.contains(&("explorer", name, "finished")),
        "{listed:?}"
    );
    for study in ["wheel_unloading", "drivers", "quiet_car_body"] {
        assert!(
            listed.contains(&("pipeline", study, "never run")),
            "{listed:?}"
        );
    }
    assert!(str_of(&s["declaration"]).contains("kind: sensitivity"));
}
