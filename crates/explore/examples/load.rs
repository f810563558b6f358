//! Load and latency benchmark of a running `explore` (BENCHMARKS.md, "Design explorer").
//!
//! ```text
//! cargo run --release -p pino-explore --example load -- ADDR [--clients 32] [--seconds 10]
//! ```
//! 1. `--clients` concurrent clients (one keep-alive connection and thread each) predict random
//!    designs inside the training ranges for `--seconds`: requests, errors (any non-200),
//!    throughput, p50 and p99 latency seen by the client;
//! 2. one client: the server-side time of a prediction (`elapsed_ms`), median of 50;
//! 3. a 100-design sweep, median of 5; an exact solve of the model's run, median of 5;
//! 4. a client that disconnects mid-solve, then a prediction: the server still serves.
//!
//! Exits nonzero when any request of the load failed or the server stopped answering.
//!
//! ```text
//! cargo run --release -p pino-explore --example load -- ADDR --study 5000
//! ```
//! instead measures the explorer beside a study (BENCHMARKS.md, "Explorer"):
//! 1. the bytes of one slider move: the page's prediction (the plotted channels' bands) and
//!    the API's default (every band), as JSON numbers and as float32 curves, uncompressed, gzip
//!    and brotli;
//! 2. predictions as the page sends them (float32 curves, brotli), one after the other: 40
//!    with nothing else running, then as many as fit while a Monte Carlo study of `--study`
//!    designs runs (started here, then listed until it ends): p50, p99 and max latency seen by
//!    the client, and the study's wall time.

use pino_explore::client::Client;
use serde_json::{json, Value};
use std::net::{SocketAddr, ToSocketAddrs};
use std::time::{Duration, Instant};

fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    percentile(&v, 0.5)
}

/// A small deterministic generator (xorshift) for the designs: no dependency for a benchmark.
struct Designs(u64);

impl Designs {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn design(&mut self, params: &[Value]) -> Value {
        let m: serde_json::Map<String, Value> = params
            .iter()
            .map(|p| {
                let (lo, hi) = (
                    p["min"].as_f64().unwrap_or(0.0),
                    p["max"].as_f64().unwrap_or(0.0),
                );
                (
                    p["name"].as_str().unwrap_or_default().to_owned(),
                    json!(lo + self.next() * (hi - lo)),
                )
            })
            .collect();
        json!({ "design": m })
    }
}

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(target) = args.first() else {
        eprintln!("usage: load ADDR [--clients 32] [--seconds 10]  (ADDR: 127.0.0.1:PORT or the URL explore printed)");
        std::process::exit(2);
    };
    let host = target
        .trim_start_matches("http://")
        .split('/')
        .next()
        .unwrap_or_default();
    let addr: SocketAddr = match host.to_socket_addrs().ok().and_then(|mut a| a.next()) {
        Some(a) => a,
        None => {
            eprintln!("load: cannot resolve {host}");
            std::process::exit(2);
        }
    };
    let clients: usize = arg(&args, "--clients", 32);
    let seconds: f64 = arg(&args, "--seconds", 10.0);
    let mut c = Client::new(addr).with_host(host);
    let model = c.get("/api/model").expect("GET /api/model").json();
    let params: Vec<Value> = model["parameters"].as_array().cloned().unwrap_or_default();
    println!(
        "model: {} algorithm {}, {} parameters, {} points",
        model["system"],
        model["model"]["algorithm"],
        params.len(),
        model["time"]["points"]
    );
    let study: usize = arg(&args, "--study", 0);
    if study > 0 {
        bytes_per_move(addr, host, &model);
        beside_study(addr, host, &params, study);
        return;
    }

    // 1. Concurrent load.
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let started = Instant::now();
    let workers: Vec<_> = (0..clients)
        .map(|k| {
            let (params, host) = (params.clone(), host.to_owned());
            std::thread::spawn(move || {
                let mut c = Client::new(addr).with_host(&host);
                let mut designs = Designs(0x9E37_79B9_7F4A_7C15 ^ (k as u64 + 1));
                let (mut lat, mut errors) = (Vec::new(), Vec::new());
                while Instant::now() < deadline {
                    let body = designs.design(&params);
                    let t0 = Instant::now();
                    match c.post_json("/api/predict", &body) {
                        Ok(a) if a.status == 200 => lat.push(t0.elapsed().as_secs_f64() * 1e3),
                        Ok(a) => errors.push(format!(
                            "HTTP {}: {}",
                            a.status,
                            String::from_utf8_lossy(&a.body)
                        )),
                        Err(e) => errors.push(e.to_string()),
                    }
                }
                (lat, errors)
            })
        })
        .collect();
    let (mut lat, mut errors) = (Vec::new(), Vec::new());
    for w in workers {
        let (l, e) = w.join().expect("client thread");
        lat.extend(l);
        errors.extend(e);
    }
    let wall = started.elapsed().as_secs_f64();
    lat.sort_by(f64::total_cmp);
    println!(
        "load: {clients} clients x {seconds} s: {} predictions, {} errors, {:.1} per s, latency p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms",
        lat.len(),
        errors.len(),
        lat.len() as f64 / wall,
        percentile(&lat, 0.5),
        percentile(&lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN)
    );
    for e in errors.iter().take(5) {
        eprintln!("load: error: {e}");
    }

    // 2. Server-side time of one prediction.
    let mut designs = Designs(42);
    let server: Vec<f64> = (0..50)
        .filter_map(|_| c.post_json("/api/predict", &designs.design(&params)).ok())
        .filter_map(|a| a.json()["elapsed_ms"].as_f64())
        .collect();
    println!(
        "predict (server side, sequential): median {:.2} ms of {}",
        median(server.clone()),
        server.len()
    );

    // 3. Sweep and solve.
    if let Some(name) = params.first().and_then(|p| p["name"].as_str()) {
        let sweep: Vec<f64> = (0..5)
            .filter_map(|_| {
                c.post_json("/api/sweep", &json!({"parameter": name, "steps": 100}))
                    .ok()
            })
            .filter_map(|a| a.json()["elapsed_ms"].as_f64())
            .collect();
        println!(
            "sweep of 100 designs: median {:.1} ms of {}",
            median(sweep.clone()),
            sweep.len()
        );
    }
    let solves: Vec<(f64, f64)> = (0..5)
        .filter_map(|_| c.post_json("/api/solve", &json!({})).ok())
        .map(|a| a.json())
        .filter_map(|v| Some((v["elapsed_ms"].as_f64()?, v["solve_ms"].as_f64()?)))
        .collect();
    println!(
        "solve exactly: median {:.1} ms in all, {:.1} ms in the solver, of {}",
        median(solves.iter().map(|s| s.0).collect()),
        median(solves.iter().map(|s| s.1).collect()),
        solves.len()
    );

    // 4. A client that leaves mid-solve.
    let before = c
        .get("/api/health")
        .map(|a| a.json()["solves_cancelled"].as_u64().unwrap_or(0))
        .unwrap_or(0);
    if let Ok(s) = c.send_only("POST", "/api/solve", b"{}") {
        std::thread::sleep(Duration::from_millis(50));
        drop(s);
    }
    std::thread::sleep(Duration::from_millis(500));
    let after = c
        .get("/api/health")
        .map(|a| a.json())
        .unwrap_or(Value::Null);
    let serving = c
        .post_json("/api/predict", &json!({}))
        .map(|a| a.status == 200)
        .unwrap_or(false);
    println!(
        "client left mid-solve: solves cancelled {} -> {}, server still predicting: {serving}",
        before, after["solves_cancelled"]
    );
    if !errors.is_empty() || !serving {
        std::process::exit(1);
    }
}

/// The channels the page plots (and asks the bands of) when it opens: the first two of each
/// group but the excitations.
fn page_bands(model: &Value) -> Vec<String> {
    let mut per_group: std::collections::BTreeMap<&str, usize> = Default::default();
    model["channels"]
        .as_array()
        .map(Vec::as_slice)
        .unwrap_or_default()
        .iter()
        .filter(|c| c["group"] != "excitation")
        .filter(|c| {
            let n = per_group
                .entry(c["group"].as_str().unwrap_or(""))
                .or_default();
            *n += 1;
            *n <= 2
        })
        .filter_map(|c| c["name"].as_str().map(str::to_owned))
        .collect()
}

/// The bytes of one prediction of the nominal design: the page's request and the API's
/// default, JSON and float32, uncompressed, gzip and brotli.
fn bytes_per_move(addr: SocketAddr, host: &str, model: &Value) {
    let bands = [
        ("the page's bands", json!(page_bands(model))),
        ("every band", json!(true)),
    ];
    for (what, b) in bands {
        for encoding in ["json", "f32"] {
            let mut sizes = Vec::new();
            for coding in [None, Some("gzip"), Some("br")] {
                let mut c = Client::new(addr).with_host(host);
                if let Some(k) = coding {
                    c.headers.push(format!("Accept-Encoding: {k}"));
                }
                let a = c
                    .post_json("/api/predict", &json!({"bands": b, "encoding": encoding}))
                    .expect("POST /api/predict");
                assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
                sizes.push(format!(
                    "{} {} B",
                    coding.unwrap_or("identity"),
                    a.body.len()
                ));
            }
            println!(
                "bytes per slider move, {what}, {encoding}: {}",
                sizes.join(", ")
            );
        }
    }
}

/// Latencies (ms) of predictions as the page sends them, one after the other, while `go`.
fn page_predictions(
    c: &mut Client,
    params: &[Value],
    mut go: impl FnMut(usize) -> bool,
) -> Vec<f64> {
    let mut designs = Designs(7);
    let mut lat = Vec::new();
    while go(lat.len()) {
        let mut body = designs.design(params);
        body["encoding"] = json!("f32");
        let t0 = Instant::now();
        let a = c
            .post_json("/api/predict", &body)
            .expect("POST /api/predict");
        assert_eq!(a.status, 200, "{}", String::from_utf8_lossy(&a.body));
        lat.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    lat.sort_by(f64::total_cmp);
    lat
}

fn summary(lat: &[f64]) -> String {
    format!(
        "{} predictions, p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms",
        lat.len(),
        percentile(lat, 0.5),
        percentile(lat, 0.99),
        lat.last().copied().unwrap_or(f64::NAN)
    )
}

/// Predictions with nothing else running, then beside a Monte Carlo study of `n` designs.
fn beside_study(addr: SocketAddr, host: &str, params: &[Value], n: usize) {
    let mut c = Client::new(addr).with_host(host);
    c.headers.push("Accept-Encoding: br".into());
    let idle = page_predictions(&mut c, params, |k| k < 40);
    println!("predict alone: {}", summary(&idle));
    let p0 = params
        .first()
        .and_then(|p| p["name"].as_str())
        .expect("a parameter");
    let started = c
        .post_json(
            "/api/studies",
            &json!({"kind": "monte_carlo", "parameters": [{"name": p0}], "n": n}),
        )
        .expect("POST /api/studies");
    assert_eq!(
        started.status,
        202,
        "{}",
        String::from_utf8_lossy(&started.body)
    );
    let name = started.json()["name"]
        .as_str()
        .unwrap_or_default()
        .to_owned();
    let t0 = Instant::now();
    let mut lister = Client::new(addr).with_host(host);
    let running = |lister: &mut Client| {
        let list = lister.get("/api/studies").expect("GET /api/studies").json();
        list["explorer"]
            .as_array()
            .and_then(|l| l.iter().find(|s| s["name"] == name.as_str()).cloned())
            .map(|s| (s["state"] == "running", s["detail"].clone()))
            .unwrap_or((false, Value::Null))
    };
    let mut last = Value::Null;
    let beside = page_predictions(&mut c, params, |k| {
        if k % 10 != 0 {
            return true;
        }
        let (on, detail) = running(&mut lister);
        last = detail;
        on
    });
    println!(
        "predict beside a {n}-design study ({name}, {:.1} s, ended: {last}): {}",
        t0.elapsed().as_secs_f64(),
        summary(&beside)
    );
}
