//! Parquet reading and writing with fixed settings and atomic replacement.
//!
//! Writes go through [`atomic_file::TempFile`] (a temporary sibling, fsynced, renamed over
//! `NAME`): a crash never leaves a partial file under the final name. Writer settings
//! (Snappy, row-group size, `created_by`) are fixed, so equal tables give equal bytes. Every
//! write attaches the units and origin of [`crate::metadata`] (the one place they are made).

use crate::units::UNIT_KEY;
use crate::{io, metadata, pq, Column, Error, Result, Table};
use arrow_array::{
    Array, ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray,
};
use arrow_schema::{DataType, Field, Metadata, Schema, SchemaRef};
use parquet::arrow::arrow_reader::{ParquetRecordBatchReader, ParquetRecordBatchReaderBuilder};
use parquet::arrow::{ArrowWriter, ProjectionMask};
use parquet::basic::Compression;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Rows per row group by default (about 1 MiB per f64 column).
const DEFAULT_ROW_GROUP: usize = 128 * 1024;

/// Writes `table` to `path` atomically with the default row-group size.
pub fn write_parquet(path: &Path, table: &Table) -> Result<()> {
    write_parquet_with(path, table, DEFAULT_ROW_GROUP)
}

/// Writes `table` to `path` atomically with `row_group_rows` rows per row group (a
/// per-sample row group, for instance, lets readers skip samples cheaply).
pub fn write_parquet_with(path: &Path, table: &Table, row_group_rows: usize) -> Result<()> {
    write_table(path, table, row_group_rows, metadata::origin())
}

/// Writes `table` to `path` atomically as [`write_parquet`] does, naming `origin` instead of
/// the process's declared one: for a long-lived process (the design explorer) whose every
/// file comes from a different request.
pub fn write_parquet_from(path: &Path, table: &Table, origin: &metadata::Origin) -> Result<()> {
    write_table(path, table, DEFAULT_ROW_GROUP, Some(origin))
}

fn write_table(
    path: &Path,
    table: &Table,
    row_group_rows: usize,
    origin: Option<&metadata::Origin>,
) -> Result<()> {
    let schema = arrow_schema(path, table, origin)?;
    let arrays = arrow_arrays(table);
    let batch = if arrays.is_empty() {
        RecordBatch::new_empty(schema.clone())
    } else {
        RecordBatch::try_new(schema.clone(), arrays).map_err(|e| pq(path, e))?
    };
    let props = writer_properties(row_group_rows.max(1), &schema);

    let (tmp, file) = atomic_file::TempFile::create(path).map_err(atomic)?;
    // Any early return drops `tmp`, which removes the temporary file.
    let mut writer = ArrowWriter::try_new(file, schema, Some(props)).map_err(|e| pq(path, e))?;
    writer.write(&batch).map_err(|e| pq(path, e))?;
    let file = writer.into_inner().map_err(|e| pq(path, e))?;
    tmp.commit(file).map_err(atomic)
}

/// The Arrow type of a column.
pub(crate) fn data_type(col: &Column) -> DataType {
    match col {
        Column::F64(_) => DataType::Float64,
        Column::I64(_) => DataType::Int64,
        Column::Str(_) | Column::OptStr(_) => DataType::Utf8,
        Column::Bool(_) => DataType::Boolean,
    }
}

/// The Arrow schema of a table written to `path` (every column non-nullable but a
/// [`Column::OptStr`], whose nulls are its absent values): each field
/// with its `unit`, the schema with the file's key-value metadata ([`crate::metadata`]).
pub(crate) fn arrow_schema(
    path: &Path,
    table: &Table,
    origin: Option<&metadata::Origin>,
) -> Result<SchemaRef> {
    let units = metadata::column_units(path, table)?;
    let fields: Vec<Field> = table
        .columns()
        .iter()
        .zip(&units)
        .map(|((name, col), (_, unit))| {
            Field::new(name, data_type(col), matches!(col, Column::OptStr(_)))
                .with_metadata(Metadata::new().with(UNIT_KEY, *unit))
        })
        .collect();
    let kv = metadata::file_metadata(&units, origin);
    Ok(Arc::new(Schema::new_with_metadata(fields, kv)))
}

/// The table's columns as Arrow arrays.
pub(crate) fn arrow_arrays(table: &Table) -> Vec<ArrayRef> {
    table
        .columns()
        .iter()
        .map(|(_, col)| arrow_array(col.clone()))
        .collect()
}

/// One column as an Arrow array, its vector moved into the array's buffer.
pub(crate) fn arrow_array(col: Column) -> ArrayRef {
    match col {
        Column::F64(v) => Arc::new(Float64Array::from(v)),
        Column::I64(v) => Arc::new(Int64Array::from(v)),
        Column::Str(v) => Arc::new(StringArray::from(v)),
        Column::Bool(v) => Arc::new(BooleanArray::from(v)),
        Column::OptStr(v) => Arc::new(StringArray::from(v)),
    }
}

/// The fixed writer settings (Snappy, `created_by`), so equal tables give equal bytes, and
/// the schema's metadata as the file's key-value metadata (sorted by key), where readers
/// that do not decode Arrow's embedded schema (DuckDB, polars) find it.
pub(crate) fn writer_properties(max_row_group_rows: usize, schema: &Schema) -> WriterProperties {
    let kv = schema
        .metadata()
        .iter()
        .map(|(k, v)| KeyValue::new(k.clone(), v.clone()))
        .collect();
    WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_max_row_group_row_count(Some(max_row_group_rows))
        .set_created_by("pino-mbd".to_owned())
        .set_key_value_metadata(Some(kv))
        .build()
}

/// The data layer's error for a failed atomic write.
pub(crate) fn atomic(e: atomic_file::Error) -> Error {
    Error::Io {
        path: e.path,
        source: e.source,
    }
}

/// Number of rows in a Parquet file, from its footer alone.
pub fn row_count(path: &Path) -> Result<usize> {
    let file = File::open(path).map_err(|e| io(path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| pq(path, e))?;
    Ok(builder.metadata().file_metadata().num_rows() as usize)
}

/// Opens `path` and projects it onto the named columns (all when `None`): the batch reader,
/// the wanted names in order, and the file's Arrow schema.
fn projected_reader(
    path: &Path,
    columns: Option<&[&str]>,
) -> Result<(ParquetRecordBatchReader, Vec<String>, SchemaRef)> {
    let file = File::open(path).map_err(|e| io(path, e))?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| pq(path, e))?;
    let arrow_schema = builder.schema().clone();
    let present: Vec<String> = arrow_schema
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect();
    let wanted: Vec<String> = match columns {
        Some(cols) => cols.iter().map(|s| s.to_string()).collect(),
        None => present.clone(),
    };
    let mut leaf_indices = Vec::with_capacity(wanted.len());
    for name in &wanted {
        match present.iter().position(|p| p == name) {
            Some(i) => leaf_indices.push(i),
            None => {
                return Err(Error::MissingColumn {
                    path: path.to_owned(),
                    column: name.clone(),
                    present: present.join(", "),
                })
            }
        }
    }
    let mask = ProjectionMask::roots(builder.parquet_schema(), leaf_indices.iter().copied());
    let reader = builder
        .with_projection(mask)
        .with_batch_size(64 * 1024)
        .build()
        .map_err(|e| pq(path, e))?;
    Ok((reader, wanted, arrow_schema))
}

/// Reads the named columns (all columns when `columns` is `None`) of one Parquet file.
/// Columns come back in the order asked for.
pub fn read_parquet(path: &Path, columns: Option<&[&str]>) -> Result<Table> {
    let (reader, wanted, arrow_schema) = projected_reader(path, columns)?;

    let mut cols: Vec<Column> = Vec::new();
    let mut first = true;
    for batch in reader {
        let batch = batch.map_err(|e| pq(path, e))?;
        let schema = batch.schema();
        if first {
            cols = wanted
                .iter()
                .map(|name| {
                    let field = schema.field_with_name(name).map_err(|e| pq(path, e))?;
                    empty_column(path, name, field.data_type())
                })
                .collect::<Result<_>>()?;
            first = false;
        }
        for (name, col) in wanted.iter().zip(cols.iter_mut()) {
            let idx = schema.index_of(name).map_err(|e| pq(path, e))?;
            append_array(path, name, col, batch.column(idx).as_ref())?;
        }
    }
    if first {
        // No batches: an empty file; types come from the schema.
        cols = wanted
            .iter()
            .map(|name| {
                let field = arrow_schema
                    .field_with_name(name)
                    .map_err(|e| pq(path, e))?;
                empty_column(path, name, field.data_type())
            })
            .collect::<Result<_>>()?;
    }
    let mut table = Table::with_origin(path);
    for (name, col) in wanted.iter().zip(cols) {
        table.push(name, col)?;
    }
    Ok(table)
}

/// Reads the same columns from several files (for example the shards of one artifact) and
/// concatenates them in the given order.
pub fn read_parquet_files(paths: &[PathBuf], columns: Option<&[&str]>) -> Result<Table> {
    let mut table = Table::default();
    for p in paths {
        table.append(read_parquet(p, columns)?)?;
    }
    Ok(table)
}

/// Streams the named columns of one Parquet file as tables of at most 64 Ki rows each, in
/// file order, to `f` (for files too large to hold whole; an empty file calls `f` never).
pub fn for_each_batch(
    path: &Path,
    columns: Option<&[&str]>,
    mut f: impl FnMut(Table) -> Result<()>,
) -> Result<()> {
    let (reader, wanted, _) = projected_reader(path, columns)?;
    for batch in reader {
        let batch = batch.map_err(|e| pq(path, e))?;
        let schema = batch.schema();
        let mut table = Table::with_origin(path);
        for name in &wanted {
            let idx = schema.index_of(name).map_err(|e| pq(path, e))?;
            let mut col = empty_column(path, name, schema.field(idx).data_type())?;
            append_array(path, name, &mut col, batch.column(idx).as_ref())?;
            table.push(name, col)?;
        }
        f(table)?;
    }
    Ok(())
}

pub(crate) fn empty_column(path: &Path, name: &str, dt: &DataType) -> Result<Column> {
    match dt {
        DataType::Float64 | DataType::Float32 => Ok(Column::F64(Vec::new())),
        DataType::Int64 | DataType::Int32 | DataType::UInt32 | DataType::UInt64 => {
            Ok(Column::I64(Vec::new()))
        }
        DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View => Ok(Column::Str(Vec::new())),
        DataType::Boolean => Ok(Column::Bool(Vec::new())),
        other => Err(Error::ColumnType {
            path: path.to_owned(),
            column: name.to_owned(),
            found: other.to_string(),
            expected: "f64, i64, bool or string".to_owned(),
        }),
    }
}

/// Appends `array` to `col`: numbers and Booleans without nulls, strings with or without
/// (a string column becomes a [`Column::OptStr`] at its first null).
pub(crate) fn append_array(
    path: &Path,
    name: &str,
    col: &mut Column,
    array: &dyn Array,
) -> Result<()> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{
        Float32Type, Float64Type, Int32Type, Int64Type, UInt32Type, UInt64Type,
    };
    let strings: Option<Vec<Option<&str>>> = match array.data_type() {
        DataType::Utf8 => Some(array.as_string::<i32>().iter().collect()),
        DataType::LargeUtf8 => Some(array.as_string::<i64>().iter().collect()),
        DataType::Utf8View => Some(array.as_string_view().iter().collect()),
        _ => None,
    };
    if let Some(strings) = strings {
        return append_strings(path, name, col, strings, array.data_type());
    }
    if array.null_count() > 0 {
        return Err(Error::ColumnType {
            path: path.to_owned(),
            column: name.to_owned(),
            found: format!("{} with {} nulls", array.data_type(), array.null_count()),
            expected: "no nulls".to_owned(),
        });
    }
    match (col, array.data_type()) {
        (Column::F64(v), DataType::Float64) => {
            v.extend_from_slice(array.as_primitive::<Float64Type>().values())
        }
        (Column::F64(v), DataType::Float32) => v.extend(
            array
                .as_primitive::<Float32Type>()
                .values()
                .iter()
                .map(|&x| x as f64),
        ),
        (Column::I64(v), DataType::Int64) => {
            v.extend_from_slice(array.as_primitive::<Int64Type>().values())
        }
        (Column::I64(v), DataType::Int32) => v.extend(
            array
                .as_primitive::<Int32Type>()
                .values()
                .iter()
                .map(|&x| x as i64),
        ),
        (Column::I64(v), DataType::UInt32) => v.extend(
            array
                .as_primitive::<UInt32Type>()
                .values()
                .iter()
                .map(|&x| x as i64),
        ),
        (Column::I64(v), DataType::UInt64) => v.extend(
            array
                .as_primitive::<UInt64Type>()
                .values()
                .iter()
                .map(|&x| x as i64),
        ),
        (Column::Bool(v), DataType::Boolean) => v.extend(array.as_boolean().values().iter()),
        (col, dt) => return Err(mismatch(path, name, dt, col)),
    }
    Ok(())
}

/// Appends the rows of a string array to `col` (a string column, with or without nulls).
fn append_strings(
    path: &Path,
    name: &str,
    col: &mut Column,
    strings: Vec<Option<&str>>,
    dt: &DataType,
) -> Result<()> {
    if let Column::Str(v) = col {
        if strings.iter().any(Option::is_none) {
            let upgraded = std::mem::take(v).into_iter().map(Some).collect();
            *col = Column::OptStr(upgraded);
        }
    }
    match col {
        Column::Str(v) => v.extend(
            strings
                .into_iter()
                .map(|s| s.unwrap_or_default().to_owned()),
        ),
        Column::OptStr(v) => v.extend(strings.into_iter().map(|s| s.map(str::to_owned))),
        col => return Err(mismatch(path, name, dt, col)),
    }
    Ok(())
}

fn mismatch(path: &Path, name: &str, found: &DataType, col: &Column) -> Error {
    Error::ColumnType {
        path: path.to_owned(),
        column: name.to_owned(),
        found: found.to_string(),
        expected: col.type_name().to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Table {
        let mut t = Table::default();
        t.push("sample_id", Column::I64(vec![3, 3, 4])).unwrap();
        t.push("t", Column::F64(vec![0.0, 1e-3, 0.0])).unwrap();
        t.push(
            "split",
            Column::Str(vec!["train".into(), "train".into(), "validation".into()]),
        )
        .unwrap();
        t
    }

    #[test]
    fn round_trip_is_exact_and_bytes_are_deterministic() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.parquet");
        let b = dir.path().join("b.parquet");
        write_parquet(&a, &sample()).unwrap();
        write_parquet(&b, &sample()).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
        let back = read_parquet(&a, None).unwrap();
        assert_eq!(back.columns(), sample().columns());
        assert_eq!(row_count(&a).unwrap(), 3);
        // No temporary file is left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "{names:?}");
    }

    /// Booleans and strings with nulls round-trip as Parquet BOOLEAN and a nullable STRING
    /// (the reader sees the null, not an empty string); a column without a null reads back
    /// as a plain string column, and the accessors take either.
    #[test]
    fn booleans_and_nulls_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.parquet");
        let mut t = sample();
        t.push("pass", Column::Bool(vec![true, false, true]))
            .unwrap();
        t.push(
            "verdict",
            Column::OptStr(vec![None, Some("fail".into()), Some(String::new())]),
        )
        .unwrap();
        t.push("failed", Column::OptStr(vec![Some("x".into()); 3]))
            .unwrap();
        write_parquet(&a, &t).unwrap();
        let back = read_parquet(&a, None).unwrap();
        assert_eq!(back.bool("pass").unwrap(), [true, false, true]);
        assert_eq!(
            back.column("verdict").unwrap(),
            &Column::OptStr(vec![None, Some("fail".into()), Some(String::new())])
        );
        assert_eq!(back.opt_str("failed").unwrap(), [Some("x"); 3]);
        assert_eq!(back.str("failed").unwrap()[0], "x");
        let (_, _, schema) = projected_reader(&a, None).unwrap();
        let nullable: Vec<bool> = schema.fields().iter().map(|f| f.is_nullable()).collect();
        assert_eq!(nullable, [false, false, false, false, true, true]);
        assert_eq!(schema.field(3).data_type(), &DataType::Boolean);
        // Appending a file with nulls to one without keeps every row.
        let mut both = read_parquet(&a, Some(&["failed"])).unwrap();
        let mut nulls = Table::default();
        nulls
            .push("failed", Column::OptStr(vec![None, Some("y".into())]))
            .unwrap();
        both.append(nulls).unwrap();
        assert_eq!(
            both.opt_str("failed").unwrap(),
            [Some("x"), Some("x"), Some("x"), None, Some("y")]
        );
    }

    /// Each column carries its unit (field metadata), the file its version and the units as
    /// JSON (key-value metadata), in the same bytes on a rerun; a column without a unit is
    /// refused and leaves no file.
    #[test]
    fn columns_carry_units_and_files_their_metadata() {
        use crate::metadata::{read_metadata, COLUMN_UNITS_KEY, STAGE_KEY, VERSION, VERSION_KEY};
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.parquet");
        write_parquet(&a, &sample()).unwrap();
        let m = read_metadata(&a).unwrap();
        let units: Vec<(&str, Option<&str>)> = m
            .column_units
            .iter()
            .map(|(n, u)| (n.as_str(), u.as_deref()))
            .collect();
        assert_eq!(
            units,
            [
                ("sample_id", Some("1")),
                ("t", Some("s")),
                ("split", Some("1"))
            ]
        );
        assert_eq!(m.key_value[VERSION_KEY], VERSION);
        assert_eq!(
            m.key_value[COLUMN_UNITS_KEY],
            r#"{"sample_id":"1","split":"1","t":"s"}"#
        );
        // No origin declared in this process: no stage.
        assert!(!m.key_value.contains_key(STAGE_KEY));
        assert!(m.key_value.contains_key("ARROW:schema"));

        let mut bad = sample();
        bad.push("speed", Column::F64(vec![1.0; 3])).unwrap();
        let b = dir.path().join("b.parquet");
        let e = write_parquet(&b, &bad).unwrap_err().to_string();
        assert!(
            e.contains("b.parquet") && e.contains("`speed` has no unit"),
            "{e}"
        );
        let e = crate::StreamWriter::create(&b, &bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`speed` has no unit"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn projection_keeps_requested_order_and_missing_column_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.parquet");
        write_parquet(&a, &sample()).unwrap();
        let t = read_parquet(&a, Some(&["t", "sample_id"])).unwrap();
        assert_eq!(t.names().collect::<Vec<_>>(), vec!["t", "sample_id"]);
        let err = read_parquet(&a, Some(&["z_c"])).unwrap_err().to_string();
        assert!(err.contains("a.parquet") && err.contains("`z_c`"), "{err}");
        let err = t.f64("sample_id").unwrap_err().to_string();
        assert!(err.contains("expected f64"), "{err}");
    }

    #[test]
    fn concatenating_files_and_length_mismatch() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.parquet");
        let b = dir.path().join("b.parquet");
        write_parquet(&a, &sample()).unwrap();
        write_parquet(&b, &sample()).unwrap();
        let t = read_parquet_files(&[a, b], Some(&["sample_id"])).unwrap();
        assert_eq!(t.i64("sample_id").unwrap(), &[3, 3, 4, 3, 3, 4]);
        let mut bad = Table::default();
        bad.push("x", Column::F64(vec![1.0])).unwrap();
        assert!(matches!(
            bad.push("y", Column::F64(vec![])),
            Err(Error::Length { .. })
        ));
    }
}
