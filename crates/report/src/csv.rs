//! A [`Table`] as CSV: a header of column names, then one record per row, `\n` after each.
//!
//! Cells: `f64` as Rust's `Display` writes it (the shortest text that reads back to the same
//! value: `0.1`, `1`, `1e-7`; `NaN`, `inf`), `i64` in decimal, Booleans as `true`/`false`,
//! strings as they are and a null as an empty field. The `csv`
//! crate quotes a field only when it must (RFC 4180): when it holds a comma, a double quote
//! (written doubled) or a line break, so any standard reader gets every string back.
//!
//! ```
//! use pino_data::{Column, Table};
//! let mut t = Table::default();
//! t.push("name", Column::Str(vec!["a, \"b\"".into()]))?;
//! t.push("x", Column::F64(vec![0.5]))?;
//! assert_eq!(report::csv::to_bytes(&t)?, b"name,x\n\"a, \"\"b\"\"\",0.5\n");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::{Error, Result};
use pino_data::{Column, Table};
use std::path::Path;

/// The text of row `r` of a column (a null is an empty field).
fn cell(c: &Column, r: usize) -> String {
    match c {
        Column::F64(v) => v[r].to_string(),
        Column::I64(v) => v[r].to_string(),
        Column::Str(v) => v[r].clone(),
        Column::Bool(v) => v[r].to_string(),
        Column::OptStr(v) => v[r].clone().unwrap_or_default(),
    }
}

/// The CSV bytes of a table.
pub fn to_bytes(t: &Table) -> std::result::Result<Vec<u8>, ::csv::Error> {
    let mut w = ::csv::WriterBuilder::new()
        .terminator(::csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    w.write_record(t.names())?;
    for r in 0..t.num_rows() {
        w.write_record(t.columns().iter().map(|(_, c)| cell(c, r)))?;
    }
    w.into_inner().map_err(|e| e.into_error().into())
}

/// Writes a table as CSV, atomically.
pub fn write_csv(path: &Path, t: &Table) -> Result<()> {
    let bytes = to_bytes(t).map_err(|source| Error::Csv {
        path: path.to_owned(),
        source,
    })?;
    Ok(atomic_file::write_atomic(path, &bytes)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(names: Vec<String>) -> Table {
        let mut t = Table::default();
        t.push("algorithm", Column::I64(vec![0, 5])).unwrap();
        t.push("name", Column::Str(names)).unwrap();
        t.push("x", Column::F64(vec![0.1 + 0.2, f64::NAN])).unwrap();
        t
    }

    #[test]
    fn plain_fields_are_written_as_before_quoting_was_fixed() {
        // The old hand-written writer's output for a table without special characters: the
        // switch to the csv crate changes no byte of such a file.
        let t = table(vec!["FNO".into(), "PINO-MBD (direct derivatives)".into()]);
        assert_eq!(
            String::from_utf8(to_bytes(&t).unwrap()).unwrap(),
            "algorithm,name,x\n0,FNO,0.30000000000000004\n5,PINO-MBD (direct derivatives),NaN\n"
        );
    }

    #[test]
    fn a_field_with_a_quote_a_comma_and_a_newline_round_trips() {
        let nasty = "truth \"exact\", central\ndifferences".to_owned();
        let t = table(vec![nasty.clone(), ",".into()]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        write_csv(&path, &t).unwrap();
        let mut rd = ::csv::Reader::from_path(&path).unwrap();
        assert_eq!(
            rd.headers().unwrap().iter().collect::<Vec<_>>(),
            ["algorithm", "name", "x"]
        );
        let rows: Vec<::csv::StringRecord> = rd.records().map(|r| r.unwrap()).collect();
        assert_eq!(rows.len(), 2);
        assert_eq!(&rows[0][1], nasty);
        assert_eq!(&rows[1][1], ",");
        assert_eq!(rows[0][2].parse::<f64>().unwrap(), 0.1 + 0.2);
        assert!(rows[1][2].parse::<f64>().unwrap().is_nan());
    }
}
