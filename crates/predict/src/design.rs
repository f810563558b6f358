//! The design parameters of a model's system ([`DesignSpace`]): names, nominal values,
//! designs parsed from YAML and `name=value` overrides, each value checked by name.

use crate::Error;
use crate::Result;
use mbd_system::model::FieldError;
use mbd_system::System;
use pino_data::{Column, Table};
use pino_learn::Error as LearnError;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// The design parameters of a model's system: its sampled parameters, by name, with their
/// nominal values.
#[derive(Debug, Clone)]
pub struct DesignSpace {
    system: Arc<System>,
    names: Vec<String>,
    nominal: Vec<f64>,
}

impl DesignSpace {
    /// The sampled parameters of `system`.
    pub fn of(system: Arc<System>) -> Self {
        let names = system
            .sampled_names()
            .into_iter()
            .map(str::to_owned)
            .collect();
        let nominal = system.nominal().into_values();
        Self {
            system,
            names,
            nominal,
        }
    }

    /// Parameter names, in value order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The nominal design.
    pub fn nominal(&self) -> Vec<f64> {
        self.nominal.clone()
    }

    /// Position of parameter `name`, or an error naming `origin`, the system and the allowed
    /// names (a fixed or derived parameter is named as such).
    pub fn index(&self, name: &str, origin: &Path) -> Result<usize> {
        if let Some(k) = self.names.iter().position(|n| n == name) {
            return Ok(k);
        }
        let why = if self.system.parameter(name).is_some() {
            format!(
                "`{name}` is not sampled in the description `{}` (it is fixed or derived there), so the model cannot vary it",
                self.system.name
            )
        } else {
            format!(
                "unknown parameter `{name}` of the system `{}`",
                self.system.name
            )
        };
        Err(Error::format(
            origin,
            format!("{why}; allowed: {}", self.names.join(", ")),
        ))
    }

    /// Sets parameter `name` of `design` to `value`, refused (naming `origin`) when the name is
    /// not a design parameter or the value is not finite.
    pub(super) fn set(
        &self,
        design: &mut [f64],
        name: &str,
        value: f64,
        origin: &Path,
    ) -> Result<()> {
        let k = self.index(name, origin)?;
        if !value.is_finite() {
            return Err(Error::format(
                origin,
                format!("parameter `{name}` = {value} must be finite"),
            ));
        }
        design[k] = value;
        Ok(())
    }

    /// Checks a design against the description's domains (masses positive, ...). The error
    /// is in the user's words: it names the design parameter at fault (`design.m_c`, with
    /// `label` = `design`) and its value, and says which field of the description it makes
    /// leave its domain ([`DesignSpace::blame`]).
    pub fn check(&self, design: &[f64], label: &str) -> Result<mbd_system::model::Model> {
        let sampled = self.system.sampled_values(design)?;
        Ok(self
            .system
            .instantiate(&sampled)
            .map_err(|e| self.blame(design, label, &e))?)
    }

    /// The design parameter a field out of its domain is blamed on: among the sampled
    /// parameters the field is computed from, the first whose value differs from its nominal
    /// one (what the user changed), else the first of them. The error's field is
    /// `{label}.{name}`, its value the design's, and what is allowed says which field it made
    /// invalid and its value there (with the other changed parameters it was computed with).
    /// A field that no design parameter reaches is named as the description's
    /// (`{label}: {path}`).
    pub fn blame(&self, design: &[f64], label: &str, e: &FieldError) -> LearnError {
        let position = |name: &str| self.names.iter().position(|n| n == name);
        let changed = |k: &usize| design[*k] != self.nominal[*k];
        let sources: Vec<usize> = e.sources.iter().filter_map(|n| position(n)).collect();
        let Some(&k) = sources.iter().find(|k| changed(k)).or(sources.first()) else {
            return LearnError::OutOfRange {
                field: format!("{label}: {}", e.path),
                value: e.value.to_string(),
                allowed: e.allowed.clone(),
            };
        };
        let name = &self.names[k];
        let allowed = if e.path == format!("parameters.{name}") {
            e.allowed.clone()
        } else {
            let with: Vec<String> = sources
                .iter()
                .filter(|&&j| j != k && changed(&j))
                .map(|&j| format!("`{}` = {}", self.names[j], design[j]))
                .collect();
            let with = if with.is_empty() {
                String::new()
            } else {
                format!(", with {}", with.join(", "))
            };
            format!(
                "values that keep `{}` {} (this one makes it {}{with})",
                e.path, e.allowed, e.value
            )
        };
        LearnError::OutOfRange {
            field: format!("{label}.{name}"),
            value: design[k].to_string(),
            allowed,
        }
    }

    /// The design parameter a run that leaves its profiles or a refusing beam is blamed on,
    /// and the limit it may reach: among the sampled parameters the frame speed and the moving
    /// points' offsets are computed from, the first the user changed (differs from nominal)
    /// whose nominal value `runs` accepts with the rest of the design; its limit is found by
    /// bisection between the nominal value and the design's, and the error says "at most" or
    /// "at least" it (6 significant digits, rounded to the accepted side) with `why`. A run no
    /// changed parameter explains is the design's (`{label}: why`).
    pub fn blame_run(
        &self,
        design: &[f64],
        label: &str,
        why: &str,
        runs: impl Fn(&[f64]) -> bool,
    ) -> crate::Error {
        let exprs =
            std::iter::once(&self.system.speed).chain(self.system.points.iter().map(|p| &p.offset));
        let sources = self
            .system
            .sampled_sources(exprs.flat_map(|e| e.parameters()));
        for name in &sources {
            let Some(k) = self.names.iter().position(|n| n == name) else {
                continue;
            };
            let with = |x: f64| {
                let mut d = design.to_vec();
                d[k] = x;
                d
            };
            let (mut good, mut bad) = (self.nominal[k], design[k]);
            if good == bad || !runs(&with(good)) {
                continue;
            }
            for _ in 0..64 {
                let mid = 0.5 * (good + bad);
                if mid == good || mid == bad {
                    break;
                }
                if runs(&with(mid)) {
                    good = mid;
                } else {
                    bad = mid;
                }
            }
            let above = bad > good;
            let limit = round_towards(good, 6, !above);
            let limit = if runs(&with(limit)) { limit } else { good };
            return LearnError::OutOfRange {
                field: format!("{label}.{name}"),
                value: design[k].to_string(),
                allowed: format!(
                    "{} {limit} with the rest of this design: {why}",
                    if above { "at most" } else { "at least" }
                ),
            }
            .into();
        }
        Error::format(Path::new(label), why.to_owned())
    }

    /// Parses designs from YAML text (`origin` names the file in errors).
    pub fn parse_sets(&self, text: &str, origin: &Path) -> Result<Vec<Vec<f64>>> {
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Doc {
            List(Vec<BTreeMap<String, f64>>),
            Sets { sets: Vec<BTreeMap<String, f64>> },
        }
        let doc: Doc = serde_yaml::from_str(text).map_err(|e| {
            Error::format(
                origin,
                format!("expected a list of parameter maps or `sets: [...]` with numbers: {e}"),
            )
        })?;
        let maps = match doc {
            Doc::List(l) | Doc::Sets { sets: l } => l,
        };
        if maps.is_empty() {
            return Err(Error::format(origin, "no parameter set given".into()));
        }
        maps.iter()
            .map(|m| {
                let mut p = self.nominal();
                for (k, v) in m {
                    self.set(&mut p, k, *v, origin)?;
                }
                Ok(p)
            })
            .collect()
    }

    /// Applies `name=value` to every design.
    pub fn apply_override(&self, sets: &mut [Vec<f64>], assignment: &str) -> Result<()> {
        let origin = Path::new("--set");
        let (name, value) = assignment
            .split_once('=')
            .ok_or_else(|| Error::format(origin, format!("`{assignment}`: expected name=value")))?;
        let value: f64 = value.trim().parse().map_err(|_| {
            Error::format(origin, format!("`{assignment}`: `{value}` is not a number"))
        })?;
        for s in sets.iter_mut() {
            self.set(s, name.trim(), value, origin)?;
        }
        Ok(())
    }

    /// The designs as a table: one column per parameter.
    pub fn push_columns(&self, table: &mut Table, sets: &[Vec<f64>]) -> Result<()> {
        for (j, name) in self.names.iter().enumerate() {
            table.push(name, Column::F64(sets.iter().map(|p| p[j]).collect()))?;
        }
        Ok(())
    }
}

/// `x` to `digits` significant digits, rounded up (`up`) or down.
pub(super) fn round_towards(x: f64, digits: i32, up: bool) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    // Dividing by a power of ten (not multiplying by its inverse) keeps a short decimal.
    let e = digits - 1 - x.abs().log10().floor() as i32;
    let p = 10f64.powi(e.abs());
    let q = if e >= 0 { x * p } else { x / p };
    let q = if up { q.ceil() } else { q.floor() };
    if e >= 0 {
        q / p
    } else {
        q * p
    }
}
