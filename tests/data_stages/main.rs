//! End-to-end tests of the data stages `sample-params`, `irregularity` and `weights`, run by
//! hand as the orchestrator would (`STAGE DESCRIPTION.yaml --context FILE`), on the shipped
//! descriptions (the quarter car and the vehicle-track model) and on a two-road description
//! written here: their Parquet and JSON artifacts, checked against what the description says
//! (parameter names and ranges, spectra in closed form, the equations of motion), and the
//! refusal of bad input. The pipeline files' parameter blocks are parsed into the stages' types.
//!
//! Needs the binaries: `cargo build -p sample-params -p irregularity -p simulate -p weights`.

use mbd_system::{Override, SystemSource};
use pino_data::{read_parquet, schema, write_parquet, Column, Table};
use pino_mbd_tests::{run_stage, stage_context, system, system_path};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Output;

fn log(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs `exe DESCRIPTION --context CTX` and asserts success; returns stdout.
fn ok(exe: &str, description: &Path, ctx: &Path, threads: usize) -> String {
    let o = run_stage(exe, Some(description), ctx, threads);
    assert!(o.status.success(), "{exe} failed: {}", log(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs `exe [DESCRIPTION] --context CTX`, asserts failure; returns stderr.
fn fails(exe: &str, description: Option<&Path>, ctx: &Path) -> String {
    let o = run_stage(exe, description, ctx, 1);
    assert!(!o.status.success(), "{exe} should have failed: {}", log(&o));
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn sizes(seed: u64, n_train: u64, n_validation: u64, n_test: u64) -> Value {
    json!({"seed": seed, "n_train": n_train, "n_validation": n_validation, "n_test": n_test})
}

/// `sample-params` of `description` with `params` into `<dir>/<tag>-out`.
fn sample(dir: &Path, tag: &str, description: &Path, params: Value) -> PathBuf {
    let (ctx, out) = stage_context(dir, tag, params, json!({}), false);
    ok("sample-params", description, &ctx, 1);
    out
}

/// `irregularity` of `description` over the params artifact `sp`.
fn profiles(dir: &Path, tag: &str, description: &Path, sp: &Path, params: Value) -> PathBuf {
    let (ctx, out) = stage_context(dir, tag, params, json!({"params": [sp]}), false);
    ok("irregularity", description, &ctx, 2);
    out
}

/// The mean square of an ISO 8608 displacement spectrum `G_d(n) = g0 (n / 0.1)^-2` (m^3)
/// over the spatial frequencies `[1 / l_max, 1 / l_min]`: `g0 0.01 (l_max - l_min)` (m^2).
fn iso8608_mean_square(g0: f64, wavelengths: [f64; 2]) -> f64 {
    g0 * 0.01 * (wavelengths[1] - wavelengths[0])
}

/// The same spectrum's integral over the spatial frequencies `[f1, f2]` (1/m).
fn iso8608_integral(g0: f64, f1: f64, f2: f64) -> f64 {
    g0 * 0.01 * (1.0 / f1 - 1.0 / f2)
}

/// `2 |c_k|^2` of the discrete Fourier coefficient `c_k = 1/N sum_j eta_j e^(-2 pi i k j / N)`:
/// the variance the profile holds at frequency bin `k` (a naive sum: a few bins are needed).
fn bin_variance(eta: &[f64], k: usize) -> f64 {
    let n = eta.len() as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for (j, e) in eta.iter().enumerate() {
        let a = -2.0 * std::f64::consts::PI * (k * j) as f64 / n;
        re += e * a.cos();
        im += e * a.sin();
    }
    2.0 * (re * re + im * im) / (n * n)
}

#[test]
fn sample_params_draws_the_descriptions_parameters_inside_their_ranges() {
    let dir = tempfile::tempdir().unwrap();
    // Independently of the compiler: the ranges the YAML writes (factor x nominal, or [lo, hi]).
    let quarter_car = [
        ("m_s", [256.0, 384.0]),
        ("m_u", [32.0, 48.0]),
        ("k_s", [15400.0, 28600.0]),
        ("c_s", [900.0, 2100.0]),
        ("k_t", [160000.0, 240000.0]),
        ("v_kmh", [36.0, 108.0]),
    ];
    for (name, expected_params) in [("quarter-car", Some(&quarter_car[..])), ("vtcd", None)] {
        let path = system_path(name);
        let (source, described) = system(name, &[]);
        let sp = sample(dir.path(), name, &path, sizes(5, 6, 2, 2));
        let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
        let mut expected = vec![schema::SAMPLE_ID, schema::SPLIT];
        expected.extend(described.sampled_names());
        assert_eq!(params.names().collect::<Vec<_>>(), expected, "{name}");
        if let Some(q) = expected_params {
            let names: Vec<&str> = q.iter().map(|(n, _)| *n).collect();
            assert_eq!(described.sampled_names(), names, "{name}");
        } else {
            // The paper's 14 parameters, in its table's order.
            assert_eq!(described.sampled_names().len(), 14, "{name}");
        }
        assert_eq!(
            params.i64(schema::SAMPLE_ID).unwrap(),
            &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]
        );
        let splits = params.str(schema::SPLIT).unwrap();
        assert!(
            splits[..6].iter().all(|s| s == "train")
                && splits[6..8].iter().all(|s| s == "validation")
                && splits[8..].iter().all(|s| s == "test"),
            "{splits:?}"
        );
        let ranges = described.ranges();
        if let Some(q) = expected_params {
            for (k, (_, r)) in q.iter().enumerate() {
                for b in 0..2 {
                    assert!((ranges[k][b] / r[b] - 1.0).abs() < 1e-12, "{name}: {q:?}");
                }
            }
        }
        for (k, p) in described.sampled_names().iter().enumerate() {
            let v = params.f64(p).unwrap();
            let [lo, hi] = ranges[k];
            assert!(v.iter().all(|x| (lo..hi).contains(x)), "{name}.{p}: {v:?}");
            // Ten independent uniform draws over the range are not all in one tenth of it.
            let spread = v.iter().cloned().fold(f64::MIN, f64::max)
                - v.iter().cloned().fold(f64::MAX, f64::min);
            assert!(spread > 0.1 * (hi - lo), "{name}.{p}: {v:?}");
        }
        // ranges.parquet states every range with the parameter's unit.
        let r = read_parquet(&sp.join("ranges.parquet"), None).unwrap();
        assert_eq!(
            r.str("name").unwrap(),
            described
                .sampled_names()
                .iter()
                .map(|s| s.to_string())
                .collect::<Vec<_>>()
        );
        let units: Vec<String> = described
            .sampled()
            .iter()
            .map(|&i| described.parameters[i].unit.clone())
            .collect();
        assert_eq!(r.str("unit").unwrap(), units);
        let (min, max) = (r.f64("min").unwrap(), r.f64("max").unwrap());
        for (k, range) in ranges.iter().enumerate() {
            assert_eq!([min[k], max[k]], *range, "{name}");
        }
        // system.json: the description's text and the (empty) overrides.
        let record = SystemSource::load_record(&sp.join(mbd_system::SYSTEM_FILE)).unwrap();
        assert_eq!(
            (record.text.as_str(), &record.values),
            (source.text.as_str(), &source.values)
        );
        // Same seed, same bytes (the same stage run elsewhere: the stage's name is in the
        // file's metadata); another seed, other draws.
        let first = std::fs::read(sp.join("params.parquet")).unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let again = sample(elsewhere.path(), name, &path, sizes(5, 6, 2, 2));
        assert_eq!(first, std::fs::read(again.join("params.parquet")).unwrap());
        let other = sample(
            dir.path(),
            &format!("{name}-seed"),
            &path,
            sizes(6, 6, 2, 2),
        );
        let p = described.sampled_names()[0];
        assert_ne!(
            params.f64(p).unwrap(),
            read_parquet(&other.join("params.parquet"), None)
                .unwrap()
                .f64(p)
                .unwrap()
        );
    }

    // A run's overrides: a narrower speed range is drawn from and recorded; a fixed value
    // changes nothing that is drawn but is part of the record.
    let path = system_path("quarter-car");
    let sp = sample(
        dir.path(),
        "narrow",
        &path,
        json!({"seed": 5, "n_train": 6, "n_validation": 2, "n_test": 2,
               "system_values": {"v_kmh": [60.0, 80.0], "g": 9.80665}}),
    );
    let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
    assert!(params
        .f64("v_kmh")
        .unwrap()
        .iter()
        .all(|v| (60.0..80.0).contains(v)));
    let r = read_parquet(&sp.join("ranges.parquet"), None).unwrap();
    let k = r.str("name").unwrap().iter().position(|n| n == "v_kmh");
    let k = k.unwrap();
    assert_eq!(
        [r.f64("min").unwrap()[k], r.f64("max").unwrap()[k]],
        [60.0, 80.0]
    );
    let record = SystemSource::load_record(&sp.join(mbd_system::SYSTEM_FILE)).unwrap();
    assert_eq!(record.values["v_kmh"], Override::Range([60.0, 80.0]));
    assert_eq!(record.values["g"], Override::Value(9.80665));
}

#[test]
fn irregularity_profiles_have_the_descriptions_spectrum() {
    let dir = tempfile::tempdir().unwrap();

    // The quarter car's road: ISO 8608 class C (G_d(0.1) = 256e-6 m^3) over 0.5-90 m.
    let path = system_path("quarter-car");
    let sp = sample(dir.path(), "sp", &path, sizes(5, 6, 2, 2));
    let controls = json!({"seed": 5, "dx": 0.1, "length": 200.0});
    let ir = profiles(dir.path(), "road", &path, &sp, controls.clone());
    let table = read_parquet(&ir.join("irregularity.parquet"), None).unwrap();
    // One generated profile: no `profile` column.
    assert_eq!(
        table.names().collect::<Vec<_>>(),
        [schema::SAMPLE_ID, schema::TRACK_X, schema::TRACK_ETA]
    );
    let n = 2000;
    assert_eq!(table.num_rows(), 10 * n);
    let (ids, x, eta) = (
        table.i64(schema::SAMPLE_ID).unwrap(),
        table.f64(schema::TRACK_X).unwrap(),
        table.f64(schema::TRACK_ETA).unwrap(),
    );
    let g0 = 256e-6;
    let df = 1.0 / 200.0;
    for s in 0..10 {
        let rows = s * n..(s + 1) * n;
        assert!(ids[rows.clone()].iter().all(|&i| i == s as i64));
        for (j, r) in rows.clone().enumerate() {
            assert!((x[r] - j as f64 * 0.1).abs() < 1e-9, "x[{j}] = {}", x[r]);
        }
        let e = &eta[rows];
        // Exactly the band's mean square: every bin gets its cell's integral.
        let ms = e.iter().map(|v| v * v).sum::<f64>() / n as f64;
        let want = iso8608_mean_square(g0, [0.5, 90.0]);
        assert!((ms / want - 1.0).abs() < 1e-9, "sample {s}: {ms} vs {want}");
        // The spectrum bin by bin: inside the band each bin holds its cell's integral; below
        // the longest wavelength (k df < 1/90) and above the shortest (k df > 2) nothing.
        for k in [3, 10, 20, 50, 150, 300] {
            let want = iso8608_integral(g0, (k as f64 - 0.5) * df, (k as f64 + 0.5) * df);
            let got = bin_variance(e, k);
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "sample {s} bin {k}: {got} vs {want}"
            );
        }
        for k in [1, 401, 600, 999] {
            assert!(bin_variance(e, k) < 1e-12 * want, "sample {s} bin {k}");
        }
    }
    // Every sample its own profile.
    assert_ne!(&eta[..n], &eta[n..2 * n]);
    let recorded: mbd_dataset::ProfileParams = serde_json::from_value(
        pino_data::system::read_json(&ir.join(pino_data::artifacts::PROFILES_FILE)).unwrap(),
    )
    .unwrap();
    assert_eq!(
        recorded,
        mbd_dataset::ProfileParams {
            seed: 5,
            dx: 0.1,
            length: 200.0
        }
    );
    // The thread count does not change the bytes; the seed changes the phases.
    let bytes = std::fs::read(ir.join("irregularity.parquet")).unwrap();
    let (ctx, one) = stage_context(
        &dir.path().join("one-thread"),
        "road",
        controls,
        json!({"params": [sp]}),
        false,
    );
    ok("irregularity", &path, &ctx, 1);
    assert_eq!(
        bytes,
        std::fs::read(one.join("irregularity.parquet")).unwrap()
    );
    let other = profiles(
        dir.path(),
        "road-seed",
        &path,
        &sp,
        json!({"seed": 6, "dx": 0.1, "length": 200.0}),
    );
    let t = read_parquet(&other.join("irregularity.parquet"), None).unwrap();
    assert_ne!(&t.f64(schema::TRACK_ETA).unwrap()[..n], &eta[..n]);

    // The vehicle-track model's TB/T 3352-2014 spectrum over 2-100 m: 0.3667 mm^2 (the
    // standard's figure, 4 digits: 2e-4 relative).
    let path = system_path("vtcd");
    let sp = sample(dir.path(), "sp-vtcd", &path, sizes(5, 2, 1, 1));
    let ir = profiles(
        dir.path(),
        "track",
        &path,
        &sp,
        json!({"seed": 5, "dx": 0.1, "length": 540.0}),
    );
    let table = read_parquet(&ir.join("irregularity.parquet"), None).unwrap();
    let eta = table.f64(schema::TRACK_ETA).unwrap();
    assert_eq!(eta.len(), 4 * 5400);
    for s in 0..4 {
        let ms = eta[s * 5400..(s + 1) * 5400]
            .iter()
            .map(|e| e * e)
            .sum::<f64>()
            / 5400.0;
        assert!((ms / 0.3667e-6 - 1.0).abs() < 2e-4, "sample {s}: {ms}");
    }
}

/// Two unsprung masses, each on its own generated road (classes B and D, other bands): a
/// description with two generated profiles, so `irregularity` labels them and `simulate`
/// must give each element its own.
const TWO_ROADS: &str = "\
format: 1
name: two-roads
parameters:
  m: {unit: kg, nominal: 40, range: [30, 50]}
  k: {unit: N/m, value: 200000}
  v_kmh: {unit: km/h, nominal: 36, range: [30, 40]}
bodies:
  a: {mass: m, dofs: [z]}
  b: {mass: m, dofs: [z]}
moving:
  speed: v_kmh / 3.6
  points:
    ra: {on: ground, offset: 0}
    rb: {on: ground, offset: -2}
profiles:
  left: {kind: generated, psd: {iso8608: B}, wavelengths: [0.5, 20.0]}
  right: {kind: generated, psd: {iso8608: D}, wavelengths: [1.0, 40.0]}
elements:
  ta: {kind: spring_damper, from: a, to: ra, k: k, profile: left}
  tb: {kind: spring_damper, from: b, to: rb, k: k, profile: right}
outputs: [eta_ta, eta_tb]
";

/// Linear interpolation of the profile `(x, eta)` (uniform, sorted) at `at`.
fn interpolate(x: &[f64], eta: &[f64], at: f64) -> f64 {
    let j = x.partition_point(|&v| v <= at) - 1;
    if x[j] == at {
        return eta[j];
    }
    eta[j] + (eta[j + 1] - eta[j]) * (at - x[j]) / (x[j + 1] - x[j])
}

#[test]
fn several_generated_profiles_are_labelled_and_reach_their_own_elements() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two-roads.yaml");
    std::fs::write(&path, TWO_ROADS).unwrap();
    let sp = sample(dir.path(), "sp", &path, sizes(3, 2, 1, 1));
    let ir = profiles(
        dir.path(),
        "roads",
        &path,
        &sp,
        json!({"seed": 3, "dx": 0.1, "length": 100.0}),
    );
    let t = read_parquet(&ir.join("irregularity.parquet"), None).unwrap();
    assert_eq!(
        t.names().collect::<Vec<_>>(),
        [
            "profile",
            schema::SAMPLE_ID,
            schema::TRACK_X,
            schema::TRACK_ETA
        ]
    );
    let (label, ids, x, eta) = (
        t.str("profile").unwrap(),
        t.i64(schema::SAMPLE_ID).unwrap(),
        t.f64(schema::TRACK_X).unwrap(),
        t.f64(schema::TRACK_ETA).unwrap(),
    );
    let n = 1000;
    assert_eq!(t.num_rows(), 2 * 4 * n);
    // Profiles in description order, each block sorted by sample; each its own spectrum.
    let mut profile = std::collections::BTreeMap::new();
    for (p, (name, g0, band)) in [
        ("left", 64e-6, [0.5, 20.0]),
        ("right", 1024e-6, [1.0, 40.0]),
    ]
    .into_iter()
    .enumerate()
    {
        for s in 0..4 {
            let rows = (p * 4 + s) * n..(p * 4 + s + 1) * n;
            assert!(label[rows.clone()].iter().all(|l| l == name));
            assert!(ids[rows.clone()].iter().all(|&i| i == s as i64));
            let e = &eta[rows.clone()];
            let ms = e.iter().map(|v| v * v).sum::<f64>() / n as f64;
            let want = iso8608_mean_square(g0, band);
            assert!((ms / want - 1.0).abs() < 1e-9, "{name} {s}: {ms} vs {want}");
            profile.insert((name, s as i64), (x[rows].to_vec(), e.to_vec()));
        }
    }

    // simulate: each element reads its own profile, at x0 + offset + v t.
    let inputs = json!({"params": [sp], "irregularity": [ir]});
    let run = json!({"duration": 0.2, "dt": 1e-4, "output_every": 10, "start": "equilibrium",
                     "startup_zero_fraction": 0.0, "startup_ramp_fraction": 0.0, "x0": 5.0});
    let (ctx, sim) = stage_context(dir.path(), "simulate", run, inputs, false);
    ok("simulate", &path, &ctx, 2);
    let s = read_parquet(&sim.join("simulation.parquet"), None).unwrap();
    let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
    let (sid, time) = (
        s.i64(schema::SAMPLE_ID).unwrap(),
        s.f64(schema::TIME).unwrap(),
    );
    let (eta_a, eta_b) = (s.f64("eta_ta").unwrap(), s.f64("eta_tb").unwrap());
    assert_eq!(s.num_rows(), 4 * 200);
    for r in 0..s.num_rows() {
        let v = params.f64("v_kmh").unwrap()[sid[r] as usize] / 3.6;
        for (name, offset, got) in [("left", 0.0, eta_a[r]), ("right", -2.0, eta_b[r])] {
            let (px, pe) = &profile[&(name, sid[r])];
            let want = interpolate(px, pe, 5.0 + offset + v * time[r]);
            assert!(
                (got - want).abs() < 1e-9 * pe.iter().fold(0.0f64, |m, e| m.max(e.abs())),
                "row {r}: eta under `{name}` {got} vs {want}"
            );
        }
    }
}

#[test]
fn bad_input_exits_nonzero_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let quarter = system_path("quarter-car");
    let bridge = system_path("bridge");
    let cases: Vec<(&PathBuf, Value, Vec<&str>)> = vec![
        (&quarter, sizes(1, 0, 1, 1), vec!["`n_train`", ">= 1"]),
        (&quarter, sizes(1, 4, 1, 0), vec!["`n_test`", ">= 1"]),
        (
            &quarter,
            json!({"seed": 1, "n_train": 4, "n_validation": 1}),
            vec!["missing field `n_test`"],
        ),
        (
            &quarter,
            json!({"seed": 1, "n_train": 4, "n_validaton": 1, "n_test": 1}),
            vec!["unknown field `n_validaton`"],
        ),
        // Ranges are the description's now: the old parameter is refused, not ignored.
        (
            &quarter,
            json!({"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1,
                   "ranges": {"m_s": [300, 400]}}),
            vec!["unknown field `ranges`"],
        ),
        (
            &quarter,
            json!({"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1,
                   "system_values": {"mass": 1.0}}),
            vec!["`mass` is not a parameter", "m_s"],
        ),
        (
            &quarter,
            json!({"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1,
                   "system_values": {"m_s": [400.0, 300.0]}}),
            vec!["system_values.m_s", "containing the nominal 320"],
        ),
        (
            &quarter,
            json!({"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1,
                   "system_values": {"m_s": [330.0, 400.0]}}),
            vec!["system_values.m_s", "containing the nominal 320"],
        ),
        (
            &bridge,
            json!({"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1,
                   "system_values": {"static_midspan": 0.01}}),
            vec!["system_values.static_midspan", "derived"],
        ),
        (
            &bridge,
            json!({"seed": 1, "n_train": 4, "n_validation": 1, "n_test": 1,
                   "system_values": {"span": [20.0, 30.0]}}),
            vec![
                "system_values.span",
                "fixed parameter takes a finite number",
            ],
        ),
    ];
    for (i, (description, params, needles)) in cases.into_iter().enumerate() {
        let (ctx, _) = stage_context(
            dir.path(),
            &format!("sp{i}"),
            params.clone(),
            json!({}),
            false,
        );
        let err = fails("sample-params", Some(description.as_path()), &ctx);
        for n in needles {
            assert!(err.contains(n), "{params}: `{n}` not in: {err}");
        }
    }
    // The description: none named, a missing file, one with an error (its file and line).
    let (ctx, _) = stage_context(dir.path(), "sp-none", sizes(1, 4, 1, 1), json!({}), false);
    let err = fails("sample-params", None, &ctx);
    assert!(err.contains("no system description"), "{err}");
    let missing = dir.path().join("nope.yaml");
    let err = fails("sample-params", Some(&missing), &ctx);
    assert!(
        err.contains("nope.yaml") && err.contains("cannot read the system description"),
        "{err}"
    );
    let broken = dir.path().join("broken.yaml");
    let text = std::fs::read_to_string(&quarter).unwrap();
    let line = 1 + text.lines().position(|l| l.starts_with("  tyre:")).unwrap();
    std::fs::write(
        &broken,
        text.replace("from: u, to: road", "from: wheel, to: road"),
    )
    .unwrap();
    for check in [false, true] {
        let (ctx, _) = stage_context(dir.path(), "sp-broken", sizes(1, 4, 1, 1), json!({}), check);
        let err = fails("sample-params", Some(&broken), &ctx);
        assert!(
            err.contains(&format!("broken.yaml:{line}:"))
                && err.contains("elements.tyre.from")
                && err.contains("`wheel`"),
            "check mode {check}: {err}"
        );
    }

    // irregularity: the description's band against the run's spacing and length, the input.
    let sp = sample(dir.path(), "sp", &quarter, sizes(1, 2, 1, 1));
    let inputs = json!({"params": [sp]});
    for (params, needles) in [
        // 2 dx = 0.6 m above the shortest wavelength 0.5 m.
        (
            json!({"seed": 1, "dx": 0.3, "length": 200.0}),
            vec!["wavelengths", "2 dx = 0.6"],
        ),
        // The longest wavelength, 90 m, does not fit in 50 m.
        (
            json!({"seed": 1, "dx": 0.1, "length": 50.0}),
            vec!["wavelengths", "length = 50"],
        ),
        (
            json!({"seed": 1, "dx": 0.1}),
            vec!["missing field `length`"],
        ),
        // The band is the description's now.
        (
            json!({"seed": 1, "dx": 0.1, "length": 200.0, "wavelength_min": 2.0}),
            vec!["unknown field `wavelength_min`"],
        ),
    ] {
        let (ctx, _) = stage_context(dir.path(), "ir", params.clone(), inputs.clone(), false);
        let err = fails("irregularity", Some(&quarter), &ctx);
        for n in needles {
            assert!(err.contains(n), "{params}: `{n}` not in: {err}");
        }
    }
    let good = json!({"seed": 1, "dx": 0.1, "length": 200.0});
    let (ctx, _) = stage_context(dir.path(), "ir-alone", good.clone(), json!({}), false);
    let err = fails("irregularity", Some(&quarter), &ctx);
    assert!(err.contains("needs input `params`"), "{err}");
    // Params sampled from another description, or from this one with other overrides.
    let (ctx, _) = stage_context(dir.path(), "ir-bridge", good.clone(), inputs.clone(), false);
    let err = fails("irregularity", Some(&bridge), &ctx);
    assert!(
        err.contains("differ in their descriptions") && err.contains("bridge.yaml"),
        "{err}"
    );
    let overridden = json!({"seed": 1, "dx": 0.1, "length": 200.0,
                            "system_values": {"v_kmh": [60.0, 80.0]}});
    let (ctx, _) = stage_context(dir.path(), "ir-values", overridden, inputs, false);
    let err = fails("irregularity", Some(&quarter), &ctx);
    assert!(
        err.contains("differ in their parameter overrides (system_values)"),
        "{err}"
    );
}

/// The quarter car's equations of motion, written from docs/systems.md (conventions,
/// elements, loads) rather than taken from the engine: with `z` downward, the suspension from
/// `s` to `u` (`d = z_s - z_u`, `f = m_s g + k_s d + c_s d'`) and the tyre from `u` to the road
/// (`d = z_u - eta`, `f = (m_s + m_u) g + k_t d`), each pushing its upper end up,
///
/// ```text
/// m_s z_s'' = m_s g - f_suspension
/// m_u z_u'' = m_u g + f_suspension - f_tyre
/// ```
struct QuarterCar {
    m_s: f64,
    m_u: f64,
    k_s: f64,
    c_s: f64,
    k_t: f64,
    g: f64,
}

impl QuarterCar {
    fn of(params: &Table, row: usize) -> Self {
        let p = |n: &str| params.f64(n).unwrap()[row];
        Self {
            m_s: p("m_s"),
            m_u: p("m_u"),
            k_s: p("k_s"),
            c_s: p("c_s"),
            k_t: p("k_t"),
            g: 9.81,
        }
    }

    /// `(f_suspension, f_tyre)` at a state.
    fn forces(&self, z: [f64; 2], v: [f64; 2], eta: f64) -> (f64, f64) {
        let f_s = self.m_s * self.g + self.k_s * (z[0] - z[1]) + self.c_s * (v[0] - v[1]);
        let f_t = (self.m_s + self.m_u) * self.g + self.k_t * (z[1] - eta);
        (f_s, f_t)
    }
}

/// A `simulation.parquet` of the quarter car with `ids` in `dir` (with the `system.json` and
/// `provenance.parquet` of a simulate shard): every signal zero except the sprung mass's
/// acceleration, a constant `0.5 + 0.1 id` m/s^2 per sample, over 20 points at 1 kHz.
fn synthetic_quarter_car(dir: &Path, ids: &[i64], drop: Option<&str>) {
    let (source, described) = system("quarter-car", &[]);
    std::fs::create_dir_all(dir).unwrap();
    let n = 20;
    let mut t = Table::default().with_units(pino_data::system::units_of(&described).unwrap());
    let per_sample = |f: &dyn Fn(i64, usize) -> f64| -> Vec<f64> {
        ids.iter()
            .flat_map(|&i| (0..n).map(move |k| (i, k)))
            .map(|(i, k)| f(i, k))
            .collect()
    };
    t.push(
        schema::SAMPLE_ID,
        Column::I64(
            ids.iter()
                .flat_map(|&i| std::iter::repeat_n(i, n))
                .collect(),
        ),
    )
    .unwrap();
    t.push(
        schema::TIME,
        Column::F64(per_sample(&|_, k| k as f64 * 1e-3)),
    )
    .unwrap();
    for c in &described.channels {
        if Some(c.name.as_str()) == drop {
            continue;
        }
        let values = match c.name.as_str() {
            "z_s_a" => per_sample(&|i, _| 0.5 + 0.1 * i as f64),
            // The static tyre force at the zero state (reference: static equilibrium).
            _ => per_sample(&|_, _| 0.0),
        };
        t.push(&c.name, Column::F64(values)).unwrap();
    }
    write_parquet(&dir.join("simulation.parquet"), &t).unwrap();
    pino_data::system::write_record(dir, &source).unwrap();
    pino_data::provenance::write_provenance(
        &dir.join(pino_data::artifacts::PROVENANCE_FILE),
        &[
            ("dt", 1e-4),
            ("duration", 0.02),
            ("output_every", 10.0),
            ("startup_zero_fraction", 0.0),
            ("startup_ramp_fraction", 0.0),
            ("x0", 5.0),
        ],
    )
    .unwrap();
}

fn weights_params(noise_ratio: f64) -> Value {
    json!({"seed": 3, "noise_ratio": noise_ratio, "window_start_fraction": 0.0})
}

/// A profile read by a cubic spline needs 4 points: run controls giving fewer (`length / dx`
/// rounded up to even) are refused by `irregularity`, in check mode (before `pipeline run`
/// starts anything) as in a run, at the line of the profile's `interpolation:` in the
/// description (the shipped bridge asks for cubic), with the allowed length. The same controls
/// under a linear profile fail on the generator's own limits, not on the interpolation.
#[test]
fn irregularity_refuses_a_cubic_profile_of_fewer_than_four_points() {
    let dir = tempfile::tempdir().unwrap();
    let bridge = system_path("bridge");
    let text = std::fs::read_to_string(&bridge).unwrap();
    let line = 1 + text
        .lines()
        .position(|l| l.trim_start().starts_with("interpolation: cubic"))
        .expect("the shipped bridge reads its deck profile by a cubic");
    let short = json!({"seed": 1, "dx": 0.1, "length": 0.2});
    for check in [true, false] {
        let (ctx, _) = stage_context(dir.path(), "ir-short", short.clone(), json!({}), check);
        let err = fails("irregularity", Some(&bridge), &ctx);
        assert!(
            err.contains(&format!("bridge.yaml:{line}:"))
                && err.contains("profiles.deck.interpolation")
                && err.contains("cubic needs at least 4 profile points")
                && err.contains("give 2")
                && err.contains("length >= 4 dx = 0.4 m"),
            "check mode {check}: {err}"
        );
    }
    let linear = dir.path().join("linear.yaml");
    std::fs::write(
        &linear,
        text.replace("interpolation: cubic", "interpolation: linear"),
    )
    .unwrap();
    let (ctx, _) = stage_context(dir.path(), "ir-linear", short, json!({}), true);
    let err = fails("irregularity", Some(&linear), &ctx);
    assert!(
        !err.contains("interpolation") && err.contains("length"),
        "{err}"
    );
    // The shipped controls pass the check.
    let (ctx, _) = stage_context(
        dir.path(),
        "ir-shipped",
        json!({"seed": 1, "dx": 0.1, "length": 120.0}),
        json!({}),
        true,
    );
    ok("irregularity", &bridge, &ctx, 1);
}

#[test]
fn simulate_check_mode_refuses_a_start_before_a_generated_profile() {
    // The check mode (what `pipeline run` runs before anything, `check: true`; a failure
    // there stops the run with exit 2) of `simulate` refuses x0 < 0 under the quarter car's generated road, at the profile's line, with the
    // least x0 that passes; the shipped start passes. No input is read in check mode.
    let dir = tempfile::tempdir().unwrap();
    let quarter = system_path("quarter-car");
    let text = std::fs::read_to_string(&quarter).unwrap();
    let line = 1 + text.lines().position(|l| l.starts_with("  road:")).unwrap();
    let run = |x0: f64| {
        json!({"duration": 0.3, "dt": 2e-4, "output_every": 5, "start": "equilibrium",
               "startup_zero_fraction": 0.0, "startup_ramp_fraction": 0.0, "x0": x0})
    };
    let (ctx, _) = stage_context(dir.path(), "sim-before", run(-20.0), json!({}), true);
    let err = fails("simulate", Some(&quarter), &ctx);
    assert!(
        err.contains(&format!("quarter-car.yaml:{line}:"))
            && err.contains("x0 = -20 m")
            && err.contains("set x0 >= 0 m"),
        "{err}"
    );
    let (ctx, _) = stage_context(dir.path(), "sim-shipped", run(5.0), json!({}), true);
    ok("simulate", &quarter, &ctx, 1);
}

#[test]
fn weights_are_the_residual_peaks_of_every_training_sample_from_any_shard_layout() {
    let dir = tempfile::tempdir().unwrap();
    let quarter = system_path("quarter-car");
    let sp = sample(dir.path(), "sp", &quarter, sizes(5, 6, 2, 2));
    // Two shards, round robin; sample 4 (train) failed and is absent; 6, 7 are validation and
    // 8 a test sample (present, and skipped like validation: weights cover training only).
    let (a, b) = (dir.path().join("shard0"), dir.path().join("shard1"));
    synthetic_quarter_car(&a, &[0, 2, 6], None);
    synthetic_quarter_car(&b, &[1, 3, 5, 7, 8], None);
    let inputs = json!({"params": [sp], "dataset": [a, b]});
    let (ctx, out) = stage_context(dir.path(), "weights", weights_params(0.02), inputs, false);
    let o = run_stage("weights", None, &ctx, 2);
    assert!(o.status.success(), "{}", log(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("phi of 2 equations for 5 training samples")
            && stdout.contains("1 training samples absent"),
        "{stdout}"
    );
    let w = read_parquet(&out.join("weights.parquet"), None).unwrap();
    // One column per DOF of the description with an equation, named after it.
    assert_eq!(
        w.names().collect::<Vec<_>>(),
        [schema::SAMPLE_ID, "phi_z_s", "phi_z_u"]
    );
    assert_eq!(w.i64(schema::SAMPLE_ID).unwrap(), &[0, 1, 2, 3, 5]);
    // At the zero state every spring carries its preload, which balances the weights: the
    // residual of the sprung mass is m_s a (a constant, so no noise: std 0), the unsprung
    // mass's vanishes to round-off.
    let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
    for (k, &id) in w.i64(schema::SAMPLE_ID).unwrap().iter().enumerate() {
        let car = QuarterCar::of(&params, id as usize);
        let (f_s, f_t) = car.forces([0.0; 2], [0.0; 2], 0.0);
        let a = 0.5 + 0.1 * id as f64;
        let r_s = car.m_s * a - (car.m_s * car.g - f_s);
        let r_u = -(car.m_u * car.g + f_s - f_t);
        let phi_s = w.f64("phi_z_s").unwrap()[k];
        assert!((phi_s / r_s.abs() - 1.0).abs() < 1e-12, "{phi_s} vs {r_s}");
        let scale = (car.m_s + car.m_u) * car.g;
        let phi_u = w.f64("phi_z_u").unwrap()[k];
        assert!(
            phi_u < 1e-12 * scale && r_u.abs() < 1e-12 * scale,
            "{phi_u}"
        );
    }
    // Shard layout does not matter: one file with all samples gives the same bytes.
    let bytes = std::fs::read(out.join("weights.parquet")).unwrap();
    let c = dir.path().join("single");
    synthetic_quarter_car(&c, &[0, 1, 2, 3, 5, 6, 7, 8], None);
    let single = json!({"params": [sp], "dataset": [c]});
    // The same unit (`weights`, written into every file's metadata) in another directory.
    let (ctx1, out1) = stage_context(
        &dir.path().join("single-run"),
        "weights",
        weights_params(0.02),
        single.clone(),
        false,
    );
    let o = run_stage("weights", None, &ctx1, 1);
    assert!(o.status.success(), "{}", log(&o));
    assert_eq!(bytes, std::fs::read(out1.join("weights.parquet")).unwrap());

    // A missing column is named with its file.
    synthetic_quarter_car(&b, &[1, 3, 5, 7, 8], Some("z_u_a"));
    let err = fails("weights", None, &ctx);
    assert!(
        err.contains("missing column `z_u_a`") && err.contains("shard1"),
        "{err}"
    );
    // Parameters: range, window, every field required, the old constants refused.
    for (params, needles) in [
        (weights_params(1.5), vec!["`noise_ratio` = 1.5", "(0, 1]"]),
        (
            json!({"seed": 3, "noise_ratio": 0.02, "window_start_fraction": 1.0}),
            vec!["window_start_fraction", "[0, 1)"],
        ),
        (
            json!({"seed": 3, "noise_ratio": 0.02}),
            vec!["missing field `window_start_fraction`"],
        ),
        (
            json!({"seed": 3, "noise_ratio": 0.02, "window_start_fraction": 0.0, "gravity": 9.81}),
            vec!["unknown field `gravity`"],
        ),
    ] {
        let (ctx, _) = stage_context(
            dir.path(),
            "weights-bad",
            params.clone(),
            single.clone(),
            false,
        );
        let err = fails("weights", None, &ctx);
        for n in needles {
            assert!(err.contains(n), "{params}: `{n}` not in: {err}");
        }
    }
}

#[test]
fn weights_of_a_simulated_quarter_car_vanish_without_noise() {
    // The chain sample-params -> irregularity -> simulate -> weights on a short run. With
    // r = 1e-12 phi is the clean residual max_t |R_i| of the stored solution, which the
    // solver makes consistent to round-off (the quarter car's dampers act between DOFs, whose
    // velocities are stored: no finite difference enters). With r = 2% every phi is far
    // above that.
    let dir = tempfile::tempdir().unwrap();
    let quarter = system_path("quarter-car");
    let sp = sample(dir.path(), "sp", &quarter, sizes(2, 3, 1, 1));
    let ir = profiles(
        dir.path(),
        "ir",
        &quarter,
        &sp,
        json!({"seed": 2, "dx": 0.1, "length": 200.0}),
    );
    let run = json!({"duration": 0.3, "dt": 2e-4, "output_every": 5, "start": "equilibrium",
                     "startup_zero_fraction": 0.0, "startup_ramp_fraction": 0.0, "x0": 5.0});
    let (ctx, sim) = stage_context(
        dir.path(),
        "simulate",
        run,
        json!({"params": [sp], "irregularity": [ir]}),
        false,
    );
    ok("simulate", &quarter, &ctx, 2);
    let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
    let s = read_parquet(&sim.join("simulation.parquet"), None).unwrap();
    let inputs = json!({"params": [sp], "dataset": [sim]});
    let mut phi = Vec::new();
    for (stage, r) in [("weights-clean", 1e-12), ("weights-noised", 0.02)] {
        let (ctx, out) = stage_context(dir.path(), stage, weights_params(r), inputs.clone(), false);
        let o = run_stage("weights", None, &ctx, 2);
        assert!(o.status.success(), "{}", log(&o));
        let w = read_parquet(&out.join("weights.parquet"), None).unwrap();
        assert_eq!(w.i64("sample_id").unwrap(), &[0, 1, 2]);
        phi.push([
            w.f64("phi_z_s").unwrap().to_vec(),
            w.f64("phi_z_u").unwrap().to_vec(),
        ]);
    }
    for id in [0, 1, 2] {
        let car = QuarterCar::of(&params, id);
        let scale = (car.m_s + car.m_u) * car.g;
        // The stored rows satisfy the equations above (written independently of the engine)
        // to round-off, and phi without noise is that round-off.
        let col = |n: &str| s.f64(n).unwrap();
        let sid = s.i64(schema::SAMPLE_ID).unwrap();
        let rows: Vec<usize> = (0..s.num_rows()).filter(|&r| sid[r] == id as i64).collect();
        assert_eq!(rows.len(), 300);
        let mut worst = [0.0f64; 2];
        for &r in &rows {
            let (f_s, f_t) = car.forces(
                [col("z_s")[r], col("z_u")[r]],
                [col("z_s_v")[r], col("z_u_v")[r]],
                col("eta_tyre")[r],
            );
            assert!(
                (f_t - col("f_tyre")[r]).abs() < 1e-9 * scale,
                "f_tyre row {r}"
            );
            assert!(
                (col("d_suspension")[r] - (col("z_s")[r] - col("z_u")[r])).abs() < 1e-15,
                "d_suspension row {r}"
            );
            let r_s = car.m_s * col("z_s_a")[r] - (car.m_s * car.g - f_s);
            let r_u = car.m_u * col("z_u_a")[r] - (car.m_u * car.g + f_s - f_t);
            worst = [worst[0].max(r_s.abs()), worst[1].max(r_u.abs())];
        }
        for i in 0..2 {
            let (clean, noised) = (phi[0][i][id], phi[1][i][id]);
            assert!(
                worst[i] < 1e-9 * scale,
                "sample {id} eq {i}: residual {}",
                worst[i]
            );
            assert!(
                clean < 1e-9 * scale,
                "sample {id} eq {i}: phi clean {clean}"
            );
            assert!(
                noised > 1e-4 * scale && noised > 1e3 * clean,
                "sample {id} eq {i}: phi noised {noised} vs clean {clean}"
            );
        }
    }
}

/// The parameters of a stage block without its `system_values`, and those overrides.
fn split_values(mut params: Value) -> (Value, std::collections::BTreeMap<String, Override>) {
    let values = params
        .as_object_mut()
        .expect("a parameter block is a map")
        .remove("system_values")
        .map(|v| serde_json::from_value(v).expect("system_values: NAME -> number or [lo, hi]"))
        .unwrap_or_default();
    (params, values)
}

#[test]
fn pipeline_files_hold_valid_data_stage_parameters() {
    // The `params:` blocks of every pipeline file go through YAML -> JSON (as the orchestrator
    // passes them, constants substituted) into the stages' checked types, against the
    // description the file names, and hold the intended values.
    for (file, system_file, n_train, n_validation, n_test, n_calibration) in [
        ("pipeline.yaml", "systems/vtcd.yaml", 1600, 100, 100, 1000),
        (
            "configs/paper.yaml",
            "systems/vtcd.yaml",
            20000,
            2000,
            2000,
            2000,
        ),
        (
            "configs/long.yaml",
            "systems/vtcd.yaml",
            4800,
            200,
            200,
            200,
        ),
        (
            "configs/quarter-car.yaml",
            "systems/quarter-car.yaml",
            1600,
            100,
            100,
            1000,
        ),
        (
            "configs/bridge.yaml",
            "systems/bridge.yaml",
            800,
            100,
            100,
            1000,
        ),
    ] {
        let params = |stage: &str| pino_mbd_tests::stage_params(file, stage);
        // Every stage that reads the description names the same file, which exists and
        // compiles with the file's overrides; every stage gets the same overrides.
        let mut values = None;
        for stage in [
            "sample-params",
            "irregularity",
            "simulate",
            "evaluate",
            "study",
        ] {
            let cmd = pino_mbd_tests::stage_cmd(file, stage);
            assert_eq!(cmd[1..], [system_file], "{file}: {stage}");
            let (_, v) = split_values(params(stage));
            assert!(
                values.get_or_insert_with(|| v.clone()) == &v,
                "{file}: {stage} has other system_values"
            );
        }
        let values = values.unwrap();
        let path = pino_mbd_tests::workspace_root().join(system_file);
        let source = SystemSource::read(&path, values.clone()).unwrap();
        let described = source.compile().unwrap_or_else(|e| panic!("{file}: {e}"));

        let (p, _) = split_values(params("sample-params"));
        let split: mbd_dataset::SplitSizes =
            serde_json::from_value(p).unwrap_or_else(|e| panic!("{file}: sample-params: {e}"));
        let plan = mbd_dataset::SamplingPlan::new(split, &described).unwrap();
        assert_eq!(
            (
                split.n_train,
                split.n_validation,
                split.n_test,
                split.n_calibration
            ),
            (n_train, n_validation, n_test, n_calibration),
            "{file}"
        );
        // The calibration stage's settings parse and are valid; evaluate reads its output.
        let calibrate: pino_calibration::build::CalibrateParams =
            serde_json::from_value(params("calibrate"))
                .unwrap_or_else(|e| panic!("{file}: calibrate: {e}"));
        calibrate
            .validate()
            .unwrap_or_else(|e| panic!("{file}: calibrate: {e}"));
        assert_eq!(plan.ranges(), described.ranges().as_slice(), "{file}");

        // Every study of the study stages passes the planning check against the description,
        // and the file declares one study of each kind.
        let mut kinds = std::collections::BTreeSet::new();
        let pipeline = pino_mbd_tests::shipped_pipeline(file);
        let studies = pipeline
            .stages_running("study")
            .flat_map(|(_, s)| s.expansions.clone());
        for expansion in studies {
            let study: pino_study::spec::StudyParams =
                serde_json::from_value(expansion.params.clone())
                    .unwrap_or_else(|e| panic!("{file}: study: {e}"));
            pino_study::check(&described, &study).unwrap_or_else(|e| panic!("{file}: {e}"));
            kinds.insert(study.study["kind"].as_str().unwrap().to_owned());
        }
        assert_eq!(
            kinds.into_iter().collect::<Vec<_>>(),
            ["monte_carlo", "optimise", "sensitivity"],
            "{file}"
        );

        let (p, _) = split_values(params("irregularity"));
        let controls: mbd_dataset::ProfileParams =
            serde_json::from_value(p).unwrap_or_else(|e| panic!("{file}: irregularity: {e}"));
        let generators = mbd_dataset::profile_generators(&described, &controls)
            .unwrap_or_else(|e| panic!("{file}: irregularity: {e}"));
        assert!(
            generators.iter().any(Option::is_some),
            "{file}: no generated profile"
        );

        let (p, _) = split_values(params("simulate"));
        let run: mbd_engine::RunConfig =
            serde_json::from_value(p).unwrap_or_else(|e| panic!("{file}: simulate: {e}"));
        run.validate()
            .unwrap_or_else(|e| panic!("{file}: simulate: {e}"));
        assert_eq!(run.start, mbd_engine::StartMode::Equilibrium, "{file}");

        // Every point under a generated profile stays on it for the whole run, at every corner
        // of the box of sampling ranges (offsets and speed are expressions of the parameters).
        let ranges = described.ranges();
        let mut reach = (f64::INFINITY, f64::NEG_INFINITY);
        for mask in 0..1u64 << ranges.len() {
            let corner: Vec<f64> = (0..ranges.len())
                .map(|j| ranges[j][((mask >> j) & 1) as usize])
                .collect();
            let v = described
                .values(&described.sampled_values(corner).unwrap())
                .unwrap();
            let speed = described.speed.eval(&v);
            for e in &described.elements {
                let (Some(prof), mbd_system::system::End::Moving(i)) = (e.profile, &e.to) else {
                    continue;
                };
                if !matches!(
                    described.profiles[prof],
                    mbd_system::system::Profile::Generated { .. }
                ) {
                    continue;
                }
                let start = run.x0 + described.points[*i].offset.eval(&v);
                reach = (
                    reach.0.min(start),
                    reach.1.max(start + speed * run.duration),
                );
            }
        }
        assert!(
            reach.0 >= 0.0 && reach.1 <= controls.length,
            "{file}: the profiled points cover [{}, {}] m, the profiles [0, {}] m",
            reach.0,
            reach.1,
            controls.length
        );

        let w: pino_learn::weights::WeightConfig = serde_json::from_value(params("weights"))
            .unwrap_or_else(|e| panic!("{file}: weights: {e}"));
        w.validate().unwrap();
        assert_eq!(w.noise_ratio, 0.02, "{file}");
        let ix: pino_indices::IndexParams = serde_json::from_value(params("indices"))
            .unwrap_or_else(|e| panic!("{file}: indices: {e}"));
        let ix = ix.validate().unwrap();
        assert_eq!(
            ix.sperling,
            pino_indices::SperlingParams::default(),
            "{file}"
        );
        assert_eq!(ix.limits, pino_indices::Limits::default(), "{file}");
        // One start-up window for weights, indices and training.
        let train = params("train");
        assert_eq!(
            (w.window_start_fraction, ix.window_start_fraction),
            (
                train["startup_fraction"].as_f64().unwrap(),
                train["startup_fraction"].as_f64().unwrap()
            ),
            "{file}"
        );
    }
}

/// The description the README shows under "Describe your own system" compiles, and is the
/// shipped quarter car: the same sampled parameters with the same nominal values and ranges,
/// the same stored columns.
/// The job of the vehicle in space declares a critical-speed study (the speed against the yaw
/// damping and the conicity) and a Monte Carlo study, both passing the planning check against
/// its description; its calibration and training settings parse.
#[test]
fn the_vehicle_in_space_job_declares_checked_studies() {
    let file = "configs/vtcd-3d.yaml";
    let (_, values) = split_values(pino_mbd_tests::stage_params(file, "study"));
    let path = pino_mbd_tests::workspace_root().join("systems/vtcd-3d.yaml");
    let described = SystemSource::read(&path, values)
        .unwrap()
        .compile()
        .unwrap();
    let pipeline = pino_mbd_tests::shipped_pipeline(file);
    let mut kinds = std::collections::BTreeSet::new();
    for (_, s) in pipeline.stages_running("study") {
        for expansion in &s.expansions {
            let study: pino_study::spec::StudyParams =
                serde_json::from_value(expansion.params.clone()).unwrap();
            let parsed = pino_study::check(&described, &study).unwrap_or_else(|e| panic!("{e}"));
            if let pino_study::StudyKind::CriticalSpeed(c) = &parsed.kind {
                assert_eq!(c.speed, "v_kmh");
                let grid: Vec<&str> = c.grid.iter().map(|(p, _)| p.as_str()).collect();
                assert_eq!(grid, ["c_yaw", "gamma"]);
            }
            kinds.insert(study.study["kind"].as_str().unwrap().to_owned());
        }
    }
    assert_eq!(
        kinds.into_iter().collect::<Vec<_>>(),
        ["critical_speed", "monte_carlo"]
    );
    let calibrate: pino_calibration::build::CalibrateParams =
        serde_json::from_value(pino_mbd_tests::stage_params(file, "calibrate")).unwrap();
    calibrate.validate().unwrap();
}

#[test]
fn the_readme_description_is_the_shipped_quarter_car() {
    let readme =
        std::fs::read_to_string(pino_mbd_tests::workspace_root().join("README.md")).unwrap();
    let section = readme
        .split("## Describe your own system")
        .nth(1)
        .expect("README: the section `Describe your own system`");
    let block = section
        .split("```yaml\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("README: a yaml block in the section");
    let shown = mbd_system::load_str(block, "README.md", &Default::default())
        .unwrap_or_else(|d| panic!("{d}"));
    let (_, shipped) = system("quarter-car", &[]);
    assert_eq!(shown.sampled_names(), shipped.sampled_names());
    assert_eq!(shown.ranges(), shipped.ranges());
    let columns = |s: &mbd_system::System| {
        s.channels
            .iter()
            .map(|c| c.name.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(columns(&shown), columns(&shipped));
}

/// The derived residual of each shipped description on its own solver's output: the chain
/// sample-params -> irregularity -> simulate -> weights with `noise_ratio` 1e-12 makes phi the
/// clean residual `max_t |R_i|` of every equation. The vehicle-track model's and the quarter
/// car's equations read only stored exact columns (displacements, the solver's `_v` and `_a`,
/// the rail under each wheel, the profile): round-off, < 1e-9 of the static contact force, and
/// with r = 2 % every phi is far above it. The bridge's suspension damper also reads the rates
/// of the profile and of the deck under the vehicle. The profile's rate is the solver's own,
/// stored beside the profile (`eta_suspension_v`, from the cubic spline's slope); a central
/// difference of the stored profile over `2 h` (h = 1 ms) made the floor 2.6e-3 of the weight
/// (`h^2 v^3 eta''' / 6`), and 3.4e-2 with a linear profile. What remains is the deck's rate
/// under the wheel, still the central difference of `z_b1` where the solver takes the modal
/// `w_t + v w_x`: measured 3.8e-5 of the weight here, asserted below 1.5e-4. 2 % noise stands
/// only ~270 times above it (the vehicle-track's and quarter car's stand 1e10 above theirs).
#[test]
fn weights_without_noise_are_each_descriptions_residual_floor() {
    let vtcd_track = json!({"n_f": 150, "n_m": 75});
    // (description, overrides, profile length, duration, x0, floor of the clean residual
    // over the static force, whether 2 % noise stands far above it)
    for (name, values, length, duration, x0, floor, noise_above_floor) in [
        ("vtcd", vtcd_track, 120.0, 0.2, 5.0, 1e-9, true),
        ("quarter-car", json!({}), 200.0, 0.3, 5.0, 1e-9, true),
        ("bridge", json!({}), 120.0, 0.5, 0.0, 1.5e-4, false),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let path = system_path(name);
        let mut sizes = sizes(4, 3, 1, 1);
        sizes["system_values"] = values.clone();
        let sp = sample(dir.path(), "sp", &path, sizes);
        let controls = json!({"seed": 4, "dx": 0.1, "length": length, "system_values": values});
        let ir = profiles(dir.path(), "ir", &path, &sp, controls);
        let run = json!({"duration": duration, "dt": 1e-4, "output_every": 10,
                         "start": "equilibrium", "startup_zero_fraction": 0.0,
                         "startup_ramp_fraction": 0.0, "x0": x0, "system_values": values});
        let inputs = json!({"params": [sp], "irregularity": [ir]});
        let (ctx, sim) = stage_context(dir.path(), "simulate", run, inputs, false);
        ok("simulate", &path, &ctx, 2);
        let inputs = json!({"params": [sp], "dataset": [sim]});
        let mut phi = Vec::new();
        for (stage, r) in [("weights-clean", 1e-12), ("weights-noised", 0.02)] {
            let (ctx, out) =
                stage_context(dir.path(), stage, weights_params(r), inputs.clone(), false);
            let o = run_stage("weights", None, &ctx, 2);
            assert!(o.status.success(), "{name}: {}", log(&o));
            phi.push(read_parquet(&out.join("weights.parquet"), None).unwrap());
        }
        let overrides: std::collections::BTreeMap<String, Override> =
            serde_json::from_value(values).unwrap();
        let overrides: Vec<(&str, Override)> = overrides
            .iter()
            .map(|(n, v)| (n.as_str(), v.clone()))
            .collect();
        let (_, described) = system(name, &overrides);
        let params = read_parquet(&sp.join("params.parquet"), None).unwrap();
        let columns: Vec<String> = phi[0]
            .names()
            .filter(|n| n.starts_with("phi_"))
            .map(str::to_owned)
            .collect();
        assert!(!columns.is_empty(), "{name}: no equation");
        let (mut worst, mut least_noised) = (0.0f64, f64::INFINITY);
        for (row, id) in phi[0].i64("sample_id").unwrap().iter().enumerate() {
            let p = params
                .i64("sample_id")
                .unwrap()
                .iter()
                .position(|i| i == id)
                .unwrap();
            let sampled = described
                .sampled_by_name(
                    described
                        .sampled_names()
                        .into_iter()
                        .map(|n| (n, params.f64(n).unwrap()[p])),
                )
                .unwrap();
            let model = described.instantiate(&sampled).unwrap();
            let scale = mbd_engine::statics::contact_scale(&described, &model).unwrap();
            for c in &columns {
                let (clean, noised) = (phi[0].f64(c).unwrap()[row], phi[1].f64(c).unwrap()[row]);
                worst = worst.max(clean / scale);
                least_noised = least_noised.min(noised / clean);
                assert!(
                    clean < floor * scale,
                    "{name} sample {id} {c}: clean residual {clean} vs scale {scale}"
                );
                assert!(
                    !noise_above_floor || (noised > 1e3 * clean && noised > 1e-5 * scale),
                    "{name} sample {id} {c}: noised {noised}, clean {clean}"
                );
            }
        }
        println!(
            "{name}: clean residual up to {worst:.2e} of the static force; 2 % noise at least {least_noised:.2e} times it"
        );
    }
}
