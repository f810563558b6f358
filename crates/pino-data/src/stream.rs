//! Streaming Parquet writer: one row group per [`StreamWriter::write`] call, so a stage can
//! write a large artifact (for example one simulated sample at a time) without holding it in
//! memory. Same fixed settings and atomic replacement as [`crate::write_parquet`]: rows go to a
//! temporary file that is fsynced and renamed over the final name by [`StreamWriter::finish`];
//! dropping an unfinished writer removes the temporary file. Equal sequences of tables give
//! equal bytes. Units and origin are attached as by [`crate::write_parquet`]
//! ([`crate::metadata`]).

use crate::parquet_io::{arrow_arrays, arrow_schema, atomic, data_type, writer_properties};
use crate::pq;
use crate::{Error, Result, Table};
use arrow_array::RecordBatch;
use arrow_schema::SchemaRef;
use parquet::arrow::ArrowWriter;
use std::fs::File;
use std::path::{Path, PathBuf};

/// Writes a Parquet file row group by row group.
pub struct StreamWriter {
    path: PathBuf,
    /// The temporary file; dropping it uncommitted removes it.
    tmp: Option<atomic_file::TempFile>,
    schema: SchemaRef,
    writer: Option<ArrowWriter<File>>,
    rows: usize,
}

impl std::fmt::Debug for StreamWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamWriter")
            .field("path", &self.path)
            .field("rows", &self.rows)
            .finish()
    }
}

impl StreamWriter {
    /// Starts `path` with the column names and types of `template` (its rows are not
    /// written; an empty table is the usual template).
    pub fn create(path: &Path, template: &Table) -> Result<Self> {
        let schema = arrow_schema(path, template, crate::metadata::origin())?;
        // One row group per `write` call: the writer never splits one on its own.
        let props = writer_properties(usize::MAX, &schema);
        let (tmp, file) = atomic_file::TempFile::create(path).map_err(atomic)?;
        let writer =
            ArrowWriter::try_new(file, schema.clone(), Some(props)).map_err(|e| pq(path, e))?;
        Ok(Self {
            path: path.to_owned(),
            tmp: Some(tmp),
            schema,
            writer: Some(writer),
            rows: 0,
        })
    }

    /// Appends `table` (same column names and types, in order) as one row group.
    pub fn write(&mut self, table: &Table) -> Result<()> {
        let names: Vec<&str> = table.names().collect();
        let expected: Vec<&str> = self
            .schema
            .fields()
            .iter()
            .map(|f| f.name().as_str())
            .collect();
        if names != expected {
            return Err(Error::MissingColumn {
                path: self.path.clone(),
                column: expected.join(", "),
                present: names.join(", "),
            });
        }
        for ((name, col), field) in table.columns().iter().zip(self.schema.fields()) {
            if &data_type(col) != field.data_type() {
                return Err(Error::ColumnType {
                    path: self.path.clone(),
                    column: name.clone(),
                    found: col.type_name().to_owned(),
                    expected: field.data_type().to_string(),
                });
            }
        }
        if table.num_rows() == 0 {
            return Ok(());
        }
        let batch = RecordBatch::try_new(self.schema.clone(), arrow_arrays(table))
            .map_err(|e| pq(&self.path, e))?;
        let writer = self.writer.as_mut().expect("writer present until finish");
        writer.write(&batch).map_err(|e| pq(&self.path, e))?;
        writer.flush().map_err(|e| pq(&self.path, e))?;
        self.rows += table.num_rows();
        Ok(())
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Closes the file, fsyncs it and renames it over the final path.
    pub fn finish(mut self) -> Result<()> {
        let writer = self.writer.take().expect("writer present until finish");
        let tmp = self
            .tmp
            .take()
            .expect("temporary file present until finish");
        let file = writer.into_inner().map_err(|e| pq(&self.path, e))?;
        tmp.commit(file).map_err(atomic)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{read_parquet, write_parquet, Column};

    fn table(ids: Vec<i64>, xs: Vec<f64>) -> Table {
        let mut t = Table::default();
        t.push("sample_id", Column::I64(ids)).unwrap();
        t.push("x", Column::F64(xs)).unwrap();
        t
    }

    #[test]
    fn streamed_row_groups_read_back_in_order_and_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.parquet");
        let mut w = StreamWriter::create(&path, &table(vec![], vec![])).unwrap();
        w.write(&table(vec![1, 1], vec![0.5, 1.5])).unwrap();
        assert!(!path.exists(), "nothing under the final name before finish");
        w.write(&table(vec![4], vec![-2.0])).unwrap();
        assert_eq!(w.rows(), 3);
        w.finish().unwrap();
        let back = read_parquet(&path, None).unwrap();
        assert_eq!(back.i64("sample_id").unwrap(), &[1, 1, 4]);
        assert_eq!(back.f64("x").unwrap(), &[0.5, 1.5, -2.0]);
        // Wrong columns are refused; an abandoned writer leaves no file behind.
        let other = dir.path().join("o.parquet");
        let mut w = StreamWriter::create(&other, &table(vec![], vec![])).unwrap();
        let mut bad = Table::default();
        bad.push("x", Column::F64(vec![1.0])).unwrap();
        assert!(w.write(&bad).is_err());
        drop(w);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        // An empty stream is a valid empty file with the template's columns.
        let empty = dir.path().join("e.parquet");
        StreamWriter::create(&empty, &table(vec![], vec![]))
            .unwrap()
            .finish()
            .unwrap();
        assert_eq!(read_parquet(&empty, None).unwrap().num_rows(), 0);
        write_parquet(&dir.path().join("w.parquet"), &table(vec![1], vec![1.0])).unwrap();
    }

    /// `for_each_batch` streams a file in order, in batches of at most 64 Ki rows, with the
    /// asked-for columns only.
    #[test]
    fn batches_stream_the_file_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.parquet");
        let n = 150_000;
        let ids: Vec<i64> = (0..n).collect();
        let xs: Vec<f64> = (0..n).map(|i| i as f64 * 0.5).collect();
        write_parquet(&path, &table(ids.clone(), xs)).unwrap();
        let mut seen = Vec::new();
        let mut batches = 0;
        crate::for_each_batch(&path, Some(&["sample_id"]), |t| {
            assert!(t.num_rows() <= 64 * 1024);
            assert_eq!(t.names().collect::<Vec<_>>(), vec!["sample_id"]);
            seen.extend_from_slice(t.i64("sample_id")?);
            batches += 1;
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, ids);
        assert!(batches >= 3);
        let err = crate::for_each_batch(&path, Some(&["nope"]), |_| Ok(())).unwrap_err();
        assert!(err.to_string().contains("`nope`"), "{err}");
    }
}
