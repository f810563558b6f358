//! The stage's artifacts: `indices.parquet` (one row per sample) and `indices.json` (the
//! settings used and every column's unit and definition), written atomically with
//! deterministic bytes, and the stage's one-line summary.

use crate::{Computed, Error, Result};
use mbd_system::System;
use pino_data::units::DIMENSIONLESS;
use pino_data::{schema, Column, Table};
use pino_indices::{IndexConfig, IndexSet, Indices};
use std::path::Path;

/// The output table: `sample_id`, `split`, the sampled parameters of `system`, the index
/// columns ([`Computed::columns`]), `window_s`, `pass` (Boolean), `failed` (comma-separated
/// limit names, null when none).
pub fn to_table(system: &System, out: &Computed) -> pino_data::Result<Table> {
    let rows = &out.rows;
    let units = pino_data::system::units_of(system)?.with(pino_indices::column_units(system))?;
    let mut t = Table::default().with_units(units);
    t.push(
        schema::SAMPLE_ID,
        Column::I64(rows.iter().map(|r| r.id).collect()),
    )?;
    t.push(
        schema::SPLIT,
        Column::Str(rows.iter().map(|r| r.info.split.clone()).collect()),
    )?;
    for (j, name) in system.sampled_names().into_iter().enumerate() {
        t.push(
            name,
            Column::F64(rows.iter().map(|r| r.info.params.as_slice()[j]).collect()),
        )?;
    }
    for (k, c) in out.columns.iter().enumerate() {
        t.push(
            &c.name,
            Column::F64(rows.iter().map(|r| r.values[k]).collect()),
        )?;
    }
    t.push(
        pino_indices::WINDOW_COLUMN,
        Column::F64(rows.iter().map(|r| r.window_s).collect()),
    )?;
    t.push(
        pino_indices::PASS_COLUMN,
        Column::Bool(rows.iter().map(|r| r.failed.is_empty()).collect()),
    )?;
    t.push(
        pino_indices::FAILED_COLUMN,
        Column::null_if_empty(rows.iter().map(|r| r.failed.join(","))),
    )?;
    Ok(t)
}

/// The settings and column catalogue as JSON text (the `indices.json` beside the table): the
/// description's name, the settings used, every index column of `system` (name, unit,
/// definition; a simple index also its own `limit`) and the three bookkeeping columns; the
/// settings those of `system` ([`IndexConfig::of_system`]), as [`crate::compute_all`] uses.
pub fn describe_json(system: &System, cfg: &IndexConfig) -> String {
    let params: serde_json::Map<String, serde_json::Value> = cfg
        .of_system(system)
        .describe()
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v.into()))
        .collect();
    let mut columns: Vec<serde_json::Value> = IndexSet::of(system)
        .columns(system)
        .into_iter()
        .map(|c| {
            let mut v =
                serde_json::json!({"name": c.name, "unit": c.unit, "definition": c.definition});
            if let Some(limit) = system
                .indices
                .iter()
                .find(|ix| ix.name == c.name)
                .and_then(|ix| ix.limit)
            {
                v["limit"] = limit.into();
            }
            v
        })
        .collect();
    for (name, unit, definition) in [
        (
            pino_indices::WINDOW_COLUMN,
            "s",
            "length of the evaluation window",
        ),
        (
            pino_indices::PASS_COLUMN,
            DIMENSIONLESS,
            "true when no limit is exceeded (Boolean)",
        ),
        (
            pino_indices::FAILED_COLUMN,
            DIMENSIONLESS,
            "the limits exceeded, comma-separated (null when none)",
        ),
    ] {
        columns.push(serde_json::json!({"name": name, "unit": unit, "definition": definition}));
    }
    let doc = serde_json::json!({"system": system.name, "parameters": params, "columns": columns});
    serde_json::to_string_pretty(&doc).expect("plain JSON values") + "\n"
}

/// Writes `indices.parquet` and `indices.json` into `dir` (atomically, deterministic bytes).
pub fn write_outputs(dir: &Path, system: &System, out: &Computed, cfg: &IndexConfig) -> Result<()> {
    pino_data::write_parquet(
        &dir.join(pino_data::artifacts::INDICES_FILE),
        &to_table(system, out)?,
    )?;
    let path = dir.join(pino_data::artifacts::INDICES_META_FILE);
    atomic_write(&path, describe_json(system, cfg).as_bytes())
}

fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_file::write_atomic(path, bytes).map_err(|e| {
        Error::Data(pino_data::Error::Io {
            path: e.path,
            source: e.source,
        })
    })
}

/// `v` with 4 significant digits.
fn sig(v: f64) -> String {
    if !v.is_finite() || v == 0.0 {
        return v.to_string();
    }
    let decimals = 3 - v.abs().log10().floor() as i32;
    format!("{v:.*}", decimals.max(0) as usize)
}

/// The stage's one-line summary: samples, absent samples, samples over a limit, and the
/// worst of the headline indices by name: with a railway binding the peak wheel-rail force,
/// the wheel load reduction rate and the Sperling `W_z` (worst of the three points);
/// otherwise the largest value (the limits are upper bounds) of each of the first three
/// simple indices. A description with neither family says so.
pub fn summary(out: &Computed) -> String {
    let failing = out.rows.iter().filter(|r| !r.failed.is_empty()).count();
    let head = format!(
        "indices of {} samples ({} absent from the dataset); {failing} exceed a limit",
        out.rows.len(),
        out.absent,
    );
    let worst_of = |f: &dyn Fn(&crate::Row) -> Option<f64>| {
        out.rows
            .iter()
            .filter_map(f)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    if out.railway {
        let railway = |index: fn(&Indices) -> f64| worst_of(&|r| r.railway.as_ref().map(index));
        return format!(
            "{head}; worst: peak force {:.1} kN, wheel load reduction {:.3}, W_z {:.2}",
            railway(|i| i.peak_wheel_rail_force_kn),
            railway(|i| i.wheel_load_reduction_rate),
            railway(|i| i.sperling_wz.into_iter().fold(f64::NEG_INFINITY, f64::max)),
        );
    }
    if out.columns.is_empty() {
        return format!(
            "{head}; `{}` declares no index (no railway binding, no `indices:`): indices.parquet holds the keys only",
            out.system
        );
    }
    let shown: Vec<String> = out
        .columns
        .iter()
        .enumerate()
        .take(3)
        .map(|(k, c)| {
            let v = sig(worst_of(&|r| Some(r.values[k])));
            match c.unit.as_str() {
                DIMENSIONLESS | "" => format!("{} {v}", c.name),
                u => format!("{} {v} {u}", c.name),
            }
        })
        .collect();
    let more = match out.columns.len().saturating_sub(3) {
        0 => String::new(),
        k => format!(" (and {k} more in indices.parquet)"),
    };
    format!("{head}; worst: {}{more}", shown.join(", "))
}
