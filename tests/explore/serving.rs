//! The explorer's HTTP as a client that misbehaves, or a network, sees it: bodies that never
//! arrive are cut and their slots freed; a declared body over the limit is refused before it
//! is sent; every refusal carries the JSON error body, hyper's own included; one `Host` only,
//! in every spelling a browser writes for the bound address; a token given is a token
//! enforced; answers compressed as the client accepts and curves as float32 on request.

use crate::api::closed_by_server;
use crate::Trained;
use pino_explore::client::{exchange, Answer, Client};
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

/// The answer is the API's JSON error, naming `field` when given.
fn json_error(a: &Answer, status: u16, field: Option<&str>) {
    let text = String::from_utf8_lossy(&a.body);
    assert_eq!(a.status, status, "{text}");
    assert!(
        a.header("content-type")
            .is_some_and(|t| t.starts_with("application/json")),
        "{:?} {text}",
        a.headers
    );
    let v = a.json();
    assert!(v["error"].as_str().is_some_and(|e| !e.is_empty()), "{text}");
    if let Some(f) = field {
        assert_eq!(v["field"], f, "{text}");
    }
}

fn head(addr: SocketAddr, method: &str, path: &str, extra: &str) -> String {
    format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\n{extra}\r\n")
}

#[test]
fn every_refusal_is_json_whatever_layer_refuses_it() {
    let trained = Trained::shared();
    let served = trained.serve(&[]);
    let addr = served.addr;
    // Requests hyper cannot read: it answers them itself, and they carry the JSON body too.
    for raw in [
        "GARBAGE\r\n\r\n".to_owned(),
        "GET / HTTP/1.1 extra\r\nHost: x\r\n\r\n".to_owned(),
        head(addr, "POST", "/api/predict", "Content-Length: -5\r\n"),
        head(addr, "POST", "/api/predict", "Content-Length: 12abc\r\n"),
    ] {
        let a = exchange(addr, raw.as_bytes()).unwrap();
        json_error(&a, 400, Some("request"));
    }
    // More headers than hyper reads (100): 431, from hyper, as JSON.
    let many: String = (0..120).map(|k| format!("X-H{k}: v\r\n")).collect();
    let a = exchange(addr, head(addr, "GET", "/api/health", &many).as_bytes()).unwrap();
    json_error(&a, 431, Some("request"));
    // A second Host header is refused even when the first one is good.
    let two = head(addr, "GET", "/api/model", "Host: attacker.example\r\n");
    json_error(&exchange(addr, two.as_bytes()).unwrap(), 400, Some("Host"));
    // The request URI's authority is checked like the Host header.
    let absolute =
        format!("GET http://attacker.example/api/model HTTP/1.1\r\nHost: {addr}\r\n\r\n");
    json_error(
        &exchange(addr, absolute.as_bytes()).unwrap(),
        403,
        Some("Host"),
    );
    // A key given twice in a JSON body is refused, never the last one taken.
    let mut c = served.client();
    let a = c
        .request(
            "POST",
            "/api/predict",
            br#"{"design": {"m_c": 40000}, "design": {"m_c": -1}}"#,
        )
        .unwrap();
    json_error(&a, 400, Some("body"));
    assert!(a.json()["error"].as_str().unwrap().contains("`design`"));
    // An extractor's plain-text rejection becomes a JSON error.
    let a = c
        .post_json("/api/download/curves?format=csv&format=x", &json!({}))
        .unwrap();
    assert!(a.status >= 400, "{}", a.status);
    assert!(
        a.json()["error"].is_string(),
        "{}",
        String::from_utf8_lossy(&a.body)
    );
}

#[test]
fn a_body_over_the_limit_is_refused_before_it_is_sent_and_a_late_one_is_cut() {
    let trained = Trained::shared();
    let served = trained.serve(&["--body-timeout", "1", "--max-connections", "4"]);
    let addr = served.addr;
    // 413 on the head alone, and the connection closed: the body is never waited for.
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let h = head(
        addr,
        "POST",
        "/api/predict",
        "Content-Type: application/json\r\nContent-Length: 1000000000\r\n",
    );
    s.write_all(h.as_bytes()).unwrap();
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    assert!(text.starts_with("HTTP/1.1 413"), "{text}");
    assert!(text.contains("\"field\":\"body\""), "{text}");
    // Four connections (the cap) each send a head promising a body that never comes: each
    // is answered 408 with the JSON body and closed, and the server answers again.
    let promised = head(
        addr,
        "POST",
        "/api/predict",
        "Content-Type: application/json\r\nContent-Length: 60000\r\n",
    );
    let mut stuck: Vec<TcpStream> = (0..4)
        .map(|_| {
            let mut s = TcpStream::connect(addr).unwrap();
            s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
            s.write_all(promised.as_bytes()).unwrap();
            s.write_all(b"{\"des").unwrap();
            s
        })
        .collect();
    for s in &mut stuck {
        let mut text = String::new();
        let _ = s.read_to_string(&mut text);
        assert!(text.starts_with("HTTP/1.1 408"), "{text}");
        assert!(text.contains("\"field\":\"body\""), "{text}");
        assert!(closed_by_server(s), "a stuck body's connection stayed open");
    }
    let mut c = served.client();
    assert_eq!(c.post_json("/api/predict", &json!({})).unwrap().status, 200);
}

#[test]
fn a_token_given_is_required_on_a_loopback_address_too() {
    const TOKEN: &str = "loopback-token-0123";
    let trained = Trained::shared();
    let served = trained.serve(&["--bind", "127.0.0.2:0", "--token", TOKEN]);
    assert!(
        served.url.ends_with(&format!("/?token={TOKEN}")),
        "{}",
        served.url
    );
    let mut anonymous = served.client();
    json_error(&anonymous.get("/api/model").unwrap(), 403, Some("token"));
    let mut bearer = served.client();
    bearer
        .headers
        .push(format!("Authorization: Bearer {TOKEN}"));
    assert_eq!(bearer.get("/api/model").unwrap().status, 200);
}

#[test]
fn an_ipv4_mapped_address_is_answered_in_the_spellings_browsers_write() {
    let trained = Trained::shared();
    let served = trained.serve(&["--bind", "[::ffff:127.0.0.2]:0"]);
    let port = served.addr.port();
    // Chromium writes `[::ffff:127.0.0.2]` as `[::ffff:7f00:2]`.
    for host in [
        format!("[::ffff:7f00:2]:{port}"),
        format!("[::ffff:127.0.0.2]:{port}"),
        format!("[::FFFF:7F00:2]:{port}"),
        format!("127.0.0.2:{port}"),
        format!("localhost:{port}"),
    ] {
        let a = Client::new(served.addr)
            .with_host(&host)
            .get("/api/model")
            .unwrap();
        assert_eq!(a.status, 200, "{host}: {}", a.json());
    }
    // Another address (not a loopback one: every loopback address is answered).
    let other = Client::new(served.addr)
        .with_host(&format!("[::ffff:a00:1]:{port}"))
        .get("/api/model")
        .unwrap();
    json_error(&other, 403, Some("Host"));
}

/// The body of `a`, decompressed as its `Content-Encoding` says.
fn decoded(a: &Answer) -> Vec<u8> {
    let mut out = Vec::new();
    match a.header("content-encoding") {
        Some("br") => {
            brotli::Decompressor::new(&a.body[..], 4096)
                .read_to_end(&mut out)
                .unwrap();
        }
        Some("gzip") => {
            flate2::read::GzDecoder::new(&a.body[..])
                .read_to_end(&mut out)
                .unwrap();
        }
        None => out = a.body.clone(),
        Some(other) => panic!("unknown coding {other}"),
    }
    out
}

/// The values of a base64 float32 curve.
fn f32s(v: &Value) -> Vec<f32> {
    pino_explore::encoding::from_f32_base64(v.as_str().unwrap()).unwrap()
}

#[test]
fn answers_are_compressed_as_the_client_accepts() {
    let trained = Trained::shared();
    let served = trained.serve(&[]);
    let body = json!({"design": {}}).to_string();
    let mut plain = served.client();
    let identity = plain
        .request("POST", "/api/predict", body.as_bytes())
        .unwrap();
    assert_eq!(identity.header("content-encoding"), None);
    assert!(identity
        .header("vary")
        .is_some_and(|v| v.contains("accept-encoding")));
    let reference = identity.json();
    for (accept, coding) in [
        ("gzip, deflate, br", "br"),
        ("gzip, deflate", "gzip"),
        ("br;q=0, gzip", "gzip"),
    ] {
        let mut c = served.client();
        c.headers.push(format!("Accept-Encoding: {accept}"));
        let a = c.request("POST", "/api/predict", body.as_bytes()).unwrap();
        assert_eq!(a.header("content-encoding"), Some(coding), "{accept}");
        let v: Value = serde_json::from_slice(&decoded(&a)).unwrap();
        assert_eq!(v["channels"], reference["channels"], "{accept}");
        // JSON numbers compress by a third or more at the fast levels the server uses.
        assert!(
            a.body.len() * 3 < identity.body.len() * 2,
            "{accept}: {} bytes of {}",
            a.body.len(),
            identity.body.len()
        );
        // Pages are compressed too.
        let page = c.get("/assets/main.js").unwrap();
        assert_eq!(page.header("content-encoding"), Some(coding));
    }
}

#[test]
fn curves_are_sent_as_float32_on_request() {
    let trained = Trained::shared();
    let served = trained.serve(&[]);
    let reference = served
        .client()
        .post_json("/api/predict", &json!({"design": {}}))
        .unwrap();
    let identity_len = reference.body.len();
    let reference = reference.json();
    // The compact curves: every channel as float32, equal to the JSON answer's values rounded
    // to float32, and every band's half-width.
    let mut c = served.client();
    let compact = c
        .post_json("/api/predict", &json!({"design": {}, "encoding": "f32"}))
        .unwrap();
    assert_eq!(compact.status, 200, "{}", compact.json());
    let v = compact.json();
    assert_eq!(v["encoding"], "f32");
    assert_eq!(v["t"], reference["t"], "the times stay exact");
    assert_eq!(v["indices"], reference["indices"]);
    let channels = reference["channels"].as_object().unwrap();
    assert_eq!(v["channels"].as_object().unwrap().len(), channels.len());
    for (name, x) in channels {
        let want: Vec<f32> = x
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect();
        assert_eq!(f32s(&v["channels"][name]), want, "{name}");
    }
    let bands = reference["bands"].as_object().unwrap();
    assert!(!bands.is_empty());
    for (name, b) in bands {
        // Each half-width to 12 significant bits: within 1/4096 of itself.
        let half = f32s(&v["bands"][name]["half"]);
        let (lo, hi) = (b["lo"].as_array().unwrap(), b["hi"].as_array().unwrap());
        assert_eq!(half.len(), lo.len(), "{name}");
        for (k, h) in half.iter().enumerate() {
            let (l, u) = (lo[k].as_f64().unwrap(), hi[k].as_f64().unwrap());
            let want = (u - l) / 2.0;
            assert!(
                (f64::from(*h) - want).abs() <= want.abs() / 4096.0 + 1e-15 * u.abs().max(l.abs()),
                "{name}[{k}]: {h} vs {want}"
            );
        }
    }
    assert!(
        compact.body.len() * 3 < identity_len,
        "float32 curves: {} bytes against {identity_len}",
        compact.body.len(),
    );
    let bad = c
        .post_json("/api/predict", &json!({"encoding": "f16"}))
        .unwrap();
    json_error(&bad, 400, Some("encoding"));
}
