//! Compressed answers: the content coding a client accepts (`Accept-Encoding`, RFC 9110
//! section 12.5.3: brotli preferred, then gzip, each unless given `q=0`) and the compression of
//! an answer's body. Only text answers (JSON, HTML, scripts, styles, SVG, CSV, YAML, Markdown)
//! of at least [`MIN_BYTES`] are compressed; PNGs and Parquet files are compressed already.
//! Both coders are pure Rust (`brotli`, `flate2` on `miniz_oxide`).

use std::io::Write;

/// The smallest body worth compressing (bytes): below, the coding's header and the client's
/// work cost more than they save.
pub const MIN_BYTES: usize = 1024;

/// Brotli's quality (0-11): 1 makes a prediction with every band (0.87 MB of float32 curves)
/// 278 kB in about 8 ms, where 5 makes it 264 kB in about 45 ms, time a slider move waits for
/// (BENCHMARKS.md, "Explorer").
const BROTLI_QUALITY: u32 = 1;

/// Brotli's window (log2 bytes): 4 MiB, more than a prediction's answer.
const BROTLI_WINDOW: u32 = 22;

/// gzip's level (0-9): 1, for the same reason (286 kB in about 18 ms; 5: 274 kB, 30 ms).
const GZIP_LEVEL: u32 = 1;

/// A content coding the server answers in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coding {
    /// `br` (RFC 7932).
    Brotli,
    /// `gzip` (RFC 1952).
    Gzip,
}

impl Coding {
    /// Its `Content-Encoding` token.
    pub fn token(self) -> &'static str {
        match self {
            Self::Brotli => "br",
            Self::Gzip => "gzip",
        }
    }
}

/// The weight `q` of one `Accept-Encoding` item (`gzip;q=0.5`): 1 without one, 0 for a
/// malformed one.
fn weight(params: &str) -> f64 {
    params
        .split(';')
        .filter_map(|p| p.trim().split_once('='))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("q"))
        .map_or(1.0, |(_, v)| {
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|q| (0.0..=1.0).contains(q))
                .unwrap_or(0.0)
        })
}

/// The coding to answer in for an `Accept-Encoding` header: the accepted one of highest
/// weight (brotli on a tie), `None` for none (the identity).
pub fn negotiate(accept: &str) -> Option<Coding> {
    let mut wildcard = None;
    let mut named = Vec::new();
    for item in accept.split(',') {
        let (name, params) = item.split_once(';').unwrap_or((item, ""));
        let name = name.trim().to_ascii_lowercase();
        let q = weight(params);
        match name.as_str() {
            "*" => wildcard = Some(q),
            "br" => named.push((Coding::Brotli, q)),
            "gzip" | "x-gzip" => named.push((Coding::Gzip, q)),
            _ => {}
        }
    }
    let q_of = |c: Coding| {
        named
            .iter()
            .filter(|(n, _)| *n == c)
            .map(|&(_, q)| q)
            .fold(None, |a: Option<f64>, q| Some(a.map_or(q, |a| a.max(q))))
            .or(wildcard)
            .unwrap_or(0.0)
    };
    [Coding::Brotli, Coding::Gzip]
        .into_iter()
        .map(|c| (c, q_of(c)))
        .filter(|&(_, q)| q > 0.0)
        .fold(None, |best: Option<(Coding, f64)>, (c, q)| match best {
            Some((_, bq)) if bq >= q => best,
            _ => Some((c, q)),
        })
        .map(|(c, _)| c)
}

/// Whether an answer of `content_type` is worth compressing (text, not images or Parquet).
pub fn compressible(content_type: &str) -> bool {
    let t = content_type
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    t.starts_with("text/")
        || matches!(
            t.as_str(),
            "application/json" | "application/javascript" | "application/yaml" | "image/svg+xml"
        )
}

/// `bytes` compressed with `coding`.
pub fn compress(coding: Coding, bytes: &[u8]) -> std::io::Result<Vec<u8>> {
    match coding {
        Coding::Brotli => {
            let mut out = Vec::with_capacity(bytes.len() / 4);
            {
                let mut w = brotli::CompressorWriter::new(
                    &mut out,
                    64 * 1024,
                    BROTLI_QUALITY,
                    BROTLI_WINDOW,
                );
                w.write_all(bytes)?;
                w.flush()?;
            }
            Ok(out)
        }
        Coding::Gzip => {
            let mut w = flate2::write::GzEncoder::new(
                Vec::with_capacity(bytes.len() / 4),
                flate2::Compression::new(GZIP_LEVEL),
            );
            w.write_all(bytes)?;
            w.finish()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn the_accepted_coding_of_highest_weight_is_chosen_brotli_on_a_tie() {
        for (accept, want) in [
            ("gzip, deflate, br, zstd", Some(Coding::Brotli)),
            ("gzip, deflate", Some(Coding::Gzip)),
            ("GZIP", Some(Coding::Gzip)),
            ("x-gzip", Some(Coding::Gzip)),
            ("br;q=0.5, gzip;q=0.8", Some(Coding::Gzip)),
            ("br;q=0, gzip", Some(Coding::Gzip)),
            ("br;q=0, gzip;q=0", None),
            ("identity", None),
            ("", None),
            ("deflate", None),
            ("*", Some(Coding::Brotli)),
            ("*;q=0.1, br;q=0", Some(Coding::Gzip)),
            ("gzip;q=2", None),
            ("gzip;q=x", None),
        ] {
            assert_eq!(negotiate(accept), want, "{accept:?}");
        }
    }

    #[test]
    fn text_is_compressed_and_decompresses_to_itself() {
        assert!(compressible("application/json") && compressible("text/html; charset=utf-8"));
        assert!(compressible("application/javascript") && compressible("image/svg+xml"));
        assert!(!compressible("image/png") && !compressible("application/vnd.apache.parquet"));
        let text = serde_json::json!({"t": (0..5000).map(|k| k as f64 * 1e-3).collect::<Vec<_>>()})
            .to_string();
        let br = compress(Coding::Brotli, text.as_bytes()).unwrap();
        let mut back = String::new();
        brotli::Decompressor::new(&br[..], 4096)
            .read_to_string(&mut back)
            .unwrap();
        assert_eq!(back, text);
        let gz = compress(Coding::Gzip, text.as_bytes()).unwrap();
        let mut back = String::new();
        flate2::read::GzDecoder::new(&gz[..])
            .read_to_string(&mut back)
            .unwrap();
        assert_eq!(back, text);
        // Numbers of few digits, as a time axis: less than half, even at the fast levels.
        assert!(
            br.len() * 2 < text.len() && gz.len() * 2 < text.len(),
            "{} {} {}",
            br.len(),
            gz.len(),
            text.len()
        );
    }
}
