//! Tables as Arrow record batches in memory, for callers that hand them on without a file (the
//! Python package `pino_mbd` passes them through the Arrow C stream interface): a table becomes
//! one batch whose fields carry their unit (`unit` field metadata and the `pino.column_units`
//! schema metadata, as in the Parquet files) and whose buffers are the table's own vectors
//! (moved, not copied); any batch of numeric, Boolean or string columns reads back as a
//! [`Table`].

use crate::parquet_io::{append_array, arrow_array, arrow_schema, empty_column};
use crate::pq;
use crate::{Result, Table};
use arrow_array::{ArrayRef, RecordBatch};
use std::path::Path;

/// `table` as one record batch, its columns moved into Arrow buffers; `origin` names it in
/// errors (a column without a unit in the table's units or the fixed table is refused, as when
/// writing a file).
pub fn into_record_batch(table: Table, origin: &Path) -> Result<RecordBatch> {
    let schema = arrow_schema(origin, &table, None)?;
    let arrays: Vec<ArrayRef> = table
        .into_columns()
        .into_iter()
        .map(|(_, col)| arrow_array(col))
        .collect();
    if arrays.is_empty() {
        return Ok(RecordBatch::new_empty(schema));
    }
    RecordBatch::try_new(schema, arrays).map_err(|e| pq(origin, e))
}

/// The batches of one Arrow stream with `schema` as a table (floats as `f64`, integers as
/// `i64`, Booleans, strings with or without nulls; a null elsewhere refused), `origin` naming
/// it in errors.
pub fn from_record_batches(
    schema: &arrow_schema::Schema,
    batches: &[RecordBatch],
    origin: &Path,
) -> Result<Table> {
    let mut table = Table::with_origin(origin);
    for (i, field) in schema.fields().iter().enumerate() {
        let name = field.name();
        let mut col = empty_column(origin, name, field.data_type())?;
        for batch in batches {
            append_array(origin, name, &mut col, batch.column(i).as_ref())?;
        }
        table.push(name, col)?;
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Column;

    /// A table survives the trip through a record batch unchanged, with its units on the
    /// fields; a column without a unit is refused by name.
    #[test]
    fn round_trip_keeps_values_and_units() {
        let mut t = Table::default();
        t.push("sample_id", Column::I64(vec![3, 4])).unwrap();
        t.push("t", Column::F64(vec![0.0, 0.1 + 0.2])).unwrap();
        t.push("split", Column::Str(vec!["train".into(), "test".into()]))
            .unwrap();
        let batch = into_record_batch(t.clone(), Path::new("mem")).unwrap();
        let unit = batch.schema().field(1).metadata().get("unit").cloned();
        assert_eq!(unit.as_deref(), Some("s"));
        let back = from_record_batches(&batch.schema(), &[batch.clone(), batch], Path::new("mem"))
            .unwrap();
        assert_eq!(back.i64("sample_id").unwrap(), [3, 4, 3, 4]);
        assert_eq!(
            back.f64("t").unwrap()[1].to_bits(),
            (0.1f64 + 0.2).to_bits()
        );
        assert_eq!(back.str("split").unwrap()[3], "test");

        let mut bad = Table::default();
        bad.push("no_such_unit_column", Column::F64(vec![1.0]))
            .unwrap();
        let e = into_record_batch(bad, Path::new("mem")).unwrap_err();
        assert!(e.to_string().contains("no_such_unit_column"), "{e}");
    }
}
