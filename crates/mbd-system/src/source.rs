//! A description as a run uses it: the file's text, where it came from, and the parameter
//! overrides of the run (`system_values`). This is what travels with the artifacts
//! (`system.json` beside `params.parquet`, inside `model.json`), so every later stage and a
//! trained model compile exactly the description the data came from, without the workspace.
//! Its [`SystemSource::hash`] identifies it: two sources with the same text and overrides
//! compile to the same [`System`].

use crate::compile::{load_with_overrides, LoadError, Override, OverrideError};
use crate::diag::Diagnostics;
use crate::System;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The file name of the record beside a stage's outputs.
pub const SYSTEM_FILE: &str = "system.json";

/// A description's text and the run's overrides.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SystemSource {
    /// The file it was read from (as given), for messages.
    pub file: String,
    /// The description's text.
    pub text: String,
    /// Parameter overrides of the run.
    #[serde(default)]
    pub values: BTreeMap<String, Override>,
}

/// Why a source could not be read or compiled.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The file could not be read.
    #[error("{file}: cannot read the system description: {source}")]
    Read {
        /// The file.
        file: String,
        /// The error.
        source: std::io::Error,
    },
    /// The description has problems (each with its line).
    #[error("{0}")]
    Invalid(Diagnostics),
    /// An override of the run (`values`) that the description does not take.
    #[error("{file}: system_values.{error}")]
    Override {
        /// The description's file.
        file: String,
        /// The override refused and why.
        error: OverrideError,
    },
    /// A record is not valid JSON.
    #[error("{file}: malformed system record: {message}")]
    Record {
        /// The file.
        file: String,
        /// What serde said.
        message: String,
    },
}

impl SystemSource {
    /// Reads the description at `path` with the run's `values`.
    pub fn read(path: &Path, values: BTreeMap<String, Override>) -> Result<Self, SourceError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SourceError::Read {
            file: file.clone(),
            source,
        })?;
        Ok(Self { file, text, values })
    }

    /// Parses, validates and compiles it.
    pub fn compile(&self) -> Result<System, SourceError> {
        load_with_overrides(&self.text, &self.file, &self.values).map_err(|e| match e {
            LoadError::Invalid(d) => SourceError::Invalid(d),
            LoadError::Override(error) => SourceError::Override {
                file: self.file.clone(),
                error,
            },
        })
    }

    /// A problem found outside the description's own checks (a run control that does not fit
    /// it) reported as those are: at the line of the field `path` (`profiles.track`,
    /// `moving.points.road`; else its entry, else the top), `file:line:col: message`.
    pub fn problem_at(&self, path: &str, message: impl Into<String>) -> Diagnostics {
        let mut diag = Diagnostics {
            file: self.file.clone(),
            items: Vec::new(),
        };
        let pos = match crate::yaml::parse(&self.text) {
            Ok(root) => {
                let raw = crate::schema::read(&root, &mut Diagnostics::default());
                crate::checks::position(&raw, path)
            }
            Err(_) => crate::yaml::Pos { line: 1, col: 1 },
        };
        diag.push(pos, message);
        diag
    }

    /// blake3 of the text and the overrides (hex).
    pub fn hash(&self) -> String {
        let mut h = blake3::Hasher::new();
        h.update(self.text.as_bytes());
        h.update(&[0]);
        h.update(
            serde_json::to_string(&self.values)
                .expect("serialisable")
                .as_bytes(),
        );
        h.finalize().to_hex().to_string()
    }

    /// The record's JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("serialisable")
    }

    /// Reads a record written by [`SystemSource::to_json`].
    pub fn from_json(text: &str, file: &str) -> Result<Self, SourceError> {
        serde_json::from_str(text).map_err(|e| SourceError::Record {
            file: file.to_owned(),
            message: e.to_string(),
        })
    }

    /// Reads the record file `path`.
    pub fn load_record(path: &Path) -> Result<Self, SourceError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SourceError::Read {
            file: file.clone(),
            source,
        })?;
        Self::from_json(&text, &file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "format: 1\nname: t\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n  k: {unit: N/m, value: 800}\nbodies:\n  b: {mass: m, dofs: [z]}\nelements:\n  s: {kind: spring_damper, from: b, to: ground, k: k}\n";

    #[test]
    fn records_round_trip_and_overrides_change_the_hash() {
        let a = SystemSource {
            file: "t.yaml".into(),
            text: TEXT.into(),
            values: BTreeMap::new(),
        };
        let back = SystemSource::from_json(&a.to_json(), "x").unwrap();
        assert_eq!(back, a);
        assert_eq!(back.hash(), a.hash());
        let mut b = a.clone();
        b.values.insert("k".into(), Override::Value(900.0));
        assert_ne!(b.hash(), a.hash());
        let s = b.compile().unwrap();
        assert_eq!(
            s.instantiate(&s.sampled_values([2.0]).unwrap())
                .unwrap()
                .elements[0]
                .law
                .stiffness(0.0),
            900.0
        );
        b.values.insert("nope".into(), Override::Value(1.0));
        match b.compile().unwrap_err() {
            SourceError::Override { file, error } => {
                assert_eq!((file.as_str(), error.name.as_str()), ("t.yaml", "nope"));
                assert!(
                    error.message.starts_with(
                        "`nope` is not a parameter of the description; parameters: m, k"
                    ),
                    "{}",
                    error.message
                );
            }
            other => panic!("{other}"),
        }
        // The stages' reading: the run's `system_values`, not a line of the file.
        let e = crate::load_str(TEXT, "t.yaml", &b.values)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("system_values.nope: `nope` is not a parameter"),
            "{e}"
        );
    }

    /// A problem is placed at its field's line, else its entry's, else the top.
    #[test]
    fn problems_are_placed_at_the_field_they_name() {
        let a = SystemSource {
            file: "t.yaml".into(),
            text: TEXT.into(),
            values: BTreeMap::new(),
        };
        let report = |path: &str| a.problem_at(path, format!("{path}: wrong")).to_string();
        assert_eq!(report("elements.s"), "t.yaml:9:3: elements.s: wrong");
        assert_eq!(report("bodies.b.mass"), "t.yaml:7:13: bodies.b.mass: wrong");
        assert_eq!(report("profiles.none"), "t.yaml:1:1: profiles.none: wrong");
    }
}
