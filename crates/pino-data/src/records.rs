//! Per-sample records of a Parquet file whose rows are sorted by `sample_id` (then `t`): the
//! one streamed reader every stage that groups rows by sample uses (the learning data, the
//! magnitude weights, the indices).
//!
//! The file is read batch by batch with column projection ([`crate::for_each_batch`]); the rows
//! of one sample are gathered, whole, and handed on as soon as the next sample begins, so
//! memory holds one sample plus one batch of rows. A sample whose rows are not contiguous
//! (seen twice) is refused naming the file and the sample.
//!
//! [`read_params`] is the one reader of the sampled designs ([`PARAMS_FILE`](crate::artifacts::PARAMS_FILE)).

use crate::{for_each_batch, schema, Error, Result};
use mbd_system::System;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// One sample's rows: the requested `f64` columns, in request order.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// `sample_id`.
    pub id: i64,
    /// The columns, each the sample's rows in file order.
    pub columns: Vec<Vec<f64>>,
}

/// Streams every sample of `files` (in file order) to `f(file, record)`; `columns` are the
/// `f64` columns to read (besides `sample_id`; a column named twice is read once and handed on
/// in both places). An error of `f` stops the stream and is returned as it is.
pub fn for_each_record<E: From<Error>>(
    files: &[PathBuf],
    columns: &[&str],
    f: &mut dyn FnMut(&Path, Record) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let mut names = vec![schema::SAMPLE_ID];
    for c in columns {
        if !names.contains(c) {
            names.push(c);
        }
    }
    let mut seen = BTreeSet::new();
    for file in files {
        let mut failure: Option<E> = None;
        let mut current: Option<Record> = None;
        let mut finish = |rec: Record, failure: &mut Option<E>| -> bool {
            let r = if !seen.insert(rec.id) {
                Err(E::from(Error::Records {
                    path: file.clone(),
                    message: format!(
                        "rows of sample {} are not contiguous (rows must be sorted by sample_id then t)",
                        rec.id
                    ),
                }))
            } else {
                f(file, rec)
            };
            match r {
                Ok(()) => true,
                Err(e) => {
                    *failure = Some(e);
                    false
                }
            }
        };
        let stop = || Error::Parquet {
            path: file.clone(),
            message: "stopped".into(),
        };
        let streamed = for_each_batch(file, Some(&names), |table| {
            let ids = table.i64(schema::SAMPLE_ID)?;
            let cols: Vec<&[f64]> = columns
                .iter()
                .map(|n| table.f64(n))
                .collect::<Result<_>>()?;
            let mut lo = 0;
            while lo < ids.len() {
                let id = ids[lo];
                let hi = (lo..ids.len()).find(|&r| ids[r] != id).unwrap_or(ids.len());
                if current.as_ref().is_some_and(|c| c.id != id) {
                    let done = current.take().expect("checked");
                    if !finish(done, &mut failure) {
                        return Err(stop());
                    }
                }
                let rec = current.get_or_insert_with(|| Record {
                    id,
                    columns: vec![Vec::new(); cols.len()],
                });
                for (dst, src) in rec.columns.iter_mut().zip(&cols) {
                    dst.extend_from_slice(&src[lo..hi]);
                }
                lo = hi;
            }
            Ok(())
        });
        if let Some(e) = failure {
            return Err(e);
        }
        streamed.map_err(E::from)?;
        if let Some(rec) = current.take() {
            if !finish(rec, &mut failure) {
                return Err(failure.expect("set on failure"));
            }
        }
    }
    Ok(())
}

/// The rows of [`PARAMS_FILE`](crate::artifacts::PARAMS_FILE): every sample's id, split label and the named parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamsTable {
    /// `sample_id` per row.
    pub ids: Vec<i64>,
    /// `split` per row.
    pub splits: Vec<String>,
    /// The parameters of each row, in the requested order.
    pub values: Vec<Vec<f64>>,
}

impl ParamsTable {
    /// The rows, in file order: `(sample_id, split, parameters)`.
    pub fn rows(self) -> impl Iterator<Item = (i64, String, Vec<f64>)> {
        self.ids
            .into_iter()
            .zip(self.splits)
            .zip(self.values)
            .map(|((id, split), values)| (id, split, values))
    }
}

/// Reads [`PARAMS_FILE`](crate::artifacts::PARAMS_FILE) files (one per upstream shard, usually one): ids, splits and the
/// parameters `names` (none to read the ids and splits only), refusing a sample id seen twice.
/// This is the one reader of the sampled designs; [`read_params_of`] reads a description's.
pub fn read_params(files: &[PathBuf], names: &[&str]) -> Result<ParamsTable> {
    let mut cols = vec![schema::SAMPLE_ID, schema::SPLIT];
    cols.extend_from_slice(names);
    let t = crate::read_parquet_files(files, Some(&cols))?;
    let ids = t.i64(schema::SAMPLE_ID)?.to_vec();
    let splits = t.str(schema::SPLIT)?.to_vec();
    let columns: Vec<&[f64]> = names.iter().map(|n| t.f64(n)).collect::<Result<_>>()?;
    let mut seen = BTreeSet::new();
    for &id in &ids {
        if !seen.insert(id) {
            return Err(Error::Records {
                path: files.first().cloned().unwrap_or_default(),
                message: format!("sample_id {id} appears twice"),
            });
        }
    }
    let values = (0..ids.len())
        .map(|r| columns.iter().map(|c| c[r]).collect())
        .collect();
    Ok(ParamsTable {
        ids,
        splits,
        values,
    })
}

/// [`read_params`] of every sampled parameter of `system`, in the description's order (what
/// `System::sampled_values` takes).
pub fn read_params_of(files: &[PathBuf], system: &System) -> Result<ParamsTable> {
    read_params(files, &system.sampled_names())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{write_parquet_with, Column, Table};

    #[test]
    fn records_are_whole_samples_across_batches_and_interleaving_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.parquet");
        let mut t = Table::default();
        t.push(schema::SAMPLE_ID, Column::I64(vec![0, 0, 0, 1, 1, 2]))
            .unwrap();
        t.push(
            schema::TIME,
            Column::F64(vec![0.0, 1.0, 2.0, 0.0, 1.0, 0.0]),
        )
        .unwrap();
        // Row groups of two rows: sample 0 spans two batches.
        write_parquet_with(&path, &t, 2).unwrap();
        let mut got = Vec::new();
        // A column asked for twice comes in both places.
        let twice = [schema::TIME, schema::TIME];
        for_each_record::<Error>(std::slice::from_ref(&path), &twice, &mut |_, r| {
            assert_eq!(r.columns[0], r.columns[1]);
            got.push((r.id, r.columns[0].clone()));
            Ok(())
        })
        .unwrap();
        assert_eq!(
            got,
            [
                (0, vec![0.0, 1.0, 2.0]),
                (1, vec![0.0, 1.0]),
                (2, vec![0.0])
            ]
        );
        let mut t = Table::default();
        t.push(schema::SAMPLE_ID, Column::I64(vec![0, 1, 0]))
            .unwrap();
        t.push(schema::TIME, Column::F64(vec![0.0, 0.0, 1.0]))
            .unwrap();
        write_parquet_with(&path, &t, 2).unwrap();
        let e = for_each_record::<Error>(&[path], &[schema::TIME], &mut |_, _| Ok(())).unwrap_err();
        assert!(e.to_string().contains("sample 0 are not contiguous"), "{e}");
    }
}
