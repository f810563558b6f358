//! What every Parquet file of pino-mbd says about itself: the unit of each column and where
//! the file comes from.
//!
//! Every write ([`crate::write_parquet`], [`crate::StreamWriter`]) attaches:
//!
//! - to each column (Arrow field metadata): `unit` ([`crate::units::UNIT_KEY`]), from the
//!   units the table carries or the fixed table ([`crate::Table::unit`], [`crate::units`]);
//! - to the file (Parquet key-value metadata, and the Arrow schema's metadata, so
//!   `pyarrow.parquet.read_schema(f).metadata`, DuckDB's `parquet_kv_metadata(f)` and
//!   polars' `read_parquet_metadata(f)` all show it):
//!   - [`VERSION_KEY`]: the pino-mbd version that wrote it;
//!   - [`COLUMN_UNITS_KEY`]: every column's unit as one JSON object (for readers that do not
//!     surface Arrow field metadata);
//!   - and, in a process that declared its [`Origin`] (every stage and `predict` do, first
//!     thing): [`STAGE_KEY`] (the stage), [`UNIT_KEY`] (the orchestrator's unit key: the
//!     stage's matrix expansion, `train[algorithm=3]`, and `#SHARD` for a sharded stage,
//!     `simulate#1`) and [`PARAMS_KEY`] (the stage's resolved parameters, JSON).
//!
//! Nothing in it depends on the time, the machine or the paths of the run, so equal inputs
//! still give equal bytes. The unit's content-addressed identity is deliberately not written:
//! it hashes the stage executable, so a rebuild that changes no output byte would change every
//! file and rerun everything downstream (the store records it beside each output instead,
//! `artifacts/objects/<identity>/context.json`).

use crate::units::UNIT_KEY as FIELD_UNIT_KEY;
use crate::{Error, Result, Table};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

/// Key of the writing pino-mbd version.
pub const VERSION_KEY: &str = "pino.version";
/// Key of the stage that wrote the file (`simulate`, `train`, `predict`, ...).
pub const STAGE_KEY: &str = "pino.stage";
/// Key of the orchestrator's unit key (`train[algorithm=3]`, `simulate#1`, `weights`).
pub const UNIT_KEY: &str = "pino.unit";
/// Key of the stage's resolved parameters (a JSON object).
pub const PARAMS_KEY: &str = "pino.params";
/// Key of every column's unit (a JSON object: column name -> unit).
pub const COLUMN_UNITS_KEY: &str = "pino.column_units";

/// The pino-mbd version written into every file.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Which stage unit a process computes, written into every Parquet file it writes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Origin {
    /// The stage (`train`).
    pub stage: String,
    /// The orchestrator's unit key (`train[algorithm=3]`, `simulate#1`).
    pub unit: String,
    /// The resolved parameters, as compact JSON text.
    pub params: String,
}

impl Origin {
    /// The origin of a stage unit from what its context says: `expansion` is the context's
    /// `stage` (`train[algorithm=3]`), the shard is `index` of `count`.
    pub fn stage_unit(
        expansion: &str,
        index: usize,
        count: usize,
        params: &serde_json::Value,
    ) -> Self {
        let stage = expansion.split('[').next().unwrap_or(expansion).to_owned();
        let unit = if count > 1 {
            format!("{expansion}#{index}")
        } else {
            expansion.to_owned()
        };
        Self {
            stage,
            unit,
            params: params.to_string(),
        }
    }
}

static ORIGIN: OnceLock<Origin> = OnceLock::new();

/// Declares, once per process, the origin every Parquet file written from now on carries.
/// Declaring the same origin again is fine; another one is an error (a process is one unit).
pub fn set_origin(origin: Origin) -> Result<()> {
    let stored = ORIGIN.get_or_init(|| origin.clone());
    if *stored == origin {
        Ok(())
    } else {
        Err(Error::Origin(format!(
            "this process already writes as `{}`, not `{}`",
            stored.unit, origin.unit
        )))
    }
}

/// The origin declared by [`set_origin`], if any.
pub fn origin() -> Option<&'static Origin> {
    ORIGIN.get()
}

/// The unit of every column of `table` (field metadata), in column order: the table's own or
/// the fixed table's ([`Table::unit`]); a column without one is an error naming it and `path`.
pub(crate) fn column_units<'t>(path: &Path, table: &'t Table) -> Result<Vec<(&'t str, &'t str)>> {
    table
        .names()
        .map(|name| match table.unit(name) {
            Some(u) => Ok((name, u)),
            None => Err(Error::NoUnit {
                path: path.to_owned(),
                column: name.to_owned(),
            }),
        })
        .collect()
}

/// The file's key-value metadata for columns with `units`, sorted by key.
pub(crate) fn file_metadata(
    units: &[(&str, &str)],
    origin: Option<&Origin>,
) -> BTreeMap<String, String> {
    let map: serde_json::Map<String, serde_json::Value> = units
        .iter()
        .map(|(n, u)| ((*n).to_owned(), serde_json::Value::from(*u)))
        .collect();
    let mut kv = BTreeMap::from([
        (VERSION_KEY.to_owned(), VERSION.to_owned()),
        (
            COLUMN_UNITS_KEY.to_owned(),
            serde_json::Value::Object(map).to_string(),
        ),
    ]);
    if let Some(o) = origin {
        kv.insert(STAGE_KEY.to_owned(), o.stage.clone());
        kv.insert(UNIT_KEY.to_owned(), o.unit.clone());
        kv.insert(PARAMS_KEY.to_owned(), o.params.clone());
    }
    kv
}

/// What a Parquet file says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct FileMetadata {
    /// The file's key-value metadata (`pino.*` and Arrow's own `ARROW:schema`).
    pub key_value: BTreeMap<String, String>,
    /// Each column's `unit` field metadata, in file order (`None` when absent).
    pub column_units: Vec<(String, Option<String>)>,
}

/// Reads the self-description of the Parquet file at `path`.
pub fn read_metadata(path: &Path) -> Result<FileMetadata> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let file = std::fs::File::open(path).map_err(|e| crate::io(path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| crate::pq(path, e))?;
    let key_value = builder
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .map(|kvs| {
            kvs.iter()
                .map(|kv| (kv.key.clone(), kv.value.clone().unwrap_or_default()))
                .collect()
        })
        .unwrap_or_default();
    let column_units = builder
        .schema()
        .fields()
        .iter()
        .map(|f| (f.name().clone(), f.metadata().get(FIELD_UNIT_KEY).cloned()))
        .collect();
    Ok(FileMetadata {
        key_value,
        column_units,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_units_are_named_as_the_orchestrator_names_them() {
        let p = serde_json::json!({"epochs": 2, "algorithm": 3});
        let o = Origin::stage_unit("train[algorithm=3]", 0, 1, &p);
        assert_eq!(
            (o.stage.as_str(), o.unit.as_str()),
            ("train", "train[algorithm=3]")
        );
        assert_eq!(o.params, r#"{"algorithm":3,"epochs":2}"#);
        let o = Origin::stage_unit("simulate", 1, 2, &serde_json::json!({}));
        assert_eq!(
            (o.stage.as_str(), o.unit.as_str()),
            ("simulate", "simulate#1")
        );
    }
}
