//! The stage's artifacts: `indices.parquet` (one row per sample) and `indices.json` (the
//! settings used and every column's unit and definition), written atomically with
//! deterministic bytes.

use crate::{Error, Result, Row};
use pino_data::{schema, Column, Table};
use pino_indices::{IndexConfig, INDEX_COLUMNS};
use std::path::Path;

/// The output table: `sample_id`, `split`, the 14 parameters, the 14 indices, `window_s`,
/// `pass` (1/0), `failed` (comma-separated limit names).
pub fn to_table(rows: &[Row]) -> pino_data::Result<Table> {
    let mut t = Table::default();
    t.push(
        schema::SAMPLE_ID,
        Column::I64(rows.iter().map(|r| r.id).collect()),
    )?;
    t.push(
        schema::SPLIT,
        Column::Str(rows.iter().map(|r| r.info.split.clone()).collect()),
    )?;
    for (j, name) in schema::PARAMETERS.iter().enumerate() {
        t.push(
            name,
            Column::F64(rows.iter().map(|r| r.info.params[j]).collect()),
        )?;
    }
    for (k, c) in INDEX_COLUMNS.iter().enumerate() {
        t.push(
            c.name,
            Column::F64(rows.iter().map(|r| r.indices.values()[k]).collect()),
        )?;
    }
    t.push(
        pino_indices::WINDOW_COLUMN,
        Column::F64(rows.iter().map(|r| r.indices.window_s).collect()),
    )?;
    t.push(
        pino_indices::PASS_COLUMN,
        Column::I64(rows.iter().map(|r| r.failed.is_empty() as i64).collect()),
    )?;
    t.push(
        pino_indices::FAILED_COLUMN,
        Column::Str(rows.iter().map(|r| r.failed.join(",")).collect()),
    )?;
    Ok(t)
}

/// The settings and column catalogue as JSON text (the `indices.json` beside the table).
pub fn describe_json(cfg: &IndexConfig) -> String {
    let params: serde_json::Map<String, serde_json::Value> = cfg
        .describe()
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v.into()))
        .collect();
    let mut columns: Vec<serde_json::Value> = INDEX_COLUMNS
        .iter()
        .map(|c| serde_json::json!({"name": c.name, "unit": c.unit, "definition": c.definition}))
        .collect();
    for (name, unit, definition) in [
        (
            pino_indices::WINDOW_COLUMN,
            "s",
            "length of the evaluation window",
        ),
        (
            pino_indices::PASS_COLUMN,
            "-",
            "1 when no limit is exceeded, else 0",
        ),
        (
            pino_indices::FAILED_COLUMN,
            "-",
            "the limits exceeded, comma-separated",
        ),
    ] {
        columns.push(serde_json::json!({"name": name, "unit": unit, "definition": definition}));
    }
    let doc = serde_json::json!({"parameters": params, "columns": columns});
    serde_json::to_string_pretty(&doc).expect("plain JSON values") + "\n"
}

/// Writes `indices.parquet` and `indices.json` into `dir` (atomically, deterministic bytes).
pub fn write_outputs(dir: &Path, rows: &[Row], cfg: &IndexConfig) -> Result<()> {
    pino_data::write_parquet(&dir.join("indices.parquet"), &to_table(rows)?)?;
    let path = dir.join("indices.json");
    atomic_write(&path, describe_json(cfg).as_bytes())
}

fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_file::write_atomic(path, bytes).map_err(|e| {
        Error::Data(pino_data::Error::Io {
            path: e.path,
            source: e.source,
        })
    })
}
