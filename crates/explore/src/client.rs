//! A small blocking HTTP/1.1 client for the explorer's API: what the load benchmark and the
//! tests drive the server with (one keep-alive connection per client, `Content-Length`
//! framing, which is how the server answers every request).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

/// An answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    /// Status code.
    pub status: u16,
    /// Header lines (`name` lower case, value).
    pub headers: Vec<(String, String)>,
    /// The body.
    pub body: Vec<u8>,
}

impl Answer {
    /// The value of header `name` (lower case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The body as JSON (`Null` when it is not JSON).
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body).unwrap_or(serde_json::Value::Null)
    }
}

/// One keep-alive connection to a server.
pub struct Client {
    addr: SocketAddr,
    host: String,
    stream: Option<BufReader<TcpStream>>,
    /// Extra header lines sent with every request (`Name: value`).
    pub headers: Vec<String>,
}

impl Client {
    /// A client of the server at `addr`, sending `Host: addr`.
    pub fn new(addr: SocketAddr) -> Self {
        Self {
            addr,
            host: addr.to_string(),
            stream: None,
            headers: Vec::new(),
        }
    }

    /// Sends a different `Host` header.
    pub fn with_host(mut self, host: &str) -> Self {
        self.host = host.to_owned();
        self
    }

    fn connect(&mut self) -> std::io::Result<&mut BufReader<TcpStream>> {
        if self.stream.is_none() {
            let s = TcpStream::connect(self.addr)?;
            s.set_nodelay(true)?;
            s.set_read_timeout(Some(Duration::from_secs(120)))?;
            self.stream = Some(BufReader::new(s));
        }
        Ok(self.stream.as_mut().expect("connected above"))
    }

    /// Sends a request and reads the answer; reconnects once when a kept-alive connection was
    /// closed by the server.
    pub fn request(&mut self, method: &str, path: &str, body: &[u8]) -> std::io::Result<Answer> {
        let json = method == "POST";
        match self.send(method, path, body, json) {
            Ok(a) => Ok(a),
            Err(_) if self.stream.is_some() => {
                self.stream = None;
                self.send(method, path, body, json)
            }
            Err(e) => Err(e),
        }
    }

    /// Sends a request with only the headers in [`Client::headers`] (no `Content-Type` of its
    /// own, so a test can send any or none), on a new connection.
    pub fn request_without_content_type(
        &mut self,
        method: &str,
        path: &str,
        body: &[u8],
    ) -> std::io::Result<Answer> {
        self.stream = None;
        self.send(method, path, body, false)
    }

    /// `POST` of a JSON value.
    pub fn post_json(&mut self, path: &str, body: &serde_json::Value) -> std::io::Result<Answer> {
        self.request("POST", path, body.to_string().as_bytes())
    }

    /// `GET`.
    pub fn get(&mut self, path: &str) -> std::io::Result<Answer> {
        self.request("GET", path, b"")
    }

    /// Sends a request (with `Content-Type: application/json` when `json`) and reads the answer.
    fn send(
        &mut self,
        method: &str,
        path: &str,
        body: &[u8],
        json: bool,
    ) -> std::io::Result<Answer> {
        let mut head = format!(
            "{method} {path} HTTP/1.1\r\nHost: {}\r\nContent-Length: {}\r\n",
            self.host,
            body.len()
        );
        if json {
            head.push_str("Content-Type: application/json\r\n");
        }
        for h in &self.headers {
            head.push_str(h);
            head.push_str("\r\n");
        }
        head.push_str("\r\n");
        let r = self.connect()?;
        let s = r.get_mut();
        s.write_all(head.as_bytes())?;
        s.write_all(body)?;
        read_answer(r)
    }

    /// Sends a request on a new connection and returns the connection without reading the
    /// answer: dropping it is a client that goes away mid-request.
    pub fn send_only(&self, method: &str, path: &str, body: &[u8]) -> std::io::Result<TcpStream> {
        let mut s = TcpStream::connect(self.addr)?;
        let head = format!(
            "{method} {path} HTTP/1.1\r\nHost: {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
            self.host,
            body.len()
        );
        s.write_all(head.as_bytes())?;
        s.write_all(body)?;
        Ok(s)
    }
}

/// Sends `raw` bytes (a request as written, well-formed or not) on a new connection to `addr`
/// and reads the answer.
pub fn exchange(addr: SocketAddr, raw: &[u8]) -> std::io::Result<Answer> {
    let s = TcpStream::connect(addr)?;
    s.set_read_timeout(Some(Duration::from_secs(120)))?;
    let mut r = BufReader::new(s);
    r.get_mut().write_all(raw)?;
    read_answer(&mut r)
}

fn invalid(msg: impl Into<String>) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, msg.into())
}

fn read_answer(r: &mut BufReader<TcpStream>) -> std::io::Result<Answer> {
    let mut line = String::new();
    if r.read_line(&mut line)? == 0 {
        return Err(std::io::Error::new(
            std::io::ErrorKind::ConnectionAborted,
            "connection closed",
        ));
    }
    let status: u16 = line
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| invalid(format!("bad status line {line:?}")))?;
    let mut headers = Vec::new();
    loop {
        line.clear();
        r.read_line(&mut line)?;
        let l = line.trim_end();
        if l.is_empty() {
            break;
        }
        if let Some((n, v)) = l.split_once(':') {
            headers.push((n.trim().to_ascii_lowercase(), v.trim().to_owned()));
        }
    }
    let len: usize = headers
        .iter()
        .find(|(n, _)| n == "content-length")
        .and_then(|(_, v)| v.parse().ok())
        .ok_or_else(|| invalid("no Content-Length in the answer"))?;
    let mut body = vec![0; len];
    r.read_exact(&mut body)?;
    Ok(Answer {
        status,
        headers,
        body,
    })
}
