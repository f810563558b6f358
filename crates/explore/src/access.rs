//! Who may talk to the server: the `Host` names it answers to (DNS rebinding) and the token.
//!
//! - A `Host` is answered when it names the bound address in any spelling a browser writes
//!   (an IPv6 address compressed or not, in any case; an IPv4-mapped IPv6 address such as
//!   `[::ffff:7f00:2]` as the IPv4 address it maps), `localhost`, or a name given with
//!   `--allow-host`, each with the bound port. Bound to a loopback address, every loopback
//!   address is answered; bound to every interface, any host with the right port is.
//! - The token, when the server has one, is required on every request: a cookie set by the
//!   page's first load with `?token=`, `Authorization: Bearer` (the scheme in any case) or
//!   `?token=` itself, compared in constant time.

use axum::http::{header, HeaderMap};
use std::net::{IpAddr, SocketAddr};

/// The fewest characters of a token given with `--token` (a random one has 32).
pub const MIN_TOKEN_CHARS: usize = 16;

/// Name of the token cookie.
pub const TOKEN_COOKIE: &str = "explore_token";

/// `ip` as it is compared: an IPv4-mapped IPv6 address as its IPv4 address.
fn canonical(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V6(v6) => v6.to_canonical(),
        v4 => v4,
    }
}

/// Whether `ip` is a loopback address (an IPv4-mapped loopback address included).
pub fn is_loopback(ip: IpAddr) -> bool {
    canonical(ip).is_loopback()
}

/// A `Host` value (or an `--allow-host` name) as its host, lower case without brackets or a
/// trailing dot, and its port (`default_port` when it names none). `None` when malformed (an
/// IPv6 address must be bracketed).
fn split_host(host: &str, default_port: u16) -> Option<(String, u16)> {
    let host = host.trim().to_ascii_lowercase();
    let (name, port) = match host.strip_prefix('[') {
        Some(rest) => {
            let (ip, after) = rest.split_once(']')?;
            ip.parse::<std::net::Ipv6Addr>().ok()?;
            let port = match after {
                "" => None,
                p => Some(p.strip_prefix(':')?),
            };
            (ip.to_owned(), port)
        }
        None => {
            let (name, port) = match host.rsplit_once(':') {
                Some((n, p)) => (n, Some(p)),
                None => (host.as_str(), None),
            };
            if name.parse::<std::net::Ipv6Addr>().is_ok() {
                return None;
            }
            (name.strip_suffix('.').unwrap_or(name).to_owned(), port)
        }
    };
    let port = match port {
        Some(p) => p.parse().ok()?,
        None => default_port,
    };
    (!name.is_empty()).then_some((name, port))
}

/// Who may talk to the server.
#[derive(Debug, Clone, PartialEq)]
pub struct Access {
    /// The `Host` values answered, as a refusal lists them.
    pub hosts: Vec<String>,
    /// Any host (with the right port) is answered: bound to every interface, the token guards.
    pub any_host_on_port: Option<u16>,
    /// The token required on every request, when there is one.
    pub token: Option<String>,
    /// The bound address, an IPv4-mapped one as its IPv4 address.
    ip: IpAddr,
    /// The bound port.
    port: u16,
    /// Host names answered (`localhost`, `--allow-host` names) with their ports.
    names: Vec<(String, u16)>,
    /// Addresses given with `--allow-host`, with their ports.
    ips: Vec<(IpAddr, u16)>,
}

impl Access {
    /// The access rules of a server bound at `addr` with `token` (required on every request
    /// when given); `extra` are more host names (`--allow-host`, with or without port).
    pub fn new(addr: SocketAddr, token: Option<String>, extra: &[String]) -> Self {
        let port = addr.port();
        let ip = canonical(addr.ip());
        let show = |ip: IpAddr| match ip {
            IpAddr::V4(a) => format!("{a}:{port}"),
            IpAddr::V6(a) => format!("[{a}]:{port}"),
        };
        let mut hosts = vec![show(addr.ip()), show(ip), format!("localhost:{port}")];
        if ip.is_loopback() {
            hosts.push(format!("127.0.0.1:{port}"));
            hosts.push(format!("[::1]:{port}"));
        }
        let mut names = vec![("localhost".to_owned(), port)];
        let mut ips = Vec::new();
        for h in extra {
            let Some((name, p)) = split_host(h, port) else {
                continue;
            };
            match name.parse::<IpAddr>() {
                Ok(a) => {
                    ips.push((canonical(a), p));
                    hosts.push(show_host(&name, p));
                }
                Err(_) => {
                    hosts.push(format!("{name}:{p}"));
                    names.push((name, p));
                }
            }
        }
        let mut seen = std::collections::BTreeSet::new();
        hosts.retain(|h| seen.insert(h.clone()));
        Self {
            hosts,
            any_host_on_port: addr.ip().is_unspecified().then_some(port),
            token,
            ip,
            port,
            names,
            ips,
        }
    }

    /// Whether a request naming `host` (a `Host` header or a request URI's authority) is
    /// answered.
    pub fn host_allowed(&self, host: &str) -> bool {
        let Some((name, port)) = split_host(host, 80) else {
            return false;
        };
        if self.any_host_on_port == Some(port) {
            return true;
        }
        match name.parse::<IpAddr>() {
            Ok(ip) => {
                let ip = canonical(ip);
                (port == self.port
                    && (ip == self.ip || (self.ip.is_loopback() && ip.is_loopback())))
                    || self.ips.contains(&(ip, port))
            }
            Err(_) => self.names.contains(&(name, port)),
        }
    }

    /// Whether the request carries the token (always, when the server has none).
    pub fn token_ok(&self, headers: &HeaderMap, query: Option<&str>) -> bool {
        let Some(token) = &self.token else {
            return true;
        };
        let eq = |a: &str| {
            a.len() == token.len()
                && a.bytes()
                    .zip(token.bytes())
                    .fold(0, |d, (x, y)| d | (x ^ y))
                    == 0
        };
        // The scheme is case-insensitive (RFC 7235).
        let bearer = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.split_once(' '))
            .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
            .map(|(_, t)| t.trim_start());
        let cookie = headers
            .get_all(header::COOKIE)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(';'))
            .filter_map(|c| c.trim().strip_prefix(TOKEN_COOKIE)?.strip_prefix('='))
            .any(eq);
        cookie || bearer.is_some_and(eq) || query_token(query).is_some_and(eq)
    }
}

/// `name:port`, an IPv6 address bracketed.
fn show_host(name: &str, port: u16) -> String {
    if name.contains(':') {
        format!("[{name}]:{port}")
    } else {
        format!("{name}:{port}")
    }
}

/// The token of a query string (`token=...`).
pub fn query_token(query: Option<&str>) -> Option<&str> {
    query?.split('&').find_map(|kv| kv.strip_prefix("token="))
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(pairs: &[(&'static str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (n, v) in pairs {
            h.append(*n, HeaderValue::from_str(v).unwrap());
        }
        h
    }

    #[test]
    fn loopback_answers_only_its_own_names_and_needs_no_token_unless_given() {
        let a = Access::new("127.0.0.1:8750".parse().unwrap(), None, &[]);
        for ok in [
            "127.0.0.1:8750",
            "localhost:8750",
            "LOCALHOST:8750",
            "localhost.:8750",
            "[::1]:8750",
            "[0:0:0:0:0:0:0:1]:8750",
            "[::ffff:127.0.0.1]:8750",
        ] {
            assert!(a.host_allowed(ok), "{ok}");
        }
        for bad in [
            "evil.example:8750",
            "127.0.0.1:8751",
            "localhost",
            "",
            "127.0.0.1.evil:8750",
            "::1:8750",
            "[::1]x:8750",
            "[evil]:8750",
            "10.0.0.1:8750",
        ] {
            assert!(!a.host_allowed(bad), "{bad}");
        }
        assert_eq!(a.token, None);
        assert!(a.token_ok(&HeaderMap::new(), None));
        // A token given is a token enforced, on loopback too.
        let t = Access::new("127.0.0.2:8750".parse().unwrap(), Some("abc".into()), &[]);
        assert!(!t.token_ok(&HeaderMap::new(), None));
        assert!(t.token_ok(&headers(&[("authorization", "Bearer abc")]), None));
    }

    #[test]
    fn an_ipv4_mapped_address_is_answered_in_every_spelling() {
        let a = Access::new("[::ffff:127.0.0.2]:9000".parse().unwrap(), None, &[]);
        assert!(is_loopback("::ffff:127.0.0.2".parse().unwrap()));
        for ok in [
            "[::ffff:127.0.0.2]:9000",
            "[::ffff:7f00:2]:9000",
            "[::FFFF:7F00:2]:9000",
            "[0:0:0:0:0:ffff:7f00:2]:9000",
            "127.0.0.2:9000",
            "localhost:9000",
        ] {
            assert!(a.host_allowed(ok), "{ok}");
        }
        assert!(!a.host_allowed("[::ffff:7f00:2]:9001"));
        let lan = Access::new("[::ffff:10.0.0.5]:80".parse().unwrap(), None, &[]);
        for ok in ["[::ffff:a00:5]", "10.0.0.5", "10.0.0.5:80"] {
            assert!(lan.host_allowed(ok), "{ok}");
        }
        assert!(!lan.host_allowed("127.0.0.1:80"));
    }

    #[test]
    fn beyond_loopback_the_token_is_required_by_cookie_bearer_or_query() {
        let a = Access::new(
            "10.0.0.5:9000".parse().unwrap(),
            Some("abc".into()),
            &[
                "lab-pc".into(),
                "[fd00::7]".into(),
                "192.168.1.9:9001".into(),
            ],
        );
        assert!(a.host_allowed("10.0.0.5:9000") && a.host_allowed("lab-pc:9000"));
        assert!(a.host_allowed("[fd00:0::7]:9000") && a.host_allowed("192.168.1.9:9001"));
        assert!(!a.host_allowed("127.0.0.1:9000") && !a.host_allowed("192.168.1.9:9000"));
        assert!(!a.token_ok(&HeaderMap::new(), None));
        assert!(a.token_ok(&headers(&[("cookie", "x=1; explore_token=abc")]), None));
        assert!(a.token_ok(&headers(&[("authorization", "Bearer abc")]), None));
        assert!(a.token_ok(&HeaderMap::new(), Some("a=1&token=abc")));
        for wrong in [
            "explore_token=abd",
            "explore_token=ab",
            "explore_tokenx=abc",
        ] {
            assert!(!a.token_ok(&headers(&[("cookie", wrong)]), None), "{wrong}");
        }
        let any = Access::new("0.0.0.0:9000".parse().unwrap(), Some("abc".into()), &[]);
        assert!(any.host_allowed("192.168.1.20:9000") && !any.host_allowed("192.168.1.20:9001"));
    }
}
