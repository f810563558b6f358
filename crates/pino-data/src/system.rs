//! The system description as the stages see it.
//!
//! A stage that reads the description names its file as the first argument of its command
//! (`cmd: [simulate, "${constants.system}"]`, so the orchestrator hashes the file into the
//! stage's identity) and takes the run's parameter overrides from its `system_values`
//! parameter. `sample-params` writes the description it sampled from as `system.json` beside
//! `params.parquet`, `simulate` beside every dataset shard; the stages after them read that
//! record instead of the file, so they learn from exactly the description the data came from,
//! and a stage that reads both refuses a mismatch. [`declare_units`] states the unit of every
//! column the description defines, for the Parquet writers.

use crate::{Error, Result};
use mbd_system::system::{ParamSource, Role};
use mbd_system::{Override, System, SystemSource, SYSTEM_FILE};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// File `irregularity` writes beside its profiles: the generator's controls (seed, dx, length).
pub const PROFILES_FILE: &str = "profiles.json";
/// File `simulate` writes beside every dataset shard: `{"run": <the run controls>,
/// "profiles": <the irregularity stage's profiles.json, or null>}`, how the data were made.
pub const RUN_FILE: &str = "run.json";

/// Writes a JSON value atomically.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("serialisable");
    atomic_file::write_atomic(path, text.as_bytes()).map_err(|e| Error::Io {
        path: path.to_owned(),
        source: std::io::Error::other(e.to_string()),
    })
}

/// Reads a JSON file.
pub fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_owned(),
        source,
    })?;
    serde_json::from_str(&text)
        .map_err(|e| Error::System(format!("{}: malformed JSON: {e}", path.display())))
}

/// The description's path: the first argument of the stage's command that is not
/// `--context FILE`.
pub fn description_path() -> Result<PathBuf> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--context" {
            it.next();
            continue;
        }
        return Ok(PathBuf::from(a));
    }
    Err(Error::System(
        "no system description: the stage's command names it, as in `cmd: [simulate, \"${constants.system}\"]` with `constants: {system: systems/vtcd.yaml}`".to_owned(),
    ))
}

/// Reads and compiles the description the command names, with `values` overriding its
/// parameters; the error lists every problem with its line.
pub fn load(values: &BTreeMap<String, Override>) -> Result<(SystemSource, System)> {
    let path = description_path()?;
    let source =
        SystemSource::read(&path, values.clone()).map_err(|e| Error::System(e.to_string()))?;
    let system = source.compile().map_err(|e| Error::System(e.to_string()))?;
    Ok((source, system))
}

/// Writes `source` as `system.json` into `dir` (atomically).
pub fn write_record(dir: &Path, source: &SystemSource) -> Result<()> {
    let path = dir.join(SYSTEM_FILE);
    atomic_file::write_atomic(&path, source.to_json().as_bytes()).map_err(|e| Error::Io {
        path: path.clone(),
        source: std::io::Error::other(e.to_string()),
    })
}

/// Reads the `system.json` of every directory in `dirs` (shards of one artifact), checks they
/// are one description, and compiles it.
pub fn read_record(dirs: &[PathBuf]) -> Result<(SystemSource, System)> {
    let mut first: Option<(PathBuf, SystemSource)> = None;
    for dir in dirs {
        let path = dir.join(SYSTEM_FILE);
        let source = SystemSource::load_record(&path).map_err(|e| Error::System(e.to_string()))?;
        match &first {
            None => first = Some((path, source)),
            Some((p0, s0)) => same(p0, s0, &path, &source)?,
        }
    }
    let (path, source) =
        first.ok_or_else(|| Error::System("no input directory holds a system.json".to_owned()))?;
    let system = source
        .compile()
        .map_err(|e| Error::System(format!("{}: {e}", path.display())))?;
    Ok((source, system))
}

/// Refuses two different descriptions (text or overrides), naming both records.
pub fn same(a_path: &Path, a: &SystemSource, b_path: &Path, b: &SystemSource) -> Result<()> {
    if a.hash() == b.hash() {
        return Ok(());
    }
    let what = if a.text != b.text {
        "descriptions"
    } else {
        "parameter overrides (system_values)"
    };
    Err(Error::System(format!(
        "{} ({}) and {} ({}) differ in their {what}: every stage of a run must use one description; rerun the upstream stages",
        a_path.display(),
        a.file,
        b_path.display(),
        b.file
    )))
}

/// Declares the unit of every column `system` defines: its parameters (as written in the
/// description), its stored channels, the magnitude weight `phi_<dof>` of every DOF (N, or
/// N m for a pitch) and its index columns (the railway family's when it binds them, its own).
pub fn declare_units(system: &System) -> Result<()> {
    let mut pairs: Vec<(String, String)> = Vec::new();
    for p in &system.parameters {
        if matches!(p.source, ParamSource::Sampled { .. }) {
            pairs.push((p.name.clone(), p.unit.clone()));
        }
    }
    for c in &system.channels {
        pairs.push((c.name.clone(), c.unit.clone()));
    }
    for d in &system.dofs {
        let unit = match d.kind {
            mbd_system::schema::DofKind::Z => "N",
            mbd_system::schema::DofKind::Pitch => "N m",
        };
        pairs.push((phi_column(&d.name), unit.to_owned()));
    }
    for ix in pino_indices::IndexSet::of(system).columns(system) {
        pairs.push((ix.name, ix.unit));
    }
    crate::units::declare(pairs.iter().map(|(n, u)| (n.as_str(), u.as_str())))
}

/// The magnitude-weight column of DOF `dof`: `phi_z_c`.
pub fn phi_column(dof: &str) -> String {
    format!("phi_{dof}")
}

/// The stored channels of a role, by name.
pub fn channel_names(system: &System, role: Role) -> Vec<String> {
    system
        .channels_of(role)
        .into_iter()
        .map(|i| system.channels[i].name.clone())
        .collect()
}
