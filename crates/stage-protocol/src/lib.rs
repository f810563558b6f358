//! The **stage protocol** of pino-mbd: the contract between the orchestrator (`pipeline`)
//! and a stage process, written once and used by both sides (the orchestrator writes and
//! reads with this crate, `stage-kit` wraps it for stages).
//!
//! - The orchestrator starts a stage with the environment variable [`CONTEXT_ENV`] holding
//!   the path of a JSON context file ([`Context`], written by [`Context::to_json`], read by
//!   [`Context::parse`], which refuses any other [`PROTOCOL_VERSION`] and unknown fields).
//! - The stage prints protocol lines on stdout: `::progress DONE TOTAL [MESSAGE]`
//!   ([`progress_line`]) and `::summary TEXT` ([`summary_line`]); in check mode it may print
//!   `::work AMOUNT` ([`work_line`]), its work relative to the other units of its stage, which
//!   the orchestrator uses to start the biggest first when no run of the unit is on record.
//!   [`parse_line`] reads them back, and every other line is plain log.
//!
//! The protocol version is hashed into every stage identity: changing the contract
//! recomputes every artifact. The format of the store's manifests is versioned separately
//! (in the orchestrator), since it can change without any stage noticing. The full text of
//! the protocol, with an example context, is `docs/protocol.md`.
#![warn(missing_docs)]

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The protocol version both sides speak.
pub const PROTOCOL_VERSION: u32 = 1;
/// Environment variable that carries the context file's path.
pub const CONTEXT_ENV: &str = "PINO_STAGE_CONTEXT";
/// Name of the context file in a unit's working directory.
pub const CONTEXT_FILE: &str = "context.json";
/// Prefix of a progress line.
pub const PROGRESS_PREFIX: &str = "::progress";
/// Prefix of a summary line.
pub const SUMMARY_PREFIX: &str = "::summary";
/// Prefix of a check mode's work line.
pub const WORK_PREFIX: &str = "::work";

/// Which part of a sharded stage a process computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shard {
    /// Zero-based shard index, `index < count`.
    pub index: usize,
    /// Number of shards (1 when the stage is not sharded).
    pub count: usize,
}

impl Shard {
    /// The only shard of an unsharded stage.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Whether item `i` (for example a sample id) belongs to this shard (round robin, so
    /// shards get equal work whatever the item order).
    pub fn owns(&self, i: u64) -> bool {
        i % self.count as u64 == self.index as u64
    }
}

impl Default for Shard {
    fn default() -> Self {
        Self::WHOLE
    }
}

/// The context file: everything the orchestrator tells one stage process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Context {
    /// [`PROTOCOL_VERSION`] of the writer.
    pub protocol: u32,
    /// Stage name as the pipeline knows it (matrix expansions carry their values, as in
    /// `train[algorithm=3]`).
    pub stage: String,
    /// The stage's resolved parameters (defaults, matrix values, constants and `--set`
    /// overrides applied).
    #[serde(default)]
    pub params: serde_json::Value,
    /// For each declared input, the directories that together form that upstream artifact:
    /// one for a plain stage, one per shard (in shard order) or per matrix expansion.
    #[serde(default)]
    pub inputs: BTreeMap<String, Vec<PathBuf>>,
    /// An existing, empty directory the stage writes its files into.
    pub output: PathBuf,
    /// A directory that survives failed or killed attempts of this very unit and is deleted
    /// after its output is committed: the place for resumable state.
    #[serde(default)]
    pub scratch: Option<PathBuf>,
    /// This process's shard (0 of 1 when unsharded).
    #[serde(default)]
    pub shard: Shard,
    /// Check mode: validate the parameters (and any file the command names) and exit, 0 when
    /// the unit could run, nonzero with the reason on stderr otherwise; read no input and write
    /// no output. The orchestrator runs it for the units of a stage with `check: true` before
    /// anything runs (absent: a normal run).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub check: bool,
}

/// Why a context file was refused.
#[derive(Debug)]
pub enum ParseError {
    /// Not valid context JSON (the error names line, column and field).
    Malformed(serde_json::Error),
    /// Written for another protocol version.
    Version {
        /// Version found in the file.
        found: u32,
    },
}

impl std::fmt::Display for ParseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParseError::Malformed(e) => write!(f, "{e}"),
            ParseError::Version { found } => {
                write!(f, "protocol {found}, this side speaks {PROTOCOL_VERSION}")
            }
        }
    }
}

impl std::error::Error for ParseError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ParseError::Malformed(e) => Some(e),
            ParseError::Version { .. } => None,
        }
    }
}

impl Context {
    /// The context's JSON text (pretty-printed, keys in a fixed order).
    pub fn to_json(&self) -> Vec<u8> {
        serde_json::to_vec_pretty(self).expect("a context is always serialisable")
    }

    /// Parses a context file's text, refusing another protocol version.
    pub fn parse(text: &str) -> Result<Self, ParseError> {
        // The version is checked first, so a future format is reported as such rather than
        // as an unknown field.
        #[derive(Deserialize)]
        struct Version {
            protocol: u32,
        }
        let v: Version = serde_json::from_str(text).map_err(ParseError::Malformed)?;
        if v.protocol != PROTOCOL_VERSION {
            return Err(ParseError::Version { found: v.protocol });
        }
        serde_json::from_str(text).map_err(ParseError::Malformed)
    }
}

/// One line of a stage's stdout, as the protocol reads it.
#[derive(Debug, Clone, PartialEq)]
pub enum Line<'a> {
    /// `::progress DONE TOTAL [MESSAGE]`.
    Progress {
        /// Units done.
        done: u64,
        /// Units in all.
        total: u64,
        /// Message (empty when none).
        message: &'a str,
    },
    /// `::summary TEXT`: the stage's one-line result.
    Summary(&'a str),
    /// `::work AMOUNT` (check mode): the unit's work relative to its stage's other units, a
    /// finite number > 0 (a scheduling estimate; no unit).
    Work(f64),
    /// Anything else: plain log.
    Log(&'a str),
}

/// Reads one stdout line (a malformed protocol line is plain log).
pub fn parse_line(line: &str) -> Line<'_> {
    if let Some(rest) = line
        .strip_prefix(PROGRESS_PREFIX)
        .and_then(|r| r.strip_prefix(' '))
    {
        let mut it = rest.splitn(3, ' ');
        let done = it.next().and_then(|s| s.parse().ok());
        let total = it.next().and_then(|s| s.parse().ok());
        if let (Some(done), Some(total)) = (done, total) {
            return Line::Progress {
                done,
                total,
                message: it.next().unwrap_or("").trim(),
            };
        }
    } else if let Some(text) = line
        .strip_prefix(SUMMARY_PREFIX)
        .and_then(|r| r.strip_prefix(' '))
    {
        return Line::Summary(text.trim());
    } else if let Some(amount) = line
        .strip_prefix(WORK_PREFIX)
        .and_then(|r| r.strip_prefix(' '))
        .and_then(|r| r.trim().parse::<f64>().ok())
        .filter(|w| w.is_finite() && *w > 0.0)
    {
        return Line::Work(amount);
    }
    Line::Log(line)
}

/// `::progress DONE TOTAL [MESSAGE]` (no newline; line breaks in the message become spaces).
pub fn progress_line(done: u64, total: u64, message: Option<&str>) -> String {
    match message {
        Some(m) => format!("{PROGRESS_PREFIX} {done} {total} {}", one_line(m)),
        None => format!("{PROGRESS_PREFIX} {done} {total}"),
    }
}

/// `::summary TEXT` (no newline; line breaks in the text become spaces).
pub fn summary_line(text: &str) -> String {
    format!("{SUMMARY_PREFIX} {}", one_line(text))
}

/// `::work AMOUNT` (no newline): a check mode's estimate of its unit's work.
pub fn work_line(amount: f64) -> String {
    format!("{WORK_PREFIX} {amount}")
}

fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Context {
        Context {
            protocol: PROTOCOL_VERSION,
            stage: "train[algorithm=3]".into(),
            params: serde_json::json!({"epochs": 40, "algorithm": 3}),
            inputs: BTreeMap::from([(
                "dataset".to_owned(),
                vec![PathBuf::from("/ws/a/out"), PathBuf::from("/ws/b/out")],
            )]),
            output: "/ws/tmp/x/out".into(),
            scratch: Some("/ws/scratch/x".into()),
            shard: Shard { index: 1, count: 4 },
            check: false,
        }
    }

    #[test]
    fn context_round_trips_through_its_own_text() {
        let c = sample();
        let text = String::from_utf8(c.to_json()).unwrap();
        assert_eq!(Context::parse(&text).unwrap(), c);
    }

    #[test]
    fn optional_fields_default_and_unknown_fields_are_refused() {
        let c = Context::parse(r#"{"protocol":1,"stage":"s","output":"/o"}"#).unwrap();
        assert_eq!(
            (c.shard, c.scratch, c.inputs.len(), c.check),
            (Shard::WHOLE, None, 0, false)
        );
        // Check mode is written only when set, so normal contexts keep their text.
        assert!(!String::from_utf8(sample().to_json())
            .unwrap()
            .contains("check"));
        let checked = Context {
            check: true,
            ..sample()
        };
        let text = String::from_utf8(checked.to_json()).unwrap();
        assert!(Context::parse(&text).unwrap().check);
        let e = Context::parse(r#"{"protocol":1,"stage":"s","output":"/o","extra":1}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown field `extra`"), "{e}");
    }

    #[test]
    fn another_version_is_refused_before_its_fields_are_read() {
        let e = Context::parse(r#"{"protocol":9,"whatever":true}"#).unwrap_err();
        assert!(matches!(e, ParseError::Version { found: 9 }), "{e}");
        assert!(matches!(
            Context::parse("{ not json"),
            Err(ParseError::Malformed(_))
        ));
    }

    #[test]
    fn lines_round_trip_and_anything_else_is_log() {
        let p = progress_line(3, 10, Some("loss\n0.5"));
        assert_eq!(p, "::progress 3 10 loss 0.5");
        assert_eq!(
            parse_line(&p),
            Line::Progress {
                done: 3,
                total: 10,
                message: "loss 0.5"
            }
        );
        assert_eq!(
            parse_line(&progress_line(0, 4, None)),
            Line::Progress {
                done: 0,
                total: 4,
                message: ""
            }
        );
        assert_eq!(
            parse_line(&summary_line("all good")),
            Line::Summary("all good")
        );
        assert_eq!(parse_line(&work_line(2.5e3)), Line::Work(2500.0));
        for log in [
            "::work 0",
            "::work -3",
            "::work NaN",
            "::work inf",
            "::workload 3",
            "::progress x 4",
            "::progress 1",
            "::progressive 1 2",
            "hello",
            "::summaryX",
        ] {
            assert_eq!(parse_line(log), Line::Log(log));
        }
    }

    #[test]
    fn shards_partition_the_items() {
        let shards: Vec<Shard> = (0..3).map(|index| Shard { index, count: 3 }).collect();
        for i in 0..30u64 {
            assert_eq!(shards.iter().filter(|s| s.owns(i)).count(), 1);
        }
    }
}
