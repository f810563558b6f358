//! The system description as the data records it.
//!
//! (A stage loads the description its command names with `stage_kit::load_description`.)
//! `sample-params` writes the description it sampled from as `system.json` beside
//! `params.parquet`, `simulate` beside every dataset shard; the stages after them read that
//! record instead of the file, so they learn from exactly the description the data came from,
//! and a stage that reads both refuses a mismatch. [`units_of`] gives the unit of every column
//! the description defines but its indices' (which the indices crate declares), for the tables
//! the Parquet writers write.

use crate::artifacts::{PARAMS_FILE, RANGES_FILE};
use crate::units::Units;
use crate::{Error, Result};
use mbd_system::system::{ParamSource, Role};
use mbd_system::{System, SystemSource, SYSTEM_FILE};
use std::path::{Path, PathBuf};

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
    let (path, source) = read_source(dirs)?;
    let system = source
        .compile()
        .map_err(|e| Error::System(format!("{}: {e}", path.display())))?;
    Ok((source, system))
}

/// Reads the `system.json` of every directory in `dirs` (shards of one artifact) and checks
/// they are one description, without compiling it: the first record's path and the record.
pub fn read_source(dirs: &[PathBuf]) -> Result<(PathBuf, SystemSource)> {
    let mut first: Option<(PathBuf, SystemSource)> = None;
    for dir in dirs {
        let path = dir.join(SYSTEM_FILE);
        let source = SystemSource::load_record(&path).map_err(|e| Error::System(e.to_string()))?;
        match &first {
            None => first = Some((path, source)),
            Some((p0, s0)) => same(p0, s0, &path, &source)?,
        }
    }
    first.ok_or_else(|| Error::System("no input directory holds a system.json".to_owned()))
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

/// Writes [`PARAMS_FILE`] and [`RANGES_FILE`] into `dir`, as `sample-params` does: sample
/// `id` (`0..draws.len()`) has split `splits[id]` and the sampled parameters' values
/// `draws[id]` (the description's order); `ranges[k]` is the `[min, max]` of its `k`-th
/// sampled parameter. Returns the path of [`PARAMS_FILE`].
pub fn write_sample_params(
    dir: &Path,
    system: &System,
    splits: &[&str],
    draws: &[Vec<f64>],
    ranges: &[[f64; 2]],
) -> Result<PathBuf> {
    let names = system.sampled_names();
    let mut params = crate::Table::default().with_units(units_of(system)?);
    params.push(
        crate::schema::SAMPLE_ID,
        crate::Column::I64((0..draws.len() as i64).collect()),
    )?;
    params.push(
        crate::schema::SPLIT,
        crate::Column::Str(splits.iter().map(|s| s.to_string()).collect()),
    )?;
    for (j, name) in names.iter().enumerate() {
        params.push(
            name,
            crate::Column::F64(draws.iter().map(|d| d[j]).collect()),
        )?;
    }
    let params_path = dir.join(PARAMS_FILE);
    crate::write_parquet(&params_path, &params)?;

    let mut table = crate::Table::default();
    table.push(
        "name",
        crate::Column::Str(names.iter().map(|s| s.to_string()).collect()),
    )?;
    let units = system
        .sampled()
        .into_iter()
        .map(|i| system.parameters[i].unit.clone())
        .collect();
    table.push("unit", crate::Column::Str(units))?;
    table.push(
        "min",
        crate::Column::F64(ranges.iter().map(|r| r[0]).collect()),
    )?;
    table.push(
        "max",
        crate::Column::F64(ranges.iter().map(|r| r[1]).collect()),
    )?;
    crate::write_parquet(&dir.join(RANGES_FILE), &table)?;
    Ok(params_path)
}

/// The unit of every column `system` defines: its sampled parameters (as written in the
/// description), its stored channels, the magnitude weight `phi_<dof>` of every DOF (N, or
/// N m for a pitch). A name of the description that the fixed table knows with another unit is
/// [`Error::UnitConflict`]. Add a writer's own columns with [`Units::with`]; a writer of index
/// columns adds theirs, which the indices crate declares (`pino_indices::column_units`).
pub fn units_of(system: &System) -> Result<Units> {
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
        pairs.push((phi_column(&d.name), d.kind.force_unit().to_owned()));
    }
    Units::default().with(pairs)
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
